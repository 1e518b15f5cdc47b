// probekit::visibility — per-probe occluder distances that keep interpolation from carrying
// light through walls between probes (leak-proof interpolation).
//
// Each probe stores six bytes, one per half-axis h = 2 * axis + side (axis 0 x, 1 y, 2 z of the
// volume's local frame; side 0 towards +axis, 1 towards -axis): the distance from the probe's
// lattice position to the first surface the baker found in that direction, in units of the
// probe's own spacing along that axis (a dense grid's spacing; a brick's probe spacing at its
// level), quantised as q = round(clamp(d, 0, 1) * 255). q = 255 means no surface within one
// cell: every point the probe is interpolated to is clear along that axis. The baker
// (baker/src/volume/visibility.cpp) takes the median of a small bundle of rays around each
// half-axis, projected onto it, so a planar wall across the axis gives its exact distance and a
// thin obstacle seen by few rays of the bundle does not hide the probe.
//
// Runtime weight of probe i at a sample point (sampler.hpp, shaders/probe_volume.glsl):
//   offset o = (sample grid coordinate) - (probe grid coordinate), |o| <= 1 per axis (the point
//   lies in a cell the probe is a corner of; brick-local coordinates for bricked volumes);
//   per axis a with o_a != 0: side s = (o_a > 0 ? 0 : 1), v_a = |o_a|, d_a = q[2a + s] / 255;
//   vis_i = min over axes of clamp(1 - (v_a - d_a) / kVisibilityRamp, 0, 1)
//   (1 up to the surface, 0 at kVisibilityRamp of a cell beyond it: the box of free space
//   around the probe, with a continuous edge);
//   w_i = trilinear_i * (vis_i + kVisibilityFloor), E = sum w_i L_i / sum w_i.
// In open space every vis_i is 1 and this is trilinear interpolation exactly (up to rounding);
// where every probe is hidden it falls back to trilinear interpolation (the floor), so the
// result is continuous everywhere in a cell. Across a cell face the face's own probes carry
// the whole weight and their offsets along the face normal are 0, so neighbouring cells agree
// there as well.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <glm/vec3.hpp>

namespace probekit::visibility {

constexpr size_t kBytesPerProbe = 6;
// Width of the visibility edge beyond a surface, in cells: 1/32 cell (1.6 cm at 0.5 m spacing)
// hides a probe from a receiver on the far face of a 2 cm wall and keeps the edge continuous.
constexpr float kRamp = 1.0f / 32.0f;
// Weight a hidden probe keeps (times its trilinear weight): where every probe of a cell is
// hidden, interpolation falls back to trilinear instead of dividing by zero.
constexpr float kFloor = 1.0e-3f;
// Byte of a half-axis with no surface within one cell.
constexpr uint8_t kClear = 255;

inline uint8_t encodeDistance(float cells) {
    const float c = std::isnan(cells) ? 0.0f : std::clamp(cells, 0.0f, 1.0f);
    return uint8_t(std::lround(c * 255.0f));
}
inline float decodeDistance(uint8_t q) {
    return float(q) * (1.0f / 255.0f);
}

// vis_i of one probe (its six bytes) at grid offset o (see the top of this file).
inline float probeVisibility(const uint8_t* q, glm::vec3 offset) {
    float vis = 1.0f;
    for (int a = 0; a < 3; ++a) {
        const float o = offset[a];
        if (o == 0.0f) {
            continue;
        }
        const float d = decodeDistance(q[2 * a + (o > 0.0f ? 0 : 1)]);
        const float v = std::abs(o);
        vis = std::min(vis, std::clamp(1.0f - (v - d) / kRamp, 0.0f, 1.0f));
    }
    return vis;
}

} // namespace probekit::visibility
