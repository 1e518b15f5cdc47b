#include "probekit/baker/scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

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
