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
//   courtyard  An open-topped 16 m x 16 m courtyard (interior x, z in -8..8, paving at y = 0)
//              inside four 6 m high, 0.2 m thick walls: plaster at -z and +z, terracotta
//              (0.66, 0.3, 0.18) at +x, sage (0.35, 0.55, 0.35) at -x. Along the -z wall a
//              colonnade: a walkway 2.5 m deep (z -8..-5.5) under a 0.25 m roof slab whose
//              underside is 3.5 m up, on eight 0.4 m square columns at x = -7, -5, ..., 7. A
//              fountain (2.8 m x 0.5 m plinth, 0.6 m x 0.7 m pedestal) at the centre. Every
//              piece is a closed box (192 triangles). One directional sun of 3 W/m^2 x colour
//              (1, 0.95, 0.85), 50 degrees up, shining from +z turned 30 degrees towards +x.
//              No sky: environments are bake settings (examples/courtyard-bake.json).
//   courtyard-overcast  The courtyard without its sun: lit by the bake's sky alone.
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
