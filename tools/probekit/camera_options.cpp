#include "camera_options.hpp"

#include <algorithm>

#include <glm/geometric.hpp>

namespace probekit::cli {

void addCameraOptions(CLI::App* cmd, CameraOptions& o) {
    cmd->add_option("--camera", o.camera,
                    "eye_x,eye_y,eye_z,at_x,at_y,at_z in metres (default: frame the scene from "
                    "the --camera-from side)")
        ->delimiter(',')
        ->expected(6);
    cmd->add_option("--camera-from", o.cameraFrom,
                    "without --camera: the side of the scene's box the default camera frames it "
                    "from, looking back at its centre (+z: glTF assets face +Z, so their front "
                    "and text read unmirrored; the bundled Cornell box opens towards -z)")
        ->check(CLI::IsMember({"+x", "-x", "+y", "-y", "+z", "-z"}))
        ->capture_default_str();
    cmd->add_option("--fov", o.fovDeg, "vertical field of view, degrees")
        ->check(CLI::Range(1.0f, 170.0f))
        ->capture_default_str();
    cmd->add_option("--size", o.size, "image width,height in pixels")
        ->delimiter(',')
        ->expected(2)
        ->check(CLI::Range(1u, 16384u))
        ->capture_default_str();
}

Result<runtime::Camera> chooseCamera(const CameraOptions& o, const grid::Aabb& framed,
                                     float aspect) {
    if (o.camera.empty()) {
        const glm::vec3 axis = o.cameraFrom[1] == 'x'   ? glm::vec3(1, 0, 0)
                               : o.cameraFrom[1] == 'y' ? glm::vec3(0, 1, 0)
                                                        : glm::vec3(0, 0, 1);
        return runtime::frameBounds(framed, o.fovDeg, aspect,
                                    o.cameraFrom[0] == '-' ? -axis : axis);
    }
    runtime::Camera camera;
    camera.eye = glm::vec3(o.camera[0], o.camera[1], o.camera[2]);
    camera.target = glm::vec3(o.camera[3], o.camera[4], o.camera[5]);
    camera.verticalFovDeg = o.fovDeg;
    const glm::vec3 forward = camera.target - camera.eye;
    if (!(glm::length(forward) > 0.0f)) {
        return makeError(ErrorCode::InvalidArgument, "--camera: the eye and the target coincide");
    }
    // Looking straight up or down: +Y cannot be "up", so -Z is.
    if (glm::length(glm::cross(glm::normalize(forward), glm::vec3(0, 1, 0))) < 1e-4f) {
        camera.up = glm::vec3(0.0f, 0.0f, -1.0f);
    }
    const float reach = glm::length(forward) + glm::length(framed.size()) +
                        glm::length(camera.eye - framed.center());
    camera.nearPlane = std::max(1e-4f, 1e-3f * reach);
    camera.farPlane = 2.0f * reach + 1.0f;
    return camera;
}

} // namespace probekit::cli
