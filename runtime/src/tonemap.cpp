#include "probekit/runtime/tonemap.hpp"

#include <algorithm>
#include <cmath>

namespace probekit::runtime {

float luminance(glm::vec3 linear) {
    return 0.2126f * linear.x + 0.7152f * linear.y + 0.0722f * linear.z;
}

float acesFilmic(float x) {
    if (!(x > 0.0f)) {
        return 0.0f;
    }
    // The curve passes 1 at x = 7.24 and is clamped there; beyond 8 the quadratics could
    // overflow float (x ~ 1e19 and above), so the clamped value is returned directly.
    if (x >= 8.0f) {
        return 1.0f;
    }
    const float y = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    return std::clamp(y, 0.0f, 1.0f);
}

float srgbEncode(float linear) {
    const float c = std::clamp(linear, 0.0f, 1.0f);
    return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

float autoExposureEv(std::span<const glm::vec4> color) {
    // Doubles: millions of logarithms summed in float would lose the mean's last digits.
    double sum = 0.0;
    size_t count = 0;
    for (const glm::vec4& c : color) {
        const float y = luminance(glm::vec3(c));
        if (y > 0.0f && std::isfinite(y)) {
            sum += std::log(double(y));
            ++count;
        }
    }
    if (count == 0) {
        return 0.0f;
    }
    return float(std::log2(double(kAutoExposureKey)) - sum / double(count) / std::log(2.0));
}

glm::vec3 toneMap(glm::vec3 linear, float ev) {
    const float scale = std::exp2(ev);
    return glm::vec3(acesFilmic(linear.x * scale), acesFilmic(linear.y * scale),
                     acesFilmic(linear.z * scale));
}

} // namespace probekit::runtime
