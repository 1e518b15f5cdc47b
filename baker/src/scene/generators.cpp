#include "probekit/baker/generators.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <numbers>
#include <string_view>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include "probekit/formats/pvol.hpp"
#include "scene_spec.hpp"

namespace probekit::baker {
namespace {

using Json = nlohmann::json;
using namespace generated;

SceneSpec cornell() {
    SceneSpec s;
    s.materials = {{"white", glm::vec3(0.73f)},
                   {"red", glm::vec3(0.63f, 0.065f, 0.05f)},
                   {"green", glm::vec3(0.14f, 0.45f, 0.091f)},
                   {"light", glm::vec3(0.78f), glm::vec3(17.0f, 12.0f, 4.0f)}};
    // Published Cornell box data, millimetres.
    auto mm = [](float x, float y, float z) { return glm::vec3(x, y, z) * 0.001f; };
    MeshSpec white{0, {}, {}, {}}, red{1, {}, {}, {}}, green{2, {}, {}, {}}, light{3, {}, {}, {}};
    white.quad(mm(552.8f, 0, 0), mm(0, 0, 0), mm(0, 0, 559.2f), mm(549.6f, 0, 559.2f)); // floor
    white.quad(mm(556.0f, 548.8f, 0), mm(556.0f, 548.8f, 559.2f), mm(0, 548.8f, 559.2f),
               mm(0, 548.8f, 0)); // ceiling
    white.quad(mm(549.6f, 0, 559.2f), mm(0, 0, 559.2f), mm(0, 548.8f, 559.2f),
               mm(556.0f, 548.8f, 559.2f)); // back wall
    green.quad(mm(0, 0, 559.2f), mm(0, 0, 0), mm(0, 548.8f, 0),
               mm(0, 548.8f, 559.2f)); // right wall
    red.quad(mm(552.8f, 0, 0), mm(549.6f, 0, 559.2f), mm(556.0f, 548.8f, 559.2f),
             mm(556.0f, 548.8f, 0)); // left wall
    // Short block.
    white.quad(mm(130, 165, 65), mm(82, 165, 225), mm(240, 165, 272), mm(290, 165, 114));
    white.quad(mm(290, 0, 114), mm(290, 165, 114), mm(240, 165, 272), mm(240, 0, 272));
    white.quad(mm(130, 0, 65), mm(130, 165, 65), mm(290, 165, 114), mm(290, 0, 114));
    white.quad(mm(82, 0, 225), mm(82, 165, 225), mm(130, 165, 65), mm(130, 0, 65));
    white.quad(mm(240, 0, 272), mm(240, 165, 272), mm(82, 165, 225), mm(82, 0, 225));
    // Tall block.
    white.quad(mm(423, 330, 247), mm(265, 330, 296), mm(314, 330, 456), mm(472, 330, 406));
    white.quad(mm(423, 0, 247), mm(423, 330, 247), mm(472, 330, 406), mm(472, 0, 406));
    white.quad(mm(472, 0, 406), mm(472, 330, 406), mm(314, 330, 456), mm(314, 0, 456));
    white.quad(mm(314, 0, 456), mm(314, 330, 456), mm(265, 330, 296), mm(265, 0, 296));
    white.quad(mm(265, 0, 296), mm(265, 330, 296), mm(423, 330, 247), mm(423, 0, 247));
    // The light: 1 mm below the ceiling so it does not coincide with it.
    light.quad(mm(343, 547.8f, 227), mm(343, 547.8f, 332), mm(213, 547.8f, 332),
               mm(213, 547.8f, 227));
    s.meshes = {white, red, green, light};
    return s;
}

SceneSpec thinWall() {
    SceneSpec s;
    s.materials = {{"wall", glm::vec3(0.6f)}};
    MeshSpec m{0, {}, {}, {}};
    const float h = 2.5f;
    const float t = 0.025f; // half the wall thickness
    // Outer shell: floor, ceiling and four walls of the 8 m x 4 m footprint.
    m.box(glm::vec3(-4.0f, -0.1f, -2.0f), glm::vec3(4.0f, 0.0f, 2.0f));
    m.box(glm::vec3(-4.0f, h, -2.0f), glm::vec3(4.0f, h + 0.1f, 2.0f));
    m.box(glm::vec3(-4.1f, 0.0f, -2.0f), glm::vec3(-4.0f, h, 2.0f));
    m.box(glm::vec3(4.0f, 0.0f, -2.0f), glm::vec3(4.1f, h, 2.0f));
    m.box(glm::vec3(-4.0f, 0.0f, -2.1f), glm::vec3(4.0f, h, -2.0f));
    m.box(glm::vec3(-4.0f, 0.0f, 2.0f), glm::vec3(4.0f, h, 2.1f));
    // The dividing wall, 5 cm thick, with a doorway from z = 1.2 to 2.0 below y = 2.0.
    m.box(glm::vec3(-t, 0.0f, -2.0f), glm::vec3(t, h, 1.2f));
    m.box(glm::vec3(-t, 2.0f, 1.2f), glm::vec3(t, h, 2.0f));
    s.meshes = {m};
    s.lights = {{glm::vec3(-2.0f, 1.8f, -1.0f), glm::vec3(1.0f), 20.0f}};
    return s;
}

// The direction a sun's light travels when the sun stands `elevation_deg` above the horizon,
// seen from the origin towards +z turned `azimuth_deg` towards +x.
glm::vec3 sunDirection(float elevation_deg, float azimuth_deg) {
    const float elevation = elevation_deg * std::numbers::pi_v<float> / 180.0f;
    const float azimuth = azimuth_deg * std::numbers::pi_v<float> / 180.0f;
    const glm::vec3 to_sun(std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                           std::cos(azimuth) * std::cos(elevation));
    return -to_sun;
}

SceneSpec courtyard() {
    SceneSpec s;
    s.materials = {{"paving", glm::vec3(0.45f, 0.42f, 0.38f)},
                   {"plaster", glm::vec3(0.6f)},
                   {"terracotta", glm::vec3(0.66f, 0.3f, 0.18f)},
                   {"sage", glm::vec3(0.35f, 0.55f, 0.35f)},
                   {"marble", glm::vec3(0.75f, 0.74f, 0.7f)}};
    MeshSpec paving{0, {}, {}, {}}, plaster{1, {}, {}, {}}, terracotta{2, {}, {}, {}},
        sage{3, {}, {}, {}}, marble{4, {}, {}, {}};
    const float half = 8.0f; // the open interior spans -8..8 in x and z
    const float wall = 0.2f; // wall thickness, outside the interior
    const float height = 6.0f;
    // Paving slab under everything, and four walls standing on it: every piece a closed box,
    // so a probe inside one sees only back faces.
    paving.box(glm::vec3(-half - wall, -0.1f, -half - wall),
               glm::vec3(half + wall, 0.0f, half + wall));
    plaster.box(glm::vec3(-half - wall, 0.0f, -half - wall),
                glm::vec3(half + wall, height, -half)); // -z, behind the colonnade
    plaster.box(glm::vec3(-half - wall, 0.0f, half), glm::vec3(half + wall, height, half + wall));
    terracotta.box(glm::vec3(half, 0.0f, -half), glm::vec3(half + wall, height, half)); // +x
    sage.box(glm::vec3(-half - wall, 0.0f, -half), glm::vec3(-half, height, half));     // -x
    // Colonnade along the -z wall: a walkway 2.5 m deep under a roof slab whose underside is
    // 3.5 m up, carried by eight 0.4 m square columns 2 m apart, flush with the roof's edge.
    const float walk_edge = -half + 2.5f;
    const float roof = 3.5f;
    marble.box(glm::vec3(-half, roof, -half), glm::vec3(half, roof + 0.25f, walk_edge));
    for (int i = 0; i < 8; ++i) {
        const float x = -7.0f + 2.0f * float(i);
        marble.box(glm::vec3(x - 0.2f, 0.0f, walk_edge - 0.4f),
                   glm::vec3(x + 0.2f, roof, walk_edge));
    }
    // A fountain in the middle: a low basin plinth and a pedestal on it.
    marble.box(glm::vec3(-1.4f, 0.0f, -1.4f), glm::vec3(1.4f, 0.5f, 1.4f));
    marble.box(glm::vec3(-0.3f, 0.5f, -0.3f), glm::vec3(0.3f, 1.2f, 0.3f));
    s.meshes = {paving, plaster, terracotta, sage, marble};
    // The sun 50 degrees above the horizon, shining from the open +z side (30 degrees towards
    // +x), so the columns' shadows fall into the walkway while the roof shades its back.
    s.suns = {{sunDirection(50.0f, 30.0f), glm::vec3(1.0f, 0.95f, 0.85f), 3.0f}};
    return s;
}

// A two-colour pattern: texel (x, y) gets `second` where `pick` says so, else `first` (8-bit
// sRGB values, as an image editor would store them).
template <typename Pick>
TextureSpec twoColourTexture(std::string name, uint32_t size, glm::u8vec3 first, glm::u8vec3 second,
                             Pick pick) {
    TextureSpec t{std::move(name), size, size, {}};
    t.rgb.reserve(size_t(size) * size * 3);
    for (uint32_t y = 0; y < size; ++y) {
        for (uint32_t x = 0; x < size; ++x) {
            const glm::u8vec3 c = pick(x, y) ? second : first;
            t.rgb.insert(t.rgb.end(), {c.x, c.y, c.z});
        }
    }
    return t;
}

SceneSpec critterCm() {
    SceneSpec s;
    // Stripes of 8 texel rows from the top: rows 0-7 orange, 8-15 dark brown, and so on. On the
    // 16-ring body parts each stripe covers exactly two rings.
    s.textures = {twoColourTexture("stripes", 64, {214, 140, 60}, {70, 40, 25},
                                   [](uint32_t, uint32_t y) { return (y / 8) % 2 == 1; })};
    s.materials = {{"ground", glm::vec3(0.42f, 0.4f, 0.36f)},
                   {"body", glm::vec3(1.0f), glm::vec3(0.0f), 0},
                   {"legs", glm::vec3(0.2f, 0.13f, 0.08f)},
                   {"eyes", glm::vec3(0.03f)}};
    MeshSpec ground{0, {}, {}, {}}, body{1, {}, {}, {}}, legs{2, {}, {}, {}}, eyes{3, {}, {}, {}};
    // Centimetres throughout, as a modelling tool set to cm writes them: a 5 m ground square,
    // a body 62 cm long, legs 1 cm thick reaching 60 cm to the side.
    ground.quad({-250, 0, -250}, {-250, 0, 250}, {250, 0, 250}, {250, 0, -250});
    body.ellipsoid({0, 28, 0}, {16, 11, 13}, 32, 16);   // cephalothorax, x -16..16
    body.ellipsoid({-28, 32, 0}, {18, 14, 15}, 32, 16); // abdomen, x -46..-10
    eyes.ellipsoid({14, 32, 4}, glm::vec3(2), 12, 6);
    eyes.ellipsoid({14, 32, -4}, glm::vec3(2), 12, 6);
    for (int k = 0; k < 4; ++k) {
        for (const float side : {-1.0f, 1.0f}) {
            // Hip on the body's flank, knee high above it, foot on the ground (the cylinder's
            // lowest rim stays just above y = 0).
            const float x = 10.0f - 7.0f * float(k);
            const float reach = 25.0f - 10.0f * float(k);
            const glm::vec3 hip(x, 28, side * 10);
            const glm::vec3 knee(x + 0.5f * reach, 55, side * 35);
            const glm::vec3 foot(x + reach, 0.5f, side * 60);
            legs.cylinder(hip, knee, 0.5f, 12);
            legs.cylinder(knee, foot, 0.5f, 12);
        }
    }
    s.meshes = {ground, body, legs, eyes};
    // What glTF exporters write for a sun of 3 W/m^2: 3 x 683 lm/W = 2049 lux, which
    // formats/CONVENTIONS.md takes as 2049 W/m^2.
    s.suns = {{sunDirection(40.0f, 30.0f), glm::vec3(1.0f), 2049.0f}};
    return s;
}

SceneSpec textFloor() {
    SceneSpec s;
    s.materials = {{"floor", glm::vec3(0.55f, 0.4f, 0.28f)},
                   {"plate", glm::vec3(0.1f)},
                   {"letters", glm::vec3(0.8f)},
                   {"tiles", glm::vec3(0.6f, 0.6f, 0.55f)}};
    MeshSpec floor{0, {}, {}, {}}, plate{1, {}, {}, {}}, letters{2, {}, {}, {}},
        tiles{3, {}, {}, {}};
    floor.quad({-3, 0, -3}, {-3, 0, 3}, {3, 0, 3}, {3, 0, -3});
    // A 2 cm plate with "PROBEKIT" standing on it in a 5 x 7 pixel font: 4 cm pixels, 2.5 cm
    // deep, each row's run of pixels one box (strokes 4 cm wide, letters 2.5 cm thick).
    const float px = 0.04f, depth = 0.025f, plate_top = 0.02f;
    plate.box({-1.0f, 0.0f, -0.12f}, {1.0f, plate_top, 0.12f});
    static constexpr const char* kFont[8][7] = {
        {"11110", "10001", "10001", "11110", "10000", "10000", "10000"},  // P
        {"11110", "10001", "10001", "11110", "10100", "10010", "10001"},  // R
        {"01110", "10001", "10001", "10001", "10001", "10001", "01110"},  // O
        {"11110", "10001", "10001", "11110", "10001", "10001", "11110"},  // B
        {"11111", "10000", "10000", "11110", "10000", "10000", "11111"},  // E
        {"10001", "10010", "10100", "11000", "10100", "10010", "10001"},  // K
        {"01110", "00100", "00100", "00100", "00100", "00100", "01110"},  // I
        {"11111", "00100", "00100", "00100", "00100", "00100", "00100"}}; // T
    const float left = -0.5f * (8 * 6 - 1) * px;
    for (int letter = 0; letter < 8; ++letter) {
        for (int row = 0; row < 7; ++row) {
            const std::string_view bits = kFont[letter][row];
            const float y0 = plate_top + float(6 - row) * px;
            for (size_t x = 0; x < bits.size();) {
                if (bits[x] != '1') {
                    ++x;
                    continue;
                }
                const size_t end =
                    bits.find('0', x) == std::string_view::npos ? bits.size() : bits.find('0', x);
                const float x0 = left + float(letter * 6 + int(x)) * px;
                letters.box({x0, y0, -0.5f * depth},
                            {x0 + float(end - x) * px, y0 + px, 0.5f * depth});
                x = end;
            }
        }
    }
    // Three 2 cm stepping tiles in front of the plate.
    for (int i = 0; i < 3; ++i) {
        const float x = -0.6f + 0.6f * float(i);
        tiles.box({x - 0.2f, 0.0f, -0.8f}, {x + 0.2f, 0.02f, -0.4f});
    }
    s.meshes = {floor, plate, letters, tiles};
    s.lights = {{glm::vec3(-1.0f, 1.2f, -1.0f), glm::vec3(1.0f, 0.85f, 0.7f), 8.0f}};
    const glm::vec3 spot_at(1.2f, 2.0f, -1.6f);
    s.spots = {{spot_at, glm::normalize(glm::vec3(0.0f, 0.15f, 0.0f) - spot_at),
                glm::vec3(0.8f, 0.9f, 1.0f), 60.0f, 15.0f, 25.0f}};
    return s;
}

SceneSpec loneBox() {
    SceneSpec s;
    // An 8 x 8 checkerboard of 8-texel squares, light grey and blue; the top-left one grey.
    s.textures = {twoColourTexture("checker", 64, {235, 235, 230}, {40, 80, 160},
                                   [](uint32_t x, uint32_t y) { return (x / 8 + y / 8) % 2; })};
    s.materials = {{"box", glm::vec3(1.0f), glm::vec3(0.0f), 0}};
    MeshSpec box{0, {}, {}, {}};
    box.box(glm::vec3(-0.5f), glm::vec3(0.5f)); // every face the whole texture
    s.meshes = {box};
    s.suns = {{sunDirection(50.0f, 30.0f), glm::vec3(1.0f, 0.95f, 0.85f), 3.0f}};
    return s;
}

SceneSpec engineMm() {
    SceneSpec s;
    s.materials = {{"floor", glm::vec3(0.35f)},
                   {"metal", glm::vec3(0.3f, 0.31f, 0.33f)},
                   {"bolts", glm::vec3(0.55f)},
                   {"pipes", glm::vec3(0.45f, 0.3f, 0.2f)},
                   {"wires", glm::vec3(0.05f, 0.05f, 0.06f)},
                   {"panel", glm::vec3(0.8f), glm::vec3(8.0f, 7.6f, 7.0f)}};
    MeshSpec floor{0, {}, {}, {}}, metal{1, {}, {}, {}}, bolts{2, {}, {}, {}}, pipes{3, {}, {}, {}},
        wires{4, {}, {}, {}}, panel{5, {}, {}, {}};
    // Millimetres throughout, as CAD exports write them.
    floor.quad({-1200, 0, -1200}, {-1200, 0, 1200}, {1200, 0, 1200}, {1200, 0, -1200});
    for (const float x : {-250.0f, 250.0f}) {
        for (const float z : {-150.0f, 150.0f}) {
            metal.box({x - 30, 0, z - 30}, {x + 30, 100, z + 30}); // mounts
        }
    }
    metal.box({-300, 100, -180}, {300, 450, 180}); // block
    metal.box({-310, 450, -140}, {310, 530, 140}); // head
    metal.box({-290, 530, -90}, {290, 580, 90});   // cam cover
    for (int i = 0; i < 40; ++i) {                 // 3 mm cooling fins on both flanks
        const float x = -290.0f + 14.5f * float(i);
        metal.box({x, 140, 180}, {x + 3, 420, 230});
        metal.box({x, 140, -230}, {x + 3, 420, -180});
    }
    // Bolts: a hex head on a washer, along the head's flange and the cam cover.
    auto bolt = [&bolts](glm::vec3 at) {
        bolts.cylinder(at, at + glm::vec3(0, 3, 0), 11.0f, 24);
        bolts.cylinder(at + glm::vec3(0, 3, 0), at + glm::vec3(0, 11, 0), 8.0f, 6);
    };
    for (int i = 0; i < 30; ++i) {
        bolt({-290.0f + 20.0f * float(i), 530, 115});
        bolt({-290.0f + 20.0f * float(i), 530, -115});
    }
    for (int i = 0; i < 24; ++i) {
        bolt({-287.5f + 25.0f * float(i), 580, 70});
        bolt({-287.5f + 25.0f * float(i), 580, -70});
    }
    for (int c = 0; c < 6; ++c) {
        const float x = -250.0f + 100.0f * float(c);
        metal.cylinder({x, 580, 0}, {x, 640, 0}, 14.0f, 32); // spark plug tubes
        // Intake runners from the -z side of the head up to the plenum, exhaust down the +z side.
        const glm::vec3 intake[5] = {
            {x, 500, -140}, {x, 520, -200}, {x, 580, -250}, {x, 640, -280}, {x, 660, -300}};
        const glm::vec3 exhaust[5] = {
            {x, 490, 140}, {x, 470, 200}, {x, 400, 260}, {x, 300, 280}, {x, 220, 290}};
        for (int k = 0; k < 4; ++k) {
            pipes.cylinder(intake[k], intake[k + 1], 22.0f, 32);
            pipes.cylinder(exhaust[k], exhaust[k + 1], 20.0f, 32);
        }
    }
    pipes.cylinder({-330, 660, -300}, {330, 660, -300}, 60.0f, 64); // plenum
    pipes.cylinder({-330, 220, 290}, {330, 220, 290}, 35.0f, 32);   // collector
    metal.cylinder({-330, 300, 0}, {-305, 300, 0}, 110.0f, 96);     // pulleys at the front
    metal.cylinder({-360, 420, 80}, {-335, 420, 80}, 70.0f, 96);
    metal.cylinder({-360, 480, -90}, {-335, 480, -90}, 60.0f, 96);
    metal.cylinder({300, 260, 0}, {340, 260, 0}, 170.0f, 128); // flywheel
    // A harness of 3 mm-radius wires looping over the cam cover.
    for (int w = 0; w < 50; ++w) {
        const float x = -280.0f + 11.2f * float(w);
        const glm::vec3 path[5] = {
            {x, 540, -100}, {x + 4, 610, -70}, {x + 8, 625, 0}, {x + 4, 610, 70}, {x, 540, 100}};
        for (int k = 0; k < 4; ++k) {
            wires.cylinder(path[k], path[k + 1], 3.0f, 12);
        }
    }
    // The area light: a 400 mm square panel 1.5 m up, facing down.
    panel.quad({-200, 1500, -200}, {200, 1500, -200}, {200, 1500, 200}, {-200, 1500, 200});
    s.meshes = {floor, metal, bolts, pipes, wires, panel};
    return s;
}

// The glTF node rotation (x, y, z, w) that turns the light's local -Z into unit `direction`:
// the half-way quaternion (1 + a.d, a x d) normalised, a = -Z (never opposite to `direction`
// here: the suns and spots point downwards, never along +Z exactly).
Json rotationFromMinusZ(glm::vec3 direction) {
    const glm::vec3 a(0.0f, 0.0f, -1.0f);
    const glm::vec3 axis = glm::cross(a, direction);
    const float w = 1.0f + glm::dot(a, direction);
    const float norm = std::sqrt(glm::dot(axis, axis) + w * w);
    return {axis.x / norm, axis.y / norm, axis.z / norm, w / norm};
}

// The file name of texture `t` beside a scene written as `stem`.gltf.
std::string textureFileName(const std::string& stem, const TextureSpec& t) {
    return stem + "-" + t.name + ".png";
}

// Adds `s`'s materials to `j`; true when one needs KHR_materials_emissive_strength.
bool addGltfMaterials(const SceneSpec& s, Json& j) {
    j["materials"] = Json::array();
    bool uses_strength = false;
    for (const MaterialSpec& m : s.materials) {
        Json jm = {{"name", m.name},
                   {"doubleSided", true},
                   {"pbrMetallicRoughness",
                    {{"baseColorFactor", {m.albedo.x, m.albedo.y, m.albedo.z, 1.0f}},
                     {"metallicFactor", 0.0f},
                     {"roughnessFactor", 1.0f}}}};
        const float peak = std::max({m.emission.x, m.emission.y, m.emission.z});
        if (peak > 0.0f) {
            // emissiveFactor is limited to [0, 1]: the peak goes into emissive_strength.
            jm["emissiveFactor"] = {m.emission.x / peak, m.emission.y / peak, m.emission.z / peak};
            jm["extensions"]["KHR_materials_emissive_strength"] = {{"emissiveStrength", peak}};
            uses_strength = true;
        }
        if (m.texture >= 0) {
            // One glTF texture per image, all with the same sampler.
            jm["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", m.texture}};
        }
        j["materials"].push_back(jm);
    }
    return uses_strength;
}

// Adds `s`'s texture images (PNG files named after `stem`), one sampler shared by all.
void addGltfTextures(const SceneSpec& s, const std::string& stem, Json& j) {
    if (s.textures.empty()) {
        return;
    }
    // Linear filtering, repeat wrapping: what Image::sampleBilinear does (scene.hpp).
    j["samplers"] = Json::array(
        {{{"magFilter", 9729}, {"minFilter", 9729}, {"wrapS", 10497}, {"wrapT", 10497}}});
    j["images"] = Json::array();
    j["textures"] = Json::array();
    for (size_t t = 0; t < s.textures.size(); ++t) {
        j["images"].push_back({{"name", s.textures[t].name},
                               {"uri", textureFileName(stem, s.textures[t])},
                               {"mimeType", "image/png"}});
        j["textures"].push_back({{"source", t}, {"sampler", 0}});
    }
}

// Adds one mesh and node per MeshSpec, their arrays appended to `bin`.
void addGltfMeshes(const SceneSpec& s, Json& j, std::vector<uint8_t>& bin) {
    auto append = [&bin](const void* data, size_t bytes) {
        const size_t offset = bin.size();
        bin.resize(offset + bytes);
        std::memcpy(bin.data() + offset, data, bytes);
        return offset;
    };
    for (size_t mi = 0; mi < s.meshes.size(); ++mi) {
        const MeshSpec& mesh = s.meshes[mi];
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (const glm::vec3& p : mesh.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        const size_t pos_offset =
            append(mesh.positions.data(), mesh.positions.size() * sizeof(glm::vec3));
        const size_t idx_offset =
            append(mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t));
        const bool textured = s.materials[mesh.material].texture >= 0;
        const size_t uv_offset =
            textured ? append(mesh.uvs.data(), mesh.uvs.size() * sizeof(glm::vec2)) : 0;
        const size_t view = j["bufferViews"].size();
        j["bufferViews"].push_back({{"buffer", 0},
                                    {"byteOffset", pos_offset},
                                    {"byteLength", mesh.positions.size() * sizeof(glm::vec3)},
                                    {"target", 34962}});
        j["bufferViews"].push_back({{"buffer", 0},
                                    {"byteOffset", idx_offset},
                                    {"byteLength", mesh.indices.size() * sizeof(uint32_t)},
                                    {"target", 34963}});
        const size_t acc = j["accessors"].size();
        j["accessors"].push_back({{"bufferView", view},
                                  {"componentType", 5126},
                                  {"count", mesh.positions.size()},
                                  {"type", "VEC3"},
                                  {"min", {lo.x, lo.y, lo.z}},
                                  {"max", {hi.x, hi.y, hi.z}}});
        j["accessors"].push_back({{"bufferView", view + 1},
                                  {"componentType", 5125},
                                  {"count", mesh.indices.size()},
                                  {"type", "SCALAR"}});
        Json attributes = {{"POSITION", acc}};
        if (textured) {
            attributes["TEXCOORD_0"] = j["accessors"].size();
            j["accessors"].push_back({{"bufferView", j["bufferViews"].size()},
                                      {"componentType", 5126},
                                      {"count", mesh.uvs.size()},
                                      {"type", "VEC2"}});
            j["bufferViews"].push_back({{"buffer", 0},
                                        {"byteOffset", uv_offset},
                                        {"byteLength", mesh.uvs.size() * sizeof(glm::vec2)},
                                        {"target", 34962}});
        }
        j["meshes"].push_back({{"name", s.materials[mesh.material].name},
                               {"primitives",
                                {{{"attributes", attributes},
                                  {"indices", acc + 1},
                                  {"material", mesh.material},
                                  {"mode", 4}}}}});
        j["scenes"][0]["nodes"].push_back(j["nodes"].size());
        j["nodes"].push_back({{"name", s.materials[mesh.material].name}, {"mesh", mi}});
    }
}

// Adds the point, spot and directional lights as KHR_lights_punctual nodes.
void addGltfLights(const SceneSpec& s, Json& j) {
    if (s.lights.empty() && s.spots.empty() && s.suns.empty()) {
        return;
    }
    Json lights = Json::array();
    auto add_light_node = [&j, &lights](Json light, Json node) {
        node["name"] = "light" + std::to_string(lights.size());
        node["extensions"]["KHR_lights_punctual"] = {{"light", lights.size()}};
        lights.push_back(std::move(light));
        j["scenes"][0]["nodes"].push_back(j["nodes"].size());
        j["nodes"].push_back(std::move(node));
    };
    for (const PointLightSpec& l : s.lights) {
        add_light_node({{"type", "point"},
                        {"color", {l.color.x, l.color.y, l.color.z}},
                        {"intensity", l.intensity}},
                       {{"translation", {l.position.x, l.position.y, l.position.z}}});
    }
    for (const SpotLightSpec& l : s.spots) {
        const float to_rad = std::numbers::pi_v<float> / 180.0f;
        add_light_node({{"type", "spot"},
                        {"color", {l.color.x, l.color.y, l.color.z}},
                        {"intensity", l.intensity},
                        {"spot",
                         {{"innerConeAngle", l.innerConeDeg * to_rad},
                          {"outerConeAngle", l.outerConeDeg * to_rad}}}},
                       {{"translation", {l.position.x, l.position.y, l.position.z}},
                        {"rotation", rotationFromMinusZ(l.direction)}});
    }
    for (const DirectionalLightSpec& l : s.suns) {
        add_light_node({{"type", "directional"},
                        {"color", {l.color.x, l.color.y, l.color.z}},
                        {"intensity", l.intensity}},
                       {{"rotation", rotationFromMinusZ(l.direction)}});
    }
    j["extensions"]["KHR_lights_punctual"] = {{"lights", lights}};
    j["extensionsUsed"].push_back("KHR_lights_punctual");
}

// `stem` names the .bin and the texture PNGs written beside the .gltf.
Json buildGltf(const SceneSpec& s, const std::string& stem, std::vector<uint8_t>& bin) {
    Json j;
    j["asset"] = {{"version", "2.0"}, {"generator", "probekit " PROBEKIT_VERSION_STRING}};
    j["scene"] = 0;
    j["scenes"] = Json::array({{{"nodes", Json::array()}}});
    j["nodes"] = Json::array();
    j["meshes"] = Json::array();
    j["accessors"] = Json::array();
    j["bufferViews"] = Json::array();
    const bool uses_strength = addGltfMaterials(s, j);
    addGltfTextures(s, stem, j);
    addGltfMeshes(s, j, bin);
    addGltfLights(s, j);
    if (uses_strength) {
        j["extensionsUsed"].push_back("KHR_materials_emissive_strength");
    }
    j["buffers"] = Json::array({{{"uri", stem + ".bin"}, {"byteLength", bin.size()}}});
    return j;
}

// The generated scenes, in the order generatedSceneNames lists them.
struct NamedScene {
    const char* name;
    SceneSpec (*build)();
};

SceneSpec courtyardOvercast() {
    SceneSpec s = courtyard();
    s.suns.clear(); // lit by the bake's sky alone
    return s;
}

constexpr NamedScene kScenes[] = {
    {"cornell", cornell},      {"thin-wall", thinWall},
    {"courtyard", courtyard},  {"courtyard-overcast", courtyardOvercast},
    {"critter-cm", critterCm}, {"text-floor", textFloor},
    {"lone-box", loneBox},     {"engine-mm", engineMm},
    {"arena", arenaLevel},     {"arena-sealed", arenaSealed}};

// PNG bytes of `t` through OpenImageIO, encoded in memory so the file can be written atomically.
Result<std::vector<uint8_t>> encodePng(const TextureSpec& t) {
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    const std::string file = t.name + ".png";
    auto out = OIIO::ImageOutput::create("png");
    const OIIO::ImageSpec spec(int(t.width), int(t.height), 3, OIIO::TypeDesc::UINT8);
    if (!out || !out->set_ioproxy(&proxy) || !out->open(file, spec) ||
        !out->write_image(OIIO::TypeDesc::UINT8, t.rgb.data()) || !out->close()) {
        return makeError(ErrorCode::Io, "texture '" + t.name + "': cannot encode the PNG (" +
                                            (out ? out->geterror() : OIIO::geterror()) + ")");
    }
    return std::vector<uint8_t>(bytes.begin(), bytes.end());
}

} // namespace

