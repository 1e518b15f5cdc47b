#include "probekit/formats/light.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

namespace probekit {

std::optional<LightDirection> directionToLight(const PunctualLight& light, glm::vec3 point) {
    if (light.type == LightType::Directional) {
        return LightDirection{-glm::normalize(light.direction),
                              std::numeric_limits<float>::infinity()};
    }
    const glm::vec3 offset = light.position - point;
    const float distance = glm::length(offset);
    if (!(distance > 0.0f)) {
        return std::nullopt;
    }
    return LightDirection{offset / distance, distance};
}

float rangeWindow(float range, float distance_squared) {
    if (!(range > 0.0f)) {
        return 1.0f;
    }
    const float r = distance_squared / (range * range);
    const float window = std::clamp(1.0f - r * r, 0.0f, 1.0f);
    return window * window;
}

glm::vec3 normalIrradianceAt(const PunctualLight& light, glm::vec3 point) {
    if (light.type == LightType::Directional) {
        return light.intensity;
    }
    const glm::vec3 to_point = point - light.position;
    const float d2 = glm::dot(to_point, to_point);
    if (d2 <= 0.0f) {
        return glm::vec3(0.0f);
    }
    float attenuation = 1.0f / d2;
    if (light.range > 0.0f) {
        attenuation *= rangeWindow(light.range, d2);
    }
    if (light.type == LightType::Spot) {
        const float cos_angle = glm::dot(light.direction, to_point / std::sqrt(d2));
        const float scale = 1.0f / std::max(0.001f, light.innerConeCos - light.outerConeCos);
        const float t = std::clamp((cos_angle - light.outerConeCos) * scale, 0.0f, 1.0f);
        attenuation *= t * t;
    }
    return light.intensity * attenuation;
}

glm::vec3 irradianceAt(const PunctualLight& light, glm::vec3 point, glm::vec3 normal) {
    const std::optional<LightDirection> to_light = directionToLight(light, point);
    if (!to_light) {
        return glm::vec3(0.0f);
    }
    const float cos_theta = glm::dot(normal, to_light->direction);
    if (!(cos_theta > 0.0f)) {
        return glm::vec3(0.0f);
    }
    return normalIrradianceAt(light, point) * cos_theta;
}

} // namespace probekit
