// applyLightModes (light_modes.hpp).
#include "scene/light_modes.hpp"

#include <string>
#include <vector>

namespace probekit::baker {
namespace {

// The glTF light index of scene light i: its KHR_lights_punctual index when loaded from glTF,
// else its position in Scene::lights.
int lightIndex(const Scene& scene, size_t i) {
    return scene.gltfLights.size() == scene.lights.size() ? scene.gltfLights[i].index : int(i);
}

std::string lightList(const Scene& scene) {
    std::string out;
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        out += (out.empty() ? "" : ", ") + std::to_string(lightIndex(scene, i));
        if (!scene.lights[i].name.empty()) {
            out += " '" + scene.lights[i].name + "'";
        }
    }
    return out.empty() ? "none" : out;
}

} // namespace

Result<std::vector<LightMode>> lightModesOf(const Scene& scene, const LightModesConfig& modes) {
    std::vector<LightMode> out(scene.lights.size(), modes.punctual);
    for (const auto& [key, mode] : modes.perLight) {
        bool found = false;
        for (size_t i = 0; i < scene.lights.size(); ++i) {
            if (scene.lights[i].name == key || std::to_string(lightIndex(scene, i)) == key) {
                out[i] = mode;
                found = true;
            }
        }
        if (!found) {
            const std::string where = scene.source.empty() ? "the scene" : scene.source;
            return makeError(ErrorCode::InvalidArgument,
                             "lights.per_light.\"" + key +
                                 "\": no light of that name or index in " + where +
                                 " (its lights: " + lightList(scene) + ")");
        }
    }
    return out;
}

namespace {

bool anyIndirect(const std::vector<LightMode>& lights, const LightModesConfig& modes) {
    for (LightMode m : lights) {
        if (m == LightMode::Indirect) {
            return true;
        }
    }
    return modes.emissive == LightMode::Indirect || modes.environment == LightMode::Indirect;
}

// The lights not in mode none, and which of them keep their direct light.
void applyPunctual(Scene& scene, const std::vector<LightMode>& modes) {
    std::vector<PunctualLight> lights;
    std::vector<GltfLight> gltf;
    std::vector<uint8_t> direct;
    const bool hasGltf = scene.gltfLights.size() == scene.lights.size();
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        if (modes[i] == LightMode::None) {
            continue;
        }
        lights.push_back(scene.lights[i]);
        if (hasGltf) {
            gltf.push_back(scene.gltfLights[i]);
        }
        direct.push_back(modes[i] == LightMode::Baked ? 1 : 0);
    }
    scene.lights = std::move(lights);
    scene.gltfLights = std::move(gltf);
    scene.lightDirectStored = std::move(direct);
}

} // namespace

Result<std::optional<Scene>> applyLightModes(const Scene& scene, const BakeConfig& config) {
    const LightModesConfig& modes = config.lights;
    Result<std::vector<LightMode>> lights = lightModesOf(scene, modes);
    if (!lights) {
        return lights.error();
    }
    if (modes.allBaked()) {
        return std::optional<Scene>();
    }
    if (config.method == Method::Lpv && config.lpv.direct == LpvDirect::Propagated &&
        anyIndirect(lights.value(), modes)) {
        return makeError(ErrorCode::InvalidArgument,
                         "lights: mode indirect needs lpv.direct traced (propagated direct light "
                         "travels in the grid with the bounced light and cannot be left out)");
    }
    std::optional<Scene> out(scene);
    applyPunctual(*out, lights.value());
    if (modes.emissive == LightMode::None) {
        for (Material& m : out->materials) {
            m.emission = glm::vec3(0.0f);
        }
    }
    if (modes.environment == LightMode::None) {
        out->environment = Environment{};
    }
    out->emissiveDirectStored = modes.emissive == LightMode::Baked;
    out->environmentDirectStored = modes.environment == LightMode::Baked;
    return out;
}

} // namespace probekit::baker
