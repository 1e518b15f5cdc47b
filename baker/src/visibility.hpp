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
// Deterministic: no random numbers, every probe independent, so the bytes do not depend on the
// thread count.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/grid.hpp"
#include "probekit/formats/volume.hpp"
#include "ray_tracer.hpp"

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
// threads. validity: one byte per probe (kProbeInvalid probes get zeros).
std::vector<uint8_t> traceVolumeVisibility(const RayTracer& tracer, const VolumeDesc& desc,
                                           std::span<const uint8_t> validity, uint32_t threads);

} // namespace probekit::baker
