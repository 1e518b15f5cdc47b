// What the baker sees in a scene, and whether anything in it emits light.
#include "probekit/baker/scene_summary.hpp"

#include <algorithm>
#include <numbers>

#include <glm/geometric.hpp>

#include "methods/vpl_paths.hpp"

namespace probekit::baker {
namespace {

bool isBlack(glm::vec3 v) {
    return !(v.x > 0.0f || v.y > 0.0f || v.z > 0.0f);
}

LightSummary summarizeLight(const Scene& scene, size_t index) {
    const PunctualLight& light = scene.lights[index];
    LightSummary l;
    l.name = light.name;
    l.type = light.type;
    if (index < scene.gltfLights.size()) {
        l.color = scene.gltfLights[index].color;
        l.gltfIntensity = scene.gltfLights[index].intensity;
    } else {
        l.gltfIntensity = std::max({light.intensity.x, light.intensity.y, light.intensity.z});
        l.color = l.gltfIntensity > 0.0f ? light.intensity / l.gltfIntensity : glm::vec3(1.0f);
    }
    l.intensity = light.intensity;
    // formats/CONVENTIONS.md: candela is taken as W/sr, so power = W/sr x sr.
    l.power = light.intensity * float(punctualSolidAngle(light));
    l.range = light.range;
    l.position = light.position;
    l.direction = light.direction;
    return l;
}

} // namespace

SceneSummary summarizeScene(const Scene& scene) {
    SceneSummary s;
    s.source = scene.source;
    s.triangles = scene.triangles.size();
    s.vertices = scene.positions.size();
    for (const Material& m : scene.materials) {
        s.materials.push_back(MaterialSummary{m.name, m.baseColor, m.baseColorTexture >= 0,
                                              m.emission, m.emissiveTexture >= 0, 0});
    }
    constexpr double kTwoPi = 2.0 * std::numbers::pi;
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
        const uint32_t material = scene.triangleMaterial[t];
        ++s.materials[material].triangles;
        if (!scene.materials[material].isEmissive()) {
            continue;
        }
        const glm::uvec3 tri = scene.triangles[t];
        const glm::vec3 p0 = scene.positions[tri.x];
        const double area = 0.5 * double(glm::length(glm::cross(scene.positions[tri.y] - p0,
                                                                scene.positions[tri.z] - p0)));
        // Two-sided Lambertian emitter: pi L per side and unit area
        // (docs/baking.md#the-vpl-method---method-vpl).
        const glm::vec3 radiance = scene.emissionAt(uint32_t(t), glm::vec2(1.0f / 3.0f));
        ++s.emitters.triangles;
        s.emitters.area += area;
        s.emitters.power += kTwoPi * area * glm::dvec3(radiance);
    }
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        s.lights.push_back(summarizeLight(scene, i));
    }
    s.bounds = scene.bounds;
    s.environmentBlack = scene.environment.isBlack();
    s.warnings = scene.warnings;
    if (Result<void> lit = checkSceneLit(scene); !lit) {
        s.warnings.push_back(lit.error().message);
    }
    return s;
}

Result<void> checkSceneLit(const Scene& scene) {
    if (!scene.environment.isBlack()) {
        return {};
    }
    for (const PunctualLight& light : scene.lights) {
        if (!isBlack(light.intensity)) {
            return {};
        }
    }
    for (const uint32_t material : scene.triangleMaterial) {
        if (scene.materials[material].isEmissive()) {
            return {};
        }
    }
    const std::string file = scene.source.empty() ? "scene" : scene.source;
    return makeError(ErrorCode::InvalidArgument,
                     file + ": the scene emits no light (no KHR_lights_punctual light of non-zero "
                            "intensity, no emissive material on any triangle, and a black "
                            "environment): every probe would bake to zero; add a "
                            "KHR_lights_punctual light, an emissive material (emissiveFactor) or "
                            "an environment (--env R,G,B|FILE, or the bake config's "
                            "\"environment\"); --allow-unlit bakes it black anyway");
}

} // namespace probekit::baker
