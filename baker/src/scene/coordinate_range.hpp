// The coordinates a bake accepts (docs/baking.md#scenes: coordinate range).
//
// Everything the baker traces is float32, and a ray leaving a surface starts
// RayTracer::offsetOrigin's 256 ulps of each coordinate away from it. At |x| = 1e7 m an ulp is
// 1 m, so the offset is up to 256 m and float32 cannot even place a probe to the metre: no scene
// made in metres bakes meaningfully there (1e7 m is above the Earth's radius, so geo-referenced
// exports still fit). Within it, the squared distances, areas and fluxes the integrators form
// (up to (2e7)^2 = 4e14 m^2) stay far inside float range, and every ray origin and direction
// stays far below the 1.8e18 Embree accepts (its FLT_LARGE; a larger one aborts in its
// traversal). So bake() refuses scene geometry, light positions and volume bounds beyond it,
// with an error naming the file and what is out of range, before anything is traced.
#pragma once

#include <string>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

constexpr float kMaxCoordinate = 1e7f; // metres, after the unit scale

// The largest |coordinate| of the triangles' vertices and of the point and spot lights'
// positions must be at most kMaxCoordinate (NaN fails too). The error names scene.source, the
// largest coordinate, and the node of its triangle or the light.
Result<void> checkSceneCoordinates(const Scene& scene);

// A volume's world box (`label` names it in the error) within kMaxCoordinate.
Result<void> checkVolumeCoordinates(const grid::Aabb& world_box, const std::string& label);

// The tracer's ray offset at the farthest coordinate of the scene and the volumes, metres: 256
// ulps of it (offsetOrigin). A note (empty when none) when it exceeds a quarter of
// `finest_spacing`: light near surfaces is then wrong by more than the probe grid resolves.
std::string precisionNote(const Scene& scene, const grid::Aabb& volumes_box, float finest_spacing);

} // namespace probekit::baker