std::vector<std::string> generatedSceneNames() {
    std::vector<std::string> names;
    for (const NamedScene& scene : kScenes) {
        names.emplace_back(scene.name);
    }
    return names;
}

Result<void> writeGeneratedScene(const std::string& name, const std::filesystem::path& path) {
    const auto* found = std::find_if(std::begin(kScenes), std::end(kScenes),
                                     [&name](const NamedScene& s) { return name == s.name; });
    if (found == std::end(kScenes)) {
        std::string known;
        for (const std::string& n : generatedSceneNames()) {
            known += (known.empty() ? "" : ", ") + n;
        }
        return makeError(ErrorCode::InvalidArgument,
                         "unknown scene '" + name + "' (known: " + known + ")");
    }
    const SceneSpec spec = found->build();
    const std::string stem = path.stem().string();
    std::vector<uint8_t> bin;
    const Json gltf = buildGltf(spec, stem, bin);
    // The buffer and the images first: a reader never sees a .gltf whose files are missing or
    // stale.
    for (const TextureSpec& t : spec.textures) {
        Result<std::vector<uint8_t>> png = encodePng(t);
        if (!png) {
            return makeError(png.error().code, path.string() + ": " + png.error().message);
        }
        if (auto w = writeFileAtomic(path.parent_path() / textureFileName(stem, t), png.value());
            !w) {
            return w;
        }
    }
    std::filesystem::path bin_path = path;
    bin_path.replace_extension(".bin");
    if (auto w = writeFileAtomic(bin_path, bin); !w) {
        return w;
    }
    return writeFileAtomic(path, std::string_view(gltf.dump(1)));
}

} // namespace probekit::baker
