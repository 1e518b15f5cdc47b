#include "probekit/baker/scene.hpp"

#include <algorithm>
#include <cmath>

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

} // namespace probekit::baker
