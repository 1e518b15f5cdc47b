// A glTF scene and its volumes on the runtime renderer (viewer/include/probekit/viewer/
// scene_view.hpp).
#include "probekit/viewer/scene_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <optional>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "probekit/baker/config.hpp"
#include "probekit/baker/folder_rule.hpp"
#include "probekit/baker/light_modes.hpp"
#include "probekit/baker/light_visibility.hpp"
#include "probekit/formats/json_nesting.hpp"

namespace probekit::viewer {
namespace {

// The triangle's three vertex normals: the glTF ones, or its face normal where any is missing.
void vertexNormals(const baker::Scene& scene, glm::uvec3 tri, glm::vec3 face, glm::vec3 (&n)[3]) {
    n[0] = n[1] = n[2] = face;
    if (scene.normals.size() != scene.positions.size()) {
        return;
    }
    const glm::vec3 given[3] = {scene.normals[tri.x], scene.normals[tri.y], scene.normals[tri.z]};
    if (given[0] != glm::vec3(0.0f) && given[1] != glm::vec3(0.0f) && given[2] != glm::vec3(0.0f)) {
        std::copy(std::begin(given), std::end(given), std::begin(n));
    }
}

// The texture slot of the triangle's material: its base-colour image, given a slot on first
// use while the renderer has slots left; -1 for none.
int32_t textureSlot(const baker::Scene& scene, const baker::Material& material,
                    std::vector<int32_t>& texture_of_image, RenderScene& out) {
    if (material.baseColorTexture < 0) {
        return -1;
    }
    int32_t& slot = texture_of_image[size_t(material.baseColorTexture)];
    if (slot < 0 && out.textures.size() < runtime::kMaxRenderTextures) {
        slot = int32_t(out.textures.size());
        out.textures.push_back(scene.images[size_t(material.baseColorTexture)]);
    } else if (slot < 0 && out.warnings.empty()) {
        out.warnings.push_back("more than " + std::to_string(runtime::kMaxRenderTextures) +
                               " base-colour textures; the rest are sampled per vertex");
    }
    return slot;
}

// A config holding only the section `key` = `value`, parsed as `probekit bake` parses a config.
Result<baker::BakeConfig> sectionConfig(const std::string& key, const nlohmann::json& value,
                                        const std::string& source) {
    return baker::parseBakeConfig(nlohmann::json{{key, value}}.dump(), source);
}

// A bake config's "environment" object, parsed as `probekit bake` parses it.
Result<baker::EnvironmentConfig> parseEnvironment(const nlohmann::json& env,
                                                  const std::string& source) {
    Result<baker::BakeConfig> config = sectionConfig("environment", env, source);
    if (!config) {
        return config.error();
    }
    return config.value().environment;
}

// The section `key` of the bake settings `metadata` records, read alone as `probekit bake`
// reads a config holding only it: std::nullopt when the settings are not a JSON object or hold
// no such section. Errors name `source`: a section that is not valid settings, and settings
// nested past kMaxJsonDepth (which readPvol already refuses).
Result<std::optional<baker::BakeConfig>>
recordedSection(const BakeMetadata& metadata, const std::string& key, const std::string& source) {
    Result<nlohmann::json> recorded =
        parseJsonText<nlohmann::json>(metadata.parametersJson, source);
    if (!recorded) {
        if (recorded.error().code == ErrorCode::OutOfRange) {
            return recorded.error();
        }
        return std::optional<baker::BakeConfig>();
    }
    if (!recorded.value().is_object() || !recorded.value().contains(key)) {
        return std::optional<baker::BakeConfig>();
    }
    Result<baker::BakeConfig> config = sectionConfig(key, recorded.value()[key], source);
    if (!config) {
        return config.error();
    }
    return std::optional<baker::BakeConfig>(std::move(config).value());
}

} // namespace

RenderScene flattenScene(const baker::Scene& scene) {
    RenderScene out;
    std::vector<int32_t> texture_of_image(scene.images.size(), -1);
    const glm::vec2 corner_bary[3] = {{0.0f, 0.0f}, {1.0f, 0.0f}, {0.0f, 1.0f}};
    for (uint32_t t = 0; t < scene.triangles.size(); ++t) {
        const glm::uvec3 tri = scene.triangles[t];
        const glm::vec3 p[3] = {scene.positions[tri.x], scene.positions[tri.y],
                                scene.positions[tri.z]};
        const glm::vec3 cross = glm::cross(p[1] - p[0], p[2] - p[0]);
        const float length = glm::length(cross);
        if (!(length > 0.0f) || !std::isfinite(length)) {
            continue;
        }
        glm::vec3 n[3];
        vertexNormals(scene, tri, cross / length, n);
        const baker::Material& material = scene.materials[scene.triangleMaterial[t]];
        const int32_t texture = textureSlot(scene, material, texture_of_image, out);
        out.triangleTextures.push_back(texture);
        for (int k = 0; k < 3; ++k) {
            out.indices.push_back(uint32_t(out.vertices.size()));
            const glm::vec3 albedo =
                texture >= 0 ? material.baseColor : scene.albedoAt(t, corner_bary[k]);
            out.vertices.push_back(
                {p[k], n[k], albedo, scene.emissionAt(t, corner_bary[k]), scene.uvs[tri[k]]});
        }
    }
    return out;
}

Result<void> uploadScene(runtime::Renderer& renderer, const RenderScene& scene) {
    if (auto r = renderer.setTextures(scene.textures); !r) {
        return r;
    }
    return renderer.setMeshes(scene.vertices, scene.indices, scene.triangleTextures);
}

grid::Aabb framedBox(const baker::Scene& scene, const std::vector<Volume>& volumes) {
    return scene.hasGeometry() ? scene.bounds : worldBounds(volumes);
}

Result<LightSelection> directLights(const baker::Scene& scene, const BakeMetadata& metadata,
                                    const std::string& source) {
    baker::LightModesConfig modes;
    modes.punctual = baker::LightMode::Indirect; // files that record no modes: every light
    Result<std::optional<baker::BakeConfig>> recorded = recordedSection(metadata, "lights", source);
    if (!recorded) {
        return recorded.error();
    }
    if (recorded.value()) {
        modes = recorded.value()->lights;
    }
    Result<std::vector<baker::LightMode>> per_light = baker::lightModesOf(scene, modes);
    if (!per_light) {
        return makeError(per_light.error().code, source + ": " + per_light.error().message);
    }
    LightSelection out;
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        if (per_light.value()[i] == baker::LightMode::Baked) {
            ++out.baked;
        } else if (out.lights.size() < runtime::kMaxRenderLights) {
            out.lights.push_back(scene.lights[i]);
        } else {
            ++out.dropped;
        }
    }
    return out;
}

