// probekit::baker generators — the scenes probekit bundles and tests with, built in code and
// written as glTF 2.0 (a .gltf with an external .bin beside it).
//
//   cornell    The Cornell box from the published Cornell University Program of Computer
//              Graphics measurements (geometry in millimetres, converted to metres), with the
//              usual RGB fits of its spectral reflectances (white 0.73, red (0.63, 0.065,
//              0.05), green (0.14, 0.45, 0.091)) and an emitter of radiance (17, 12, 4)
//              hanging 1 mm below the ceiling opening. Open at z = 0 (the camera side).
//   thin-wall  Two 4 m x 2.5 m x 4 m rooms side by side, split by a 5 cm wall with a
//              doorway (0.8 m wide, 2 m high) at its +z end; a 20 W/sr point light in the -x
//              room. Albedo 0.6 everywhere. For leak tests.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Names accepted by writeGeneratedScene, in a stable order.
std::vector<std::string> generatedSceneNames();

// Writes scene `name` to `path` (.gltf) plus `path` with extension .bin. Errors name the
// scene or file.
Result<void> writeGeneratedScene(const std::string& name, const std::filesystem::path& path);

} // namespace probekit::baker
