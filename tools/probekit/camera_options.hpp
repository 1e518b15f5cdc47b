// The view options `probekit render` and `probekit surface-reference` share, so that a
// reference and a render of the same options see the same pixels.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "probekit/formats/grid.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/runtime/renderer.hpp"

namespace probekit::cli {

struct CameraOptions {
    std::vector<float> camera; // eye x,y,z, target x,y,z; empty = frame the scene
    std::string cameraFrom = "+z";
    float fovDeg = 40.0f;
    std::vector<uint32_t> size{640, 480};
};

// --camera, --camera-from, --fov and --size.
void addCameraOptions(CLI::App* cmd, CameraOptions& o);

// --camera's eye and target, or (without it) the box `framed` seen from --camera-from's side
// (+z: glTF assets face +Z).
Result<runtime::Camera> chooseCamera(const CameraOptions& o, const grid::Aabb& framed,
                                     float aspect);

} // namespace probekit::cli
