// probekit::baker — what the baker sees in a scene (`probekit info SCENE.gltf`), and the check
// that a scene gives any light at all.
//
// Units follow formats/CONVENTIONS.md: metres; point and spot intensity (candela) taken as W/sr,
// directional intensity (lux) as W/m^2; emitted radiance in W/(sr m^2). Powers are per RGB
// channel, in watts.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

struct MaterialSummary {
    std::string name;
    glm::vec3 baseColor{1.0f};      // linear albedo factor
    bool baseColorTextured = false; // albedo also varies with a texture
    glm::vec3 emission{0.0f};       // emitted radiance factor, W/(sr m^2)
    bool emissionTextured = false;
    uint64_t triangles = 0; // triangles that use it
};

struct LightSummary {
    std::string name;
    LightType type = LightType::Point;
    // As the glTF gave them (Scene::gltfLights); for a scene built in code colour 1 and the
    // largest channel of the light's intensity.
    glm::vec3 color{1.0f};
    float gltfIntensity = 0.0f; // candela (point, spot) or lux (directional)
    glm::vec3 intensity{0.0f};  // colour x intensity: W/sr (point, spot) or W/m^2 (directional)
    // Point and spot: emitted power, intensity x the solid angle it shines into (4 pi for a
    // point light, the integral of the glTF cone falloff for a spot), W. Directional: 0.
    glm::vec3 power{0.0f};
    float range = 0.0f; // metres, 0 = infinite
    glm::vec3 position{0.0f};
    glm::vec3 direction{0.0f}; // spot and directional: the way the light travels
};

struct EmitterSummary {
    uint64_t triangles = 0; // triangles with a non-black emissive material
    double area = 0.0;      // m^2, one side
    // Two-sided Lambertian emission, 2 pi x area x radiance summed over the triangles, with the
    // radiance taken at each triangle's centroid (exact without emissive textures), W.
    glm::dvec3 power{0.0};
};

struct SceneSummary {
    std::string source;
    uint64_t triangles = 0;
    uint64_t vertices = 0;
    std::vector<MaterialSummary> materials;
    std::vector<LightSummary> lights;
    EmitterSummary emitters;
    grid::Aabb bounds; // world, metres (zero for a scene without triangles)
    bool environmentBlack = true;
    // The loader's warnings, then checkSceneLit's message when the scene gives no light.
    std::vector<std::string> warnings;
};

SceneSummary summarizeScene(const Scene& scene);

// Fails when nothing in the scene emits light: no punctual light of non-zero intensity, no
// triangle with a non-black emissive material and a black environment (scene.environment, which
// a bake takes from its config). Every probe of such a bake is zero by construction, so bake()
// refuses it unless BakeOptions::allowUnlit; the message names the scene's file and says what
// to add.
Result<void> checkSceneLit(const Scene& scene);

} // namespace probekit::baker