Result<std::vector<uint32_t>> lightVisibility(const baker::Scene& scene,
                                              const runtime::Frame& gbuffer,
                                              std::span<const PunctualLight> lights) {
    std::vector<baker::SurfacePoint> points(gbuffer.position.size());
    for (size_t i = 0; i < points.size(); ++i) {
        if (gbuffer.position[i].w > 0.0f) {
            points[i] = {glm::vec3(gbuffer.position[i]), glm::vec3(gbuffer.normal[i])};
        }
    }
    return baker::lightVisibility(scene, points, lights);
}

Result<Environment> environmentFromSpec(const std::string& spec, const std::string& source) {
    nlohmann::json env;
    float rgb[3];
    char tail;
    if (spec == "none") {
        env = {{"type", "black"}};
    } else if (std::sscanf(spec.c_str(), "%f,%f,%f%c", &rgb[0], &rgb[1], &rgb[2], &tail) == 3) {
        if (!std::isfinite(rgb[0]) || !std::isfinite(rgb[1]) || !std::isfinite(rgb[2])) {
            return makeError(ErrorCode::OutOfRange,
                             source + ": radiance must be finite (got \"" + spec + "\")");
        }
        env = {{"type", "constant"}, {"radiance", {rgb[0], rgb[1], rgb[2]}}};
    } else {
        env = {{"type", "latlong"}, {"file", spec}};
    }
    Result<baker::EnvironmentConfig> config = parseEnvironment(env, source);
    if (!config) {
        return config.error();
    }
    Result<Environment> loaded = baker::makeEnvironment(config.value());
    if (!loaded) {
        // The map's own error names its file; the prefix says which flag gave it.
        return makeError(loaded.error().code, source + ": " + loaded.error().message);
    }
    return loaded;
}

Result<Environment> recordedEnvironment(const BakeMetadata& metadata, const std::string& source,
                                        const std::vector<std::filesystem::path>& allowed_roots,
                                        std::string& warning) {
    Result<std::optional<baker::BakeConfig>> recorded =
        recordedSection(metadata, "environment", source);
    if (!recorded) {
        return recorded.error();
    }
    if (!recorded.value()) {
        return Environment{};
    }
    baker::EnvironmentConfig config = recorded.value()->environment;
    if (config.type == baker::EnvironmentConfig::Type::LatLong) {
        // The volume is untrusted: the file it names is opened only inside the allowed folders.
        std::optional<std::filesystem::path> inside =
            baker::pathUnderRoots(config.file, allowed_roots);
        if (!inside) {
            warning = source + ": environment file " + config.file.string() +
                      " recorded in the volume is outside the scene folder; not opened (pass "
                      "--env to use it); the background stays black";
            return Environment{};
        }
        config.file = std::move(*inside);
    }
    Result<Environment> loaded = baker::makeEnvironment(config);
    if (!loaded) {
        warning = loaded.error().message + "; the background stays black";
        return Environment{};
    }
    return loaded;
}

Result<Volume> placeholderVolume(const baker::Scene& scene) {
    VolumeDesc desc;
    desc.name = "no-volume";
    grid::Aabb box = scene.bounds;
    box.max = glm::max(box.max, box.min + glm::vec3(1e-3f));
    // make, not the constructor: a scene whose extent overflows float is an error, not a
    // failed precondition.
    Result<grid::GridLayout> layout =
        grid::GridLayout::make(box, glm::uvec3(2), grid::PositionMode::Corner);
    if (!layout) {
        return makeError(layout.error().code, "the scene's bounds: " + layout.error().message);
    }
    desc.grid = layout.value();
    desc.shOrder = sh::Order::L1;
    const std::vector<sh::ShRgb> zeros(8);
    return makeVolume(desc, zeros);
}

} // namespace probekit::viewer
