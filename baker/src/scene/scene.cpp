#include "probekit/baker/scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <glm/geometric.hpp>

namespace probekit::baker {

namespace {
glm::vec2 interpolatedUv(const Scene& scene, uint32_t tri, glm::vec2 bary) {
    const glm::uvec3 t = scene.triangles[tri];
    return (1.0f - bary.x - bary.y) * scene.uvs[t.x] + bary.x * scene.uvs[t.y] +
           bary.y * scene.uvs[t.z];
}
} // namespace

glm::vec3 Scene::albedoAt(uint32_t tri, glm::vec2 bary) const {
    const Material& m = materials[triangleMaterial[tri]];
    if (m.baseColorTexture < 0) {
        return m.baseColor;
    }
    return m.baseColor *
           glm::vec3(images[m.baseColorTexture].sampleBilinear(interpolatedUv(*this, tri, bary)));
}

glm::vec3 Scene::emissionAt(uint32_t tri, glm::vec2 bary) const {
    const Material& m = materials[triangleMaterial[tri]];
    if (m.emissiveTexture < 0) {
        return m.emission;
    }
    return m.emission *
           glm::vec3(images[m.emissiveTexture].sampleBilinear(interpolatedUv(*this, tri, bary)));
}

namespace {
template <class T>
uint64_t arrayBytes(const std::vector<T>& v) {
    return uint64_t(v.capacity()) * sizeof(T);
}
uint64_t imageBytes(const Image& image) {
    return arrayBytes(image.texels);
}
} // namespace

uint64_t sceneBytes(const Scene& scene) {
    uint64_t bytes = arrayBytes(scene.positions) + arrayBytes(scene.uvs) +
                     arrayBytes(scene.normals) + arrayBytes(scene.triangles) +
                     arrayBytes(scene.triangleMaterial) + arrayBytes(scene.triangleNode) +
                     arrayBytes(scene.materials) + arrayBytes(scene.lights) +
                     arrayBytes(scene.gltfLights) + arrayBytes(scene.nodes) +
                     imageBytes(scene.environment.image);
    for (const Image& image : scene.images) {
        bytes += imageBytes(image);
    }
    return bytes;
}

void applyUnitScale(Scene& scene, float scale) {
    scene.unitScale *= scale;
    if (scale == 1.0f) {
        return;
    }
    for (glm::vec3& p : scene.positions) {
        p *= scale;
    }
    scene.bounds = grid::Aabb{scene.bounds.min * scale, scene.bounds.max * scale};
    const glm::mat4 to_metres = glm::mat4(glm::vec4(scale, 0, 0, 0), glm::vec4(0, scale, 0, 0),
                                          glm::vec4(0, 0, scale, 0), glm::vec4(0, 0, 0, 1));
    for (SceneNode& n : scene.nodes) {
        n.world = to_metres * n.world;
        n.worldBounds = grid::Aabb{n.worldBounds.min * scale, n.worldBounds.max * scale};
    }
    for (PunctualLight& l : scene.lights) {
        l.position *= scale;
        l.range *= scale;
    }
}

std::string implausibleSizeWarning(const Scene& scene, const std::string& file) {
    if (!scene.hasGeometry()) {
        return {};
    }
    const glm::vec3 size = scene.bounds.size();
    const float longest = std::max({size.x, size.y, size.z});
    if (longest >= kPlausibleSceneMinMetres && longest <= kPlausibleSceneMaxMetres) {
        return {};
    }
    char text[512];
    if (longest > kPlausibleSceneMaxMetres) {
        std::snprintf(text, sizeof text,
                      "%s: the scene is %.4g m across (%.4g x %.4g x %.4g m), more than %g m: if "
                      "the file is in centimetres, --scale 0.01 makes it %.4g m; in millimetres, "
                      "--scale 0.001 makes it %.4g m (glTF says metres; exporters often write "
                      "other units)",
                      file.c_str(), longest, size.x, size.y, size.z, kPlausibleSceneMaxMetres,
                      longest * 0.01f, longest * 0.001f);
    } else {
        std::snprintf(text, sizeof text,
                      "%s: the scene is %.4g m across, less than %g m: if the file is in "
                      "kilometres, --scale 1000 makes it %.4g m",
                      file.c_str(), longest, kPlausibleSceneMinMetres, longest * 1000.0f);
    }
    return text;
}

} // namespace probekit::baker
