#include "probekit/formats/environment.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace probekit {

glm::vec4 RgbaImage::sampleBilinear(glm::vec2 uv) const {
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

glm::vec2 latLongUv(glm::vec3 dir, float rotation_deg) {
    // Undo the rotation about +Y, then invert dir = (sin t sin p, cos t, -sin t cos p).
    const float a = glm::radians(rotation_deg);
    const float c = std::cos(a);
    const float s = std::sin(a);
    const glm::vec3 d(c * dir.x - s * dir.z, dir.y, s * dir.x + c * dir.z);
    const float theta = std::acos(std::clamp(d.y, -1.0f, 1.0f));
    float phi = std::atan2(d.x, -d.z);
    if (phi < 0.0f) {
        phi += 2.0f * 3.14159265358979f;
    }
    return glm::vec2(phi / (2.0f * 3.14159265358979f), theta / 3.14159265358979f);
}

glm::vec3 Environment::radiance(glm::vec3 dir) const {
    if (type == Type::Constant) {
        return constant * intensity;
    }
    return glm::vec3(image.sampleBilinear(latLongUv(dir, rotationDeg))) * intensity;
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

} // namespace probekit
