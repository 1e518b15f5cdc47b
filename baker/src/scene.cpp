#include "probekit/baker/scene.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace probekit::baker {

glm::vec4 Image::sampleBilinear(glm::vec2 uv) const {
    if (width == 0 || height == 0) {
        return glm::vec4(1.0f);
    }
    if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) {
        return glm::vec4(0.0f);
    }
    // Repeat addressing: bring uv into [0, 1) first so huge coordinates cannot overflow the
    // integer texel index. Texel centres sit at (i + 0.5) / size.
    uv -= glm::floor(uv);
    const float x = uv.x * float(width) - 0.5f;
    const float y = uv.y * float(height) - 0.5f;
    const float fx = std::floor(x);
    const float fy = std::floor(y);
    const float tx = x - fx;
    const float ty = y - fy;
    auto wrap = [](long long i, uint32_t n) {
        const long long m = i % static_cast<long long>(n);
        return static_cast<uint32_t>(m < 0 ? m + n : m);
    };
    const uint32_t x0 = wrap(static_cast<long long>(fx), width);
    const uint32_t x1 = wrap(static_cast<long long>(fx) + 1, width);
    const uint32_t y0 = wrap(static_cast<long long>(fy), height);
    const uint32_t y1 = wrap(static_cast<long long>(fy) + 1, height);
    const glm::vec4 top = glm::mix(texels[y0 * width + x0], texels[y0 * width + x1], tx);
    const glm::vec4 bottom = glm::mix(texels[y1 * width + x0], texels[y1 * width + x1], tx);
    return glm::mix(top, bottom, ty);
}

glm::vec3 Environment::radiance(glm::vec3 dir) const {
    if (type == Type::Constant) {
        return constant * intensity;
    }
    // Undo the rotation about +Y, then invert dir = (sin t sin p, cos t, -sin t cos p).
    const float a = glm::radians(rotationDeg);
    const float c = std::cos(a);
    const float s = std::sin(a);
    const glm::vec3 d(c * dir.x - s * dir.z, dir.y, s * dir.x + c * dir.z);
    const float theta = std::acos(std::clamp(d.y, -1.0f, 1.0f));
    float phi = std::atan2(d.x, -d.z);
    if (phi < 0.0f) {
        phi += 2.0f * 3.14159265358979f;
    }
    const glm::vec2 uv(phi / (2.0f * 3.14159265358979f), theta / 3.14159265358979f);
    return glm::vec3(image.sampleBilinear(uv)) * intensity;
}

bool Environment::isBlack() const {
    if (intensity == 0.0f) {
        return true;
    }
    if (type == Type::Constant) {
        return constant == glm::vec3(0.0f);
    }
    return image.texels.empty();
}

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
