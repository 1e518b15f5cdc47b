// probekit::baker light visibility — which punctual lights reach points on the surfaces a
// camera sees: the shadows a renderer applies to the direct light it shades itself (lights in
// light mode indirect or none, docs/baking.md#light-modes; runtime::FrameSettings::
// lightVisibility), traced with the baker's own ray tracer against the scene's triangles.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

struct SurfacePoint {
    glm::vec3 position{0.0f}; // metres, world
    glm::vec3 normal{0.0f};   // unit, facing the viewer; (0,0,0) = no surface (mask 0)
};

// Per point a mask, bit i set where lights[i] (at most 32) reaches it: the point is on the lit
// side of its normal's plane and a ray from it (lifted off the surface by 1e-4 of the scene's
// bounding-box diagonal along the normal) to the light, or towards a directional light, hits
// nothing. Lights whose irradiance at the point is zero (beyond range, outside a spot's cone)
// keep their bit: their light is zero there anyway. Fails when the scene cannot be built into a
// tracer or more than 32 lights are given. `threads` 0 = every hardware thread.
Result<std::vector<uint32_t>> lightVisibility(const Scene& scene,
                                              std::span<const SurfacePoint> points,
                                              std::span<const PunctualLight> lights,
                                              uint32_t threads = 0);

} // namespace probekit::baker
