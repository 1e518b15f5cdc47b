// probekit::baker surface reference — path-traced irradiance at the surfaces a camera sees:
// the per-pixel reference a probe volume's shading is measured against
// (docs/accuracy.md#surface-accuracy).
//
// For each ray (one per pixel): its first hit in the scene; there, irradiance E (W/m^2 per
// channel, not divided by pi) for the shading normal a renderer would use — the glTF vertex
// normals interpolated with the hit's barycentrics (the face normal where the scene has none
// or they cancel), turned to the side the ray arrives from — estimated by the path reference's
// own integrator (path_integrator.hpp: the same lights, MIS, bounces and roulette as a probe,
// with next-event estimation at the point itself) from `samples` cosine-distributed directions.
// Each estimate carries its standard error (the per-sample spread / sqrt(samples): an upper
// bound for the stratified Sobol set), so a comparison can tell bias from reference noise.
//
// Deterministic: every random number derives from (seed, ray index, sample), so the result is
// bit-identical for any thread count.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

struct SurfaceReferenceSettings {
    uint32_t samples = 1024;  // cosine-distributed directions per hit point (>= 1)
    uint32_t maxBounces = 64; // diffuse vertices after the hit point (path_integrator.hpp)
    uint64_t seed = 1;
    uint32_t threads = 0; // 0 = every hardware thread
};

struct SurfaceRay {
    glm::vec3 origin{0.0f};    // metres, world
    glm::vec3 direction{0.0f}; // need not be unit length; non-zero
};

struct SurfaceSample {
    bool hit = false;              // false: the ray left the scene (the rest is zero)
    glm::vec3 position{0.0f};      // the hit point, metres
    glm::vec3 normal{0.0f};        // unit shading normal, facing the ray's origin
    glm::vec3 irradiance{0.0f};    // E, W/m^2 per channel
    glm::vec3 standardError{0.0f}; // of `irradiance`, W/m^2 per channel
    uint32_t triangle = 0;         // index into Scene::triangles
};

struct SurfaceReference {
    std::vector<SurfaceSample> samples; // one per ray, in ray order
    uint64_t rays = 0;                  // every ray traced
};

// `progress(done, total)` is called from the calling thread about every 0.5 s (optional).
// Fails when the scene cannot be built into a tracer, or on settings out of range.
Result<SurfaceReference>
traceSurfaceReference(const Scene& scene, std::span<const SurfaceRay> rays,
                      const SurfaceReferenceSettings& settings,
                      const std::function<void(size_t, size_t)>& progress = {});

} // namespace probekit::baker
