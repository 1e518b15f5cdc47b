// Cameras: framing a box, the ray through a pixel, the view-projection matrix of a frame.
#include <algorithm>
#include <cmath>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

#include "renderer_internal.hpp"

namespace probekit::runtime {

Camera frameBounds(const grid::Aabb& bounds, float vertical_fov_deg, float aspect, glm::vec3 side) {
    side = glm::normalize(side);
    const glm::vec3 center = bounds.center();
    const glm::vec3 half = 0.5f * bounds.size();
    const float tan_half = std::tan(glm::radians(vertical_fov_deg) * 0.5f);
    Camera camera;
    // Seen from +-Y, +Y cannot be up: the top of the image is then the far side along Z.
    camera.up = std::abs(side.y) > 0.5f ? glm::vec3(0.0f, 0.0f, side.y > 0.0f ? -1.0f : 1.0f)
                                        : glm::vec3(0.0f, 1.0f, 0.0f);
    const glm::vec3 right = glm::normalize(glm::cross(-side, camera.up));
    const glm::vec3 up = glm::cross(right, -side);
    // The box's half extents across the image and towards the camera (support distances).
    const float across = glm::dot(glm::abs(right), half);
    const float upward = glm::dot(glm::abs(up), half);
    const float depth = glm::dot(glm::abs(side), half);
    // Distance from the near face at which the face fits both angles.
    const float fit = std::max(upward, across / std::max(aspect, 1e-6f)) / tan_half;
    const float margin = 1.1f;
    const float distance = depth + fit * margin;
    camera.verticalFovDeg = vertical_fov_deg;
    camera.target = center;
    camera.eye = center + side * distance;
    const float extent = glm::length(bounds.size());
    camera.nearPlane = std::max(1e-4f, 0.01f * distance);
    camera.farPlane = distance + 2.0f * extent + 1.0f;
    return camera;
}

CameraBasis cameraBasis(const Camera& camera, float aspect) {
    const glm::vec3 forward = glm::normalize(camera.target - camera.eye);
    const glm::vec3 right = glm::normalize(glm::cross(forward, camera.up));
    const glm::vec3 up = glm::cross(right, forward);
    const float tan_half = std::tan(glm::radians(camera.verticalFovDeg) * 0.5f);
    return {right * (tan_half * aspect), up * tan_half, forward};
}

glm::vec3 pixelDirection(const Camera& camera, uint32_t width, uint32_t height, glm::vec2 pixel) {
    const CameraBasis b = cameraBasis(camera, float(width) / float(height));
    const glm::vec2 ndc(2.0f * pixel.x / float(width) - 1.0f,
                        1.0f - 2.0f * pixel.y / float(height));
    return glm::normalize(b.forward + ndc.x * b.right + ndc.y * b.up);
}

uint32_t probeBudget(uint32_t width, uint32_t height) {
    return std::max<uint32_t>(1, uint32_t(uint64_t(width) * height / kProbePixels));
}

glm::mat4 viewProjection(const FrameSettings& settings) {
    const Camera& cam = settings.camera;
    const glm::mat4 view = glm::lookAtRH(cam.eye, cam.target, cam.up);
    glm::mat4 projection = glm::perspectiveRH_ZO(glm::radians(cam.verticalFovDeg),
                                                 float(settings.width) / float(settings.height),
                                                 cam.nearPlane, cam.farPlane);
    projection[1][1] *= -1.0f; // Vulkan's clip space has +y down: row 0 is the image top
    return projection * view;
}

} // namespace probekit::runtime
