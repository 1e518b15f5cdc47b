// Bake-time tracing of the per-probe occluder distances of formats/.../visibility.hpp.
//
// For each of a probe's six half-axes a bundle of kBundleRays rays leaves the probe's lattice
// position: one along the axis and the rest on a cone of kBundleAngle around it. Each ray's hit
// is projected onto the axis (t cos(angle)) and expressed in cells of the probe's spacing along
// that axis (a miss, or a hit beyond one cell, counts as one cell); the median of the bundle is
// the stored distance. A planar wall across the axis gives every ray the same projected
// distance, so the median is exact there; an obstacle that only some rays of the bundle meet (a
// thin post, the edge of a doorway, a floor the axis runs along) moves the median only when
// most of the bundle meets it. Rays start kStartCells of a cell along their direction, so a
// probe lying on a surface (a corner-mode grid or brick face on a floor) is not hidden along
// that surface by its own plane.
//
// Invalid probes (inside geometry; their coefficients come from dilation) get distance 0 on
// every half-axis: the runtime then gives them weight only at their own position.
//
// Relocated probes (virtual offset, below: a probe inside geometry baked at the nearest point of
// free space instead) are traced like any other from their lattice position, which lies inside
// the solid, so their box of free space ends at the solid's own faces: they light the surfaces
// of the solid around them and nothing beyond. The half-axes pointing away from the move (local
// direction e with e . move < 0) get 0, so a probe inside a thin wall, moved out to one side,
// never lights the wall's other face.
//
// Deterministic: no random numbers, every probe independent, so the bytes do not depend on the
// thread count.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/grid.hpp"
#include "probekit/formats/volume.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {

constexpr int kBundleRays = 9;           // rays per half-axis: the axis and 8 on a cone
constexpr float kBundleAngleDeg = 15.0f; // cone half-angle around the axis
constexpr float kVisibilityStartCells = 1.0e-3f;
constexpr uint64_t kVisibilityRaysPerProbe = 6 * kBundleRays;

// The six bytes of one probe: `world_position` its lattice position, `spacing` its cell size per
// local axis (metres), `frame` the volume's local -> world frame.
std::array<uint8_t, visibility::kBytesPerProbe> traceProbeVisibility(const RayTracer& tracer,
                                                                     glm::vec3 world_position,
                                                                     glm::vec3 spacing,
                                                                     const grid::RigidFrame& frame);

// Visibility of every probe of a baked volume (dense grid order or brick order), on `threads`
// threads. validity: one byte per probe (kProbeInvalid probes get zeros). moves: empty, or per
// probe the world-space vector from its lattice position to where it was baked (zero for
// probes baked in place).
std::vector<uint8_t> traceVolumeVisibility(const RayTracer& tracer, const VolumeDesc& desc,
                                           std::span<const uint8_t> validity, uint32_t threads,
                                           std::span<const glm::vec3> moves = {});

// Relocation (virtual offset). A probe inside geometry (invalid by the back-face rule) stores
// nothing a visible surface can use, and the surfaces of the solid it sits in are left to the
// probes on their far side. Instead it is baked at the nearest point of free space: from the
// lattice position `p`, kRelocationDirections spherical-Fibonacci directions find where rays
// leave the solid (a back-face hit at distance t <= max_distance); candidates in order of t
// (ties in direction order) are moved kRelocationMargin x `margin_scale` beyond the exit and
// accepted when no more than `backface_threshold` of kRelocationTestRays rays from there hit
// back faces (the validity rule on a cheaper ray set; the bake's own rule decides in the end).
// Nothing when no candidate within max_distance passes. Deterministic.
constexpr int kRelocationDirections = 64;
constexpr int kRelocationTestRays = 64;
constexpr int kRelocationCandidates = 4;
// Half a cell beyond the exit: as far from the face as a centre-mode grid's outer probes are
// from the walls it fills, so a relocated probe reads like its neighbours in free space. 5% of
// a cell (right at the face) measured the same median per pixel on the Cornell 16^3 example
// (8.3%) but drew the relocated probes as a checker on the blocks' faces (direct light changes
// fast within half a cell of a face).
constexpr float kRelocationMargin = 0.5f;
std::optional<glm::vec3> relocationTarget(const RayTracer& tracer, glm::vec3 p, float max_distance,
                                          float margin_scale, float backface_threshold);

} // namespace probekit::baker
