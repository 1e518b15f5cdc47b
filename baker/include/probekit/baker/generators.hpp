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
//
// Scenes like the third-party assets users bring, which nobody tuned the baker for. Their
// units are what modelling tools write, not metres: read as metres (formats/CONVENTIONS.md)
// they are 100x or 1000x too big, as such files are.
//   critter-cm  A spider-like creature modelled in centimetres on a 500 x 500 unit ground
//              square (y = 0): body and abdomen ellipsoids 62 units long (x -46..16, 32
//              segments x 16 rings each) with a base-colour texture, an external PNG beside
//              the .gltf (NAME-stripes.png, 64 x 64: stripes of 8 texel rows from the top,
//              alternating sRGB (214, 140, 60) and (70, 40, 25)), two eyes, and eight legs of
//              two 1-unit-thick cylinders each reaching 60 units to the side and 55 up (2,930
//              triangles). One sun as glTF exporters write a 3 W/m^2 sun, 2,049 lux, 40
//              degrees up; no sky.
//   text-floor  A 6 m x 6 m floor (metres) with "PROBEKIT" in a 5 x 7 pixel font standing
//              on a 2 cm plate: 4 cm strokes, letters 2.5 cm thick and 28 cm high, each row's
//              run of pixels one box; three 2 cm floor tiles in front (986 triangles). Lit by
//              an 8 W/sr point light and a 60 W/sr spot (cones 15 and 25 degrees) aimed at
//              the text, both on its -z side.
//   lone-box    One closed 1 m cube (metres, centred on the origin), every face carrying the
//              whole texture NAME-checker.png (64 x 64: 8 x 8 squares, sRGB (235, 235, 230)
//              where column + row is even, (40, 80, 160) where odd), in open space: nothing
//              else, no ground. A 3 W/m^2 sun 50 degrees up; no sky in the file: bake with a
//              sky from the config or --env (e.g. --env 0.3,0.4,0.6,
//              examples/courtyard-bake.json's).
//   engine-mm   A dense engine-like mechanism in millimetres on a 2,400-unit floor square:
//              block, head and cover on four mounts, 80 cooling fins 3 units thick, 108 bolts,
//              intake and exhaust runners, pulleys, a flywheel and a harness of 200 wire
//              segments 6 units thick (32,568 triangles); lit only by a 400 x 400 unit
//              emissive panel 1,500 units up, radiance (8, 7.6, 7) W/(sr m^2).
//
// Game levels, built of closed boxes as level editors build them (level_generators.cpp):
//   arena       A 65 m x 65 m arena (metres, x and z in -32.5..32.5, ground at y = 0): brick
//              outer walls 8 m high; a 24 m open yard in the middle (x, z in -12..12) walled
//              by 0.3 m moss walls 4 m high with an arch (3 m x 3.2 m) and two doors in each;
//              eight roofed rooms (4 m, 0.3 m stone roofs) in the band around it, joined by
//              doors; a 3 m corridor along the north wall behind doors and arches; a 5 cm
//              partition in the south room; a 16-step stair from the yard onto the south
//              roof; columns, a plinth, four lamp posts and 24 crates. 32 lights: two 30 W/sr
//              points per room, four 10 W/sr in the corridor, eight 15 W/sr wall lamps and
//              four 200 W/sr spots (cones 25 and 35 degrees) over the yard. No sky in the
//              file: the yard and the roofs are open to the bake's environment.
//   arena-sealed  The arena under a 0.5 m roof on its outer walls (y = 8): a closed level
//              lit by its lights only.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Names accepted by writeGeneratedScene, in a stable order.
std::vector<std::string> generatedSceneNames();

// Writes scene `name` to `path` (.gltf) plus `path` with extension .bin and, for textured
// scenes, the PNGs beside it (STEM-NAME.png). Deterministic: the same bytes on every run.
// Errors name the scene or file.
Result<void> writeGeneratedScene(const std::string& name, const std::filesystem::path& path);

} // namespace probekit::baker
