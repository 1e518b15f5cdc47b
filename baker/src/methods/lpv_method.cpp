#include "methods/lpv_method.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "methods/vpl_paths.hpp"
#include "trace/light_sampler.hpp"
#include "trace/rng.hpp"
#include "trace/sampling.hpp"

namespace probekit::baker {

namespace {

// Directions over which punctual lights and the sky are projected onto L1 (spherical
// Fibonacci; L1 of smooth distributions is exact to ~1e-4 with this many).
constexpr int kProjectionDirections = 4096;
// Keys the emitter samples apart from every other use of the bake seed.
constexpr uint64_t kEmitterSampleKey = 0x4c50565f656d6974ull;

// Intensity [W/sr] of a point or spot light towards unit w: its irradiance at a small
// distance d (where the range window is 1) times d^2.
glm::vec3 punctualIntensity(const PunctualLight& light, glm::vec3 w) {
    constexpr float kNear = 1e-3f;
    return normalIrradianceAt(light, light.position + kNear * w) * (kNear * kNear);
}

std::vector<LpvSurfaceLight> emitterLights(const Scene& scene, uint32_t count, uint64_t seed) {
    std::vector<LpvSurfaceLight> lights;
    const LightSampler sampler(scene);
    if (!sampler.hasEmitters()) {
        return lights;
    }
    lights.reserve(2 * size_t(count));
    for (uint32_t i = 0; i < count; ++i) {
        Rng rng(hashKeys(seed, kEmitterSampleKey, i));
        const double u_pick = rng.uniformDouble();
        const LightSampler::EmitterSample s = sampler.sampleEmitter(u_pick, rng.uniform2());
        // Each side of a two-sided emitter of radiance L emits pi L per unit area.
        const glm::vec3 flux = std::numbers::pi_v<float> * scene.emissionAt(s.triangle, s.bary) /
                               (s.pdfArea * float(count));
        lights.push_back(LpvSurfaceLight{s.position, s.normal, flux});
        lights.push_back(LpvSurfaceLight{s.position, -s.normal, flux});
    }
    return lights;
}

std::vector<LpvPointLight> punctualLights(const Scene& scene) {
    std::vector<LpvPointLight> out;
    for (const PunctualLight& light : scene.lights) {
        if (light.type == LightType::Directional) {
            continue;
        }
        LpvPointLight p{light.position, {}};
        const float weight = 4.0f * std::numbers::pi_v<float> / float(kProjectionDirections);
        for (int i = 0; i < kProjectionDirections; ++i) {
            const glm::vec3 w = sh::fibonacciDirection(i, kProjectionDirections);
            p.intensity += beamSh(w, weight * punctualIntensity(light, w));
        }
        out.push_back(p);
    }
    return out;
}

// Sun and sky per square metre of each border side (lpv.hpp, LpvInjection::borderPerArea).
std::array<Sh1Rgb, 6> borderLight(const Scene& scene) {
    std::array<Sh1Rgb, 6> out{};
    const std::array<glm::vec3, 6> inward = {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0),
                                             glm::vec3(0, 1, 0), glm::vec3(0, -1, 0),
                                             glm::vec3(0, 0, 1), glm::vec3(0, 0, -1)};
    for (const PunctualLight& light : scene.lights) {
        if (light.type != LightType::Directional) {
            continue;
        }
        const glm::vec3 travel = glm::normalize(light.direction);
        for (int d = 0; d < 6; ++d) {
            const float c = glm::dot(travel, inward[d]);
            if (c > 0.0f) {
                out[d] += beamSh(travel, c * light.intensity);
            }
        }
    }
    if (!scene.environment.isBlack()) {
        const float weight = 4.0f * std::numbers::pi_v<float> / float(kProjectionDirections);
        for (int i = 0; i < kProjectionDirections; ++i) {
            // Light travelling along w comes from the sky in direction -w.
            const glm::vec3 w = sh::fibonacciDirection(i, kProjectionDirections);
            const glm::vec3 radiance = scene.environment.radiance(-w);
            for (int d = 0; d < 6; ++d) {
                const float c = glm::dot(w, inward[d]);
                if (c > 0.0f) {
                    out[d] += beamSh(w, weight * c * radiance);
                }
            }
        }
    }
    return out;
}

} // namespace

LpvSettings resolveLpvSettings(const LpvConfig& config) {
    LpvSettings s;
    s.grid = config.grid;
    s.cascades = config.cascades;
    s.cascadeRatio = config.cascadeRatio;
    s.iterations = config.iterations ? *config.iterations : config.grid;
    s.propagationWeight = config.propagationWeight;
    s.fadeCells = config.fadeCells;
    s.occlusion = config.occlusion;
    return s;
}

LpvLights prepareLpvLights(const Scene& scene, const RayTracer& tracer, const LpvConfig& config,
                           const std::vector<VolumeDesc>& volumes, uint64_t seed,
                           uint32_t threads) {
    LpvLights out;
    // The VPL method's default light paths (bounces, stratified sampling), lpv.vpl_count of them.
    const VplSet set = traceVpls(scene, tracer, config.vplCount, VplConfig{}, seed);
    out.vpls = set.vpls.size();
    out.rays = set.rays;
    std::vector<LpvSurfaceLight> surface;
    surface.reserve(set.vpls.size());
    for (const Vpl& v : set.vpls) {
        // A VPL's intensity along its normal is J: a Lambertian element reflects pi J in all.
        surface.push_back(
            LpvSurfaceLight{v.position, v.normal, std::numbers::pi_v<float> * v.intensity});
    }
    std::vector<LpvPointLight> points;
    if (config.direct == LpvDirect::Propagated) {
        std::vector<LpvSurfaceLight> emitters = emitterLights(scene, config.vplCount, seed);
        surface.insert(surface.end(), emitters.begin(), emitters.end());
        points = punctualLights(scene);
    }
    // Escape rays reach one cell of the coarsest cascade of any volume.
    const LpvSettings settings = resolveLpvSettings(config);
    const grid::Aabb scene_bounds = scene.bounds;
    float reach = 0.0f;
    for (const VolumeDesc& v : volumes) {
        const grid::Aabb bounds = v.grid.worldBounds();
        reach = std::max(
            reach, layoutLpvCascades(bounds, scene.hasGeometry() ? scene_bounds : bounds, settings)
                       .back()
                       .cellSize);
    }
    out.rays += uint64_t(surface.size()) * kEscapeRays;
    out.injection =
        traceLpvInjection(tracer, std::move(surface), std::move(points), reach, seed, threads);
    if (config.direct == LpvDirect::Propagated) {
        out.injection.borderPerArea = borderLight(scene);
    }
    return out;
}

LpvCascades propagateLpv(const Scene& scene, const LpvLights& lights, const LpvConfig& config,
                         const VolumeDesc& volume, uint32_t threads) {
    const LpvSettings settings = resolveLpvSettings(config);
    const grid::Aabb bounds = volume.grid.worldBounds();
    return LpvCascades(
        scene, lights.injection,
        layoutLpvCascades(bounds, scene.hasGeometry() ? scene.bounds : bounds, settings), settings,
        threads);
}

sh::ShRgb lpvProbe(const LpvCascades& cascades, const LpvConfig& config, glm::vec3 p,
                   const sh::ShRgb& traced) {
    sh::ShRgb out = cascades.radiance(p);
    out *= config.intensity;
    if (config.direct == LpvDirect::Traced) {
        out += traced;
    }
    return out;
}

} // namespace probekit::baker
