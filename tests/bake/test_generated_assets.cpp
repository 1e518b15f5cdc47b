// The generated scenes that stand in for third-party assets (generators.hpp): critter-cm,
// text-floor, lone-box and engine-mm, and the game levels arena and arena-sealed. Each is written
// by writeGeneratedScene, loaded through loadGltf like any user file, and checked for what it was
// built to exercise: its triangle count and bounds in the file's own units (centimetres and
// millimetres read as metres, the way formats/CONVENTIONS.md reads every glTF), its textures
// decoded and sampled by albedoAt as designed, its lights, and a small bake whose figures follow
// from those lights.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/sh.hpp"

using namespace probekit;
using namespace probekit::baker;
namespace fs = std::filesystem;

namespace {

// Coordinates are float sums of the generator's decimal constants (up to 1500 file units):
// a few float ulps, far below a millimetre of a misplaced part.
constexpr float kBoundsTolerance = 1e-3f;
// An 8-bit sRGB value decoded by the exact EOTF in double, then stored as float: 1e-7; the
// bilinear lookup between two equal texels adds another float rounding.
constexpr float kTexelTolerance = 1e-5f;

// The scene `name` written into a folder of this test's own and loaded like a user file.
struct Generated {
    fs::path dir;
    Scene scene;
};

Generated writeAndLoad(const std::string& name) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    Generated g{test::tempDir(std::string("assets_") + info->name()), {}};
    const Result<void> written = writeGeneratedScene(name, g.dir / (name + ".gltf"));
    EXPECT_TRUE(written.ok()) << (written.ok() ? "" : written.error().message);
    g.scene = test::loadOrFail(g.dir / (name + ".gltf"));
    // The scenes in centimetres and millimetres are read as metres here, which the loader
    // says, naming the scale that fits; nothing else may warn.
    const bool wrong_units = name.ends_with("-cm") || name.ends_with("-mm");
    EXPECT_EQ(g.scene.warnings.size(), wrong_units ? 1u : 0u)
        << (g.scene.warnings.empty() ? "" : g.scene.warnings.front());
    if (wrong_units && !g.scene.warnings.empty()) {
        const std::string scale = name.ends_with("-cm") ? "--scale 0.01" : "--scale 0.001";
        EXPECT_NE(g.scene.warnings.front().find(scale), std::string::npos)
            << g.scene.warnings.front();
    }
    return g;
}

double srgbToLinear(int value) {
    const double e = value / 255.0;
    return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
}

glm::vec3 linear(int r, int g, int b) {
    return glm::vec3(float(srgbToLinear(r)), float(srgbToLinear(g)), float(srgbToLinear(b)));
}

int materialIndex(const Scene& scene, const std::string& name) {
    for (size_t i = 0; i < scene.materials.size(); ++i) {
        if (scene.materials[i].name == name) {
            return int(i);
        }
    }
    ADD_FAILURE() << "no material '" << name << "'";
    return -1;
}

// World bounds of the triangles of one material.
grid::Aabb materialBounds(const Scene& scene, int material) {
    grid::Aabb box{glm::vec3(1e30f), glm::vec3(-1e30f)};
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
        if (int(scene.triangleMaterial[t]) != material) {
            continue;
        }
        for (int k = 0; k < 3; ++k) {
            box.min = glm::min(box.min, scene.positions[scene.triangles[t][k]]);
            box.max = glm::max(box.max, scene.positions[scene.triangles[t][k]]);
        }
    }
    return box;
}

void expectNear(glm::vec3 actual, glm::vec3 expected, float tolerance, const std::string& what) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(actual[c], expected[c], tolerance) << what << " [" << c << "]";
    }
}

glm::vec2 uvAt(const Scene& scene, size_t tri, glm::vec2 bary) {
    const glm::uvec3 t = scene.triangles[tri];
    return (1.0f - bary.x - bary.y) * scene.uvs[t.x] + bary.x * scene.uvs[t.y] +
           bary.y * scene.uvs[t.z];
}

// Whether a bilinear lookup at texture coordinate `coord` (u or v) of a `size`-texel axis reads
// two texels of the same `cell`-texel square of the pattern: then it returns that square's
// colour exactly.
bool insideOneCell(float coord, int size, int cell) {
    const float texel = coord * float(size) - 0.5f;
    const int lo = int(std::floor(texel));
    return lo >= 0 && lo + 1 < size && lo / cell == (lo + 1) / cell;
}

// Irradiance E(normal) of the L2 projection of each light's unshadowed delta at `point`, the
// way a probe stores direct light (formats/CONVENTIONS.md: a delta of irradiance e from
// direction d has coefficients e Y_lm(d)).
glm::vec3 directL2(const Scene& scene, glm::vec3 point, glm::vec3 normal) {
    glm::vec3 e(0.0f);
    for (const PunctualLight& light : scene.lights) {
        const auto to = directionToLight(light, point);
        const glm::vec3 facing = normalIrradianceAt(light, point);
        e += sh::irradiance(sh::projectDelta(to->direction, facing, sh::Order::L2), sh::Order::L2,
                            normal);
    }
    return e;
}

// One centre-mode probe at each point, `samples` directions each, nothing dilated.
std::vector<sh::ShRgb> bakeAt(const Scene& scene, const std::vector<glm::vec3>& points,
                              uint32_t samples) {
    BakeConfig config = test::probesAt(points, 0.01f);
    config.path.samples = samples;
    config.dilate = false;
    const Result<BakeResult> result = bake(scene, config);
    EXPECT_TRUE(result.ok()) << (result.ok() ? "" : result.error().message);
    std::vector<sh::ShRgb> probes;
    if (result.ok()) {
        for (const Volume& v : result.value().file.volumes) {
            EXPECT_EQ(v.validity, std::vector<uint8_t>{1}) << v.desc.name << " is in open air";
            probes.push_back(v.probe(0));
        }
    }
    return probes;
}

std::vector<uint8_t> fileBytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

const glm::vec3 kUp(0.0f, 1.0f, 0.0f);

} // namespace

// ---------------------------------------------------------------------------------------------
// critter-cm

TEST(GeneratedCritterCm, CentimetreGeometryStripedTextureAndExporterSun) {
    const Generated g = writeAndLoad("critter-cm");
    const Scene& scene = g.scene;
    // Ground 2; body and abdomen 32 x (2 x 16 - 2) = 960 each; eyes 12 x 10 = 120 each;
    // 16 leg cylinders 4 x 12 = 48 each.
    EXPECT_EQ(scene.triangles.size(), 2u + 2 * 960 + 2 * 120 + 16 * 48);
    // Read as metres, the file is 100x too big: a 5 m ground square spans 500 units and the
    // knees stand 55 units (+ the 0.5 unit leg radius) above it.
    EXPECT_NEAR(scene.bounds.min.x, -250.0f, kBoundsTolerance);
    EXPECT_NEAR(scene.bounds.max.z, 250.0f, kBoundsTolerance);
    EXPECT_NEAR(scene.bounds.min.y, 0.0f, kBoundsTolerance);
    EXPECT_GT(scene.bounds.max.y, 55.0f);
    EXPECT_LT(scene.bounds.max.y, 55.5f);
    const int body = materialIndex(scene, "body");
    const grid::Aabb body_box = materialBounds(scene, body);
    EXPECT_NEAR(body_box.min.x, -46.0f, kBoundsTolerance) << "abdomen tip";
    EXPECT_NEAR(body_box.max.x, 16.0f, kBoundsTolerance) << "front of the cephalothorax";
    const grid::Aabb legs_box = materialBounds(scene, materialIndex(scene, "legs"));
    EXPECT_NEAR(legs_box.max.z - legs_box.min.z, 121.0f, 0.5f) << "feet 60 units to each side";

    // The texture is an external PNG beside the .gltf, decoded from sRGB.
    EXPECT_TRUE(fs::exists(g.dir / "critter-cm-stripes.png"));
    ASSERT_EQ(scene.images.size(), 1u);
    ASSERT_EQ(scene.materials[size_t(body)].baseColorTexture, 0);
    EXPECT_EQ(scene.images[0].width, 64u);
    EXPECT_EQ(scene.images[0].height, 64u);
    // Stripes of 8 rows alternating orange (214, 140, 60) and dark brown (70, 40, 25); each
    // covers two of the 16 rings of the body parts, so every body triangle's centroid reads one
    // stripe's colour exactly.
    const glm::vec3 orange = linear(214, 140, 60), brown = linear(70, 40, 25);
    size_t orange_count = 0, brown_count = 0;
    const glm::vec2 centroid(1.0f / 3.0f);
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
        if (int(scene.triangleMaterial[t]) != body) {
            continue;
        }
        const int stripe = int(uvAt(scene, t, centroid).y * 64.0f) / 8;
        const glm::vec3 expected = stripe % 2 == 0 ? orange : brown;
        (stripe % 2 == 0 ? orange_count : brown_count)++;
        expectNear(scene.albedoAt(uint32_t(t), centroid), expected, kTexelTolerance,
                   "triangle " + std::to_string(t));
        if (HasFailure()) {
            break;
        }
    }
    EXPECT_EQ(orange_count, brown_count) << "8 stripes of each colour, 4 rings each";
    EXPECT_EQ(orange_count + brown_count, 2u * 960);

    // One sun as exporters write it: 3 W/m^2 x 683 lm/W = 2049 lux, 40 deg up.
    ASSERT_EQ(scene.lights.size(), 1u);
    EXPECT_EQ(scene.lights[0].type, LightType::Directional);
    expectNear(scene.lights[0].intensity, glm::vec3(2049.0f), 1e-2f, "sun");
    EXPECT_NEAR(-scene.lights[0].direction.y, std::sin(40.0 * std::numbers::pi / 180.0), 1e-5);
}

TEST(GeneratedCritterCm, TheBodyShadowsTheGround) {
    const Generated g = writeAndLoad("critter-cm");
    // A probe 3 units above the ground in the open, and one where the line to the sun passes
    // through the body's centre (0, 28, 0): 25 units below it, back along the sun's direction.
    const glm::vec3 sun = g.scene.lights[0].direction;
    const glm::vec3 open(-120.0f, 3.0f, 120.0f);
    const glm::vec3 shadowed = glm::vec3(0.0f, 28.0f, 0.0f) + sun * (25.0f / -sun.y);
    const std::vector<sh::ShRgb> probes = bakeAt(g.scene, {open, shadowed}, 256);
    ASSERT_EQ(probes.size(), 2u);
    const glm::vec3 open_up = sh::irradiance(probes[0], sh::Order::L2, kUp);
    const glm::vec3 shadow_up = sh::irradiance(probes[1], sh::Order::L2, kUp);
    std::printf("[critter-cm] E(+Y) open %.1f, in the body's shadow %.1f (W/m^2, red)\n", open_up.x,
                shadow_up.x);
    // In the open the upper hemisphere holds the sun alone (no sky): its L2 delta exactly, up
    // to the thin legs' few hundredths of a steradian of bounce; in the shadow only the light
    // the ground throws back onto the body's underside, far below it.
    const glm::vec3 expected = directL2(g.scene, open, kUp);
    EXPECT_NEAR(open_up.x, expected.x, 0.02f * expected.x);
    EXPECT_GT(shadow_up.x, 0.0f) << "bounce light reaches under the body";
    EXPECT_LT(shadow_up.x, 0.2f * open_up.x);
}

TEST(GeneratedCritterCm, WritingIsDeterministic) {
    const Generated a = writeAndLoad("critter-cm");
    const fs::path again = a.dir / "again";
    fs::create_directories(again);
    ASSERT_TRUE(writeGeneratedScene("critter-cm", again / "critter-cm.gltf").ok());
    for (const char* file : {"critter-cm.gltf", "critter-cm.bin", "critter-cm-stripes.png"}) {
        EXPECT_EQ(fileBytes(a.dir / file), fileBytes(again / file)) << file;
    }
}

// ---------------------------------------------------------------------------------------------
// text-floor

TEST(GeneratedTextFloor, ThinLettersOnAPlateUnderAPointAndASpot) {
    const Generated g = writeAndLoad("text-floor");
    const Scene& scene = g.scene;
    // Floor 2, plate 12, three tiles 36, and "PROBEKIT" as 78 runs of font pixels, one box
    // (12 triangles) each: P 9, R 12, O 12, B 11, E 7, K 13, I 7, T 7.
    EXPECT_EQ(scene.triangles.size(), 2u + 12 + 36 + 78 * 12);
    EXPECT_TRUE(scene.images.empty());
    // The thin parts: letters 2.5 cm thick standing on a 2 cm plate, strokes 4 cm wide.
    const grid::Aabb letters = materialBounds(scene, materialIndex(scene, "letters"));
    expectNear(letters.min, {-0.94f, 0.02f, -0.0125f}, kBoundsTolerance, "letters min");
    expectNear(letters.max, {0.94f, 0.30f, 0.0125f}, kBoundsTolerance, "letters max");
    const grid::Aabb plate = materialBounds(scene, materialIndex(scene, "plate"));
    EXPECT_NEAR(plate.max.y - plate.min.y, 0.02f, kBoundsTolerance);
    expectNear(scene.bounds.min, {-3.0f, 0.0f, -3.0f}, kBoundsTolerance, "floor");

    ASSERT_EQ(scene.lights.size(), 2u);
    EXPECT_EQ(scene.lights[0].type, LightType::Point);
    EXPECT_EQ(scene.lights[1].type, LightType::Spot);
    EXPECT_NEAR(scene.lights[1].outerConeCos, std::cos(25.0 * std::numbers::pi / 180.0), 1e-5);
    // The spot is aimed at the middle of the text.
    const glm::vec3 aim = glm::normalize(glm::vec3(0.0f, 0.15f, 0.0f) - scene.lights[1].position);
    expectNear(scene.lights[1].direction, aim, 1e-5f, "spot axis");
}

TEST(GeneratedTextFloor, ProbeInFrontOfTheTextSeesBothLights) {
    const Generated g = writeAndLoad("text-floor");
    // 30 cm in front of the letters (the lights' side), facing them: both lights unoccluded.
    const glm::vec3 point(0.0f, 0.15f, -0.3f);
    const glm::vec3 towards_lights(0.0f, 0.0f, -1.0f);
    const std::vector<sh::ShRgb> probes = bakeAt(g.scene, {point}, 1024);
    ASSERT_EQ(probes.size(), 1u);
    const glm::vec3 e = sh::irradiance(probes[0], sh::Order::L2, towards_lights);
    const glm::vec3 direct = directL2(g.scene, point, towards_lights);
    std::printf("[text-floor] E(-Z) %.3f, of which direct %.3f (W/m^2, green)\n", e.y, direct.y);
    // Direct light plus the floor and tiles lit in front of the probe, which fill the lower
    // half of the hemisphere it faces: measured 1.33x the direct light at 1024 samples (noise
    // there ~1%); a floor that let the lights through or letters that blocked them would move
    // it past one of the bounds.
    for (int c = 0; c < 3; ++c) {
        EXPECT_GT(e[c], direct[c]) << "channel " << c;
        EXPECT_LT(e[c], 1.5f * direct[c]) << "channel " << c;
    }
}

// ---------------------------------------------------------------------------------------------
// lone-box

TEST(GeneratedLoneBox, OneClosedCheckeredBox) {
    const Generated g = writeAndLoad("lone-box");
    const Scene& scene = g.scene;
    EXPECT_EQ(scene.triangles.size(), 12u);
    EXPECT_EQ(scene.positions.size(), 24u) << "4 corners per face, each with its own uv";
    size_t meshes = 0;
    for (const SceneNode& n : scene.nodes) {
        meshes += n.hasMesh ? 1 : 0;
    }
    EXPECT_EQ(meshes, 1u) << "one object, nothing else";
    expectNear(scene.bounds.min, glm::vec3(-0.5f), kBoundsTolerance, "min");
    expectNear(scene.bounds.max, glm::vec3(0.5f), kBoundsTolerance, "max");
    // Closed and wound outwards: the signed volume is the cube's 1 m^3.
    double volume = 0.0;
    for (const glm::uvec3& t : scene.triangles) {
        const glm::dvec3 a = scene.positions[t.x], b = scene.positions[t.y],
                         c = scene.positions[t.z];
        volume += glm::dot(a, glm::cross(b, c)) / 6.0;
    }
    EXPECT_NEAR(volume, 1.0, 1e-6);

    // Every face carries the whole 8 x 8 checkerboard of 8-texel squares, grey (235, 235, 230)
    // where (column + row) is even, blue (40, 80, 160) where odd: albedoAt reads the square's
    // colour wherever the bilinear footprint stays inside one square.
    ASSERT_EQ(scene.images.size(), 1u);
    EXPECT_EQ(scene.images[0].width, 64u);
    const glm::vec3 grey = linear(235, 235, 230), blue = linear(40, 80, 160);
    size_t checked = 0, blue_count = 0;
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
        for (int i = 0; i < 16; ++i) {
            for (int j = 0; i + j < 16; ++j) {
                const glm::vec2 bary((float(i) + 0.3f) / 17.0f, (float(j) + 0.3f) / 17.0f);
                const glm::vec2 uv = uvAt(scene, t, bary);
                if (!insideOneCell(uv.x, 64, 8) || !insideOneCell(uv.y, 64, 8)) {
                    continue;
                }
                const bool odd = (int(uv.x * 8.0f) + int(uv.y * 8.0f)) % 2 == 1;
                blue_count += odd ? 1 : 0;
                ++checked;
                expectNear(scene.albedoAt(uint32_t(t), bary), odd ? blue : grey, kTexelTolerance,
                           "triangle " + std::to_string(t));
            }
        }
        if (HasFailure()) {
            break;
        }
    }
    EXPECT_GT(checked, 12u * 64) << "most sample points fall inside a square";
    EXPECT_GT(blue_count, checked / 3);
    EXPECT_LT(blue_count, 2 * checked / 3);
}

TEST(GeneratedLoneBox, SunAndTheConfigsSkyAboveItsShadowBelow) {
    Generated g = writeAndLoad("lone-box");
    ASSERT_EQ(g.scene.lights.size(), 1u);
    EXPECT_TRUE(g.scene.environment.isBlack()) << "no sky in the file";
    // The sky comes from the bake config, as in examples/courtyard-bake.json.
    EnvironmentConfig sky;
    sky.type = EnvironmentConfig::Type::Constant;
    sky.radiance = glm::vec3(0.3f, 0.4f, 0.6f);
    Result<Environment> environment = makeEnvironment(sky);
    ASSERT_TRUE(environment.ok()) << environment.error().message;
    g.scene.environment = std::move(environment).value();

    // 1 m above the top face, and 30 cm below the bottom one, where the sun (50 deg up) is
    // behind the box.
    const glm::vec3 above(0.0f, 1.5f, 0.0f), below(0.0f, -0.8f, 0.0f);
    const std::vector<sh::ShRgb> probes = bakeAt(g.scene, {above, below}, 1024);
    ASSERT_EQ(probes.size(), 2u);
    const glm::vec3 above_up = sh::irradiance(probes[0], sh::Order::L2, kUp);
    const glm::vec3 below_up = sh::irradiance(probes[1], sh::Order::L2, kUp);
    // Above: the sun's L2 delta plus the whole upper sky, pi x radiance (a constant is exact in
    // SH); the box below adds nothing to E(+Y) but band-2 ringing of its dim reflection.
    const glm::vec3 expected =
        directL2(g.scene, above, kUp) + std::numbers::pi_v<float> * sky.radiance;
    std::printf("[lone-box] E(+Y) above (%.3f, %.3f, %.3f), expected (%.3f, %.3f, %.3f); below "
                "(%.3f, %.3f, %.3f)\n",
                above_up.x, above_up.y, above_up.z, expected.x, expected.y, expected.z, below_up.x,
                below_up.y, below_up.z);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(above_up[c], expected[c], 0.05f * expected[c]) << "channel " << c;
        EXPECT_LT(below_up[c], 0.5f * above_up[c]) << "channel " << c;
    }
}

// ---------------------------------------------------------------------------------------------
// engine-mm

TEST(GeneratedEngineMm, DenseMillimetreMechanismUnderOneAreaLight) {
    const Generated g = writeAndLoad("engine-mm");
    const Scene& scene = g.scene;
    // Floor 2; metal: mounts, block, head and cover 7 boxes, 80 fins (84 boxes x 12), six spark
    // plug tubes 128 each, three pulleys 384 each, a flywheel 512; 108 bolts (washer 96 + head
    // 24); pipes: 48 runner segments 128 each, plenum 256, collector 128; 200 wire segments 48
    // each; the panel 2.
    const size_t metal = 87 * 12 + 6 * 128 + 3 * 384 + 512;
    const size_t pipes = 48 * 128 + 256 + 128;
    EXPECT_EQ(scene.triangles.size(), 2 + metal + 108 * 120 + pipes + 200 * 48 + 2);
    EXPECT_GT(scene.triangles.size(), 20000u);
    // Millimetres read as metres: a 2.4 km floor and the panel 1500 units up.
    expectNear(scene.bounds.min, {-1200.0f, 0.0f, -1200.0f}, kBoundsTolerance, "min");
    expectNear(scene.bounds.max, {1200.0f, 1500.0f, 1200.0f}, kBoundsTolerance, "max");
    const grid::Aabb engine = materialBounds(scene, materialIndex(scene, "metal"));
    expectNear(engine.min, {-360.0f, 0.0f, -230.0f}, kBoundsTolerance, "engine min");

    // The one emitter: a 400 x 400 unit panel.
    size_t emissive = 0;
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
        emissive += scene.materials[scene.triangleMaterial[t]].isEmissive() ? 1 : 0;
    }
    EXPECT_EQ(emissive, 2u);
    EXPECT_TRUE(scene.lights.empty());
    expectNear(scene.materials[size_t(materialIndex(scene, "panel"))].emission, {8.0f, 7.6f, 7.0f},
               1e-5f, "panel radiance");
}

TEST(GeneratedEngineMm, ProbeUnderThePanelGetsItsIrradiance) {
    const Generated g = writeAndLoad("engine-mm");
    // 600 units under the panel's centre, facing it. A uniform square of half side a at height
    // h gives E = 2 L (2 X / sqrt(1 + X^2) atan(X / sqrt(1 + X^2))), X = a / h, the sum of the
    // four corner configuration factors: 0.3874 L at X = 1/3. The L2 projection of a source
    // this small (a 25 deg cone) reads up to 6% more on its axis (a delta's clamped-cosine
    // lobe in L2 is 17/16 of it); band-2 ringing of the lit engine below moves it by a few %.
    const glm::vec3 point(0.0f, 900.0f, 0.0f);
    const std::vector<sh::ShRgb> probes = bakeAt(g.scene, {point}, 1024);
    ASSERT_EQ(probes.size(), 1u);
    const double x = 200.0 / 600.0, s = std::sqrt(1.0 + x * x);
    const double factor = 2.0 * (2.0 * x / s * std::atan(x / s));
    const glm::vec3 e = sh::irradiance(probes[0], sh::Order::L2, kUp);
    const float expected = float(factor * 8.0);
    std::printf("[engine-mm] E(+Y) %.3f under the panel, exact %.3f (W/m^2, red)\n", e.x, expected);
    EXPECT_GT(e.x, 0.95f * expected);
    EXPECT_LT(e.x, 1.12f * expected);
}

// ---------------------------------------------------------------------------------------------
// arena and arena-sealed: the game levels (issue 29)

TEST(GeneratedArena, ALevelInMetresLoadsWithoutAUnitsAlarmAndGetsAnEvenGrid) {
    for (const char* name : {"arena", "arena-sealed"}) {
        SCOPED_TRACE(name);
        const Generated g = writeAndLoad(name); // no warning: 4 m storeys read as metres
        const Scene& scene = g.scene;
        const bool sealed = std::string(name) == "arena-sealed";
        // 136 boxes of 12 triangles; the sealed one has its roof on top.
        EXPECT_EQ(scene.triangles.size(), sealed ? 1644u : 1632u);
        expectNear(scene.bounds.min, {-32.5f, -0.5f, -32.5f}, kBoundsTolerance, "min");
        expectNear(scene.bounds.max, {32.5f, sealed ? 8.5f : 8.0f, 32.5f}, kBoundsTolerance, "max");
        size_t spots = 0;
        for (const PunctualLight& l : scene.lights) {
            spots += l.type == LightType::Spot ? 1 : 0;
        }
        EXPECT_EQ(scene.lights.size(), 32u);
        EXPECT_EQ(spots, 4u);
        // Default placement: no padding (the open one is no closed object, the sealed one is
        // a level seen from its solid space), and bricked with level 0 under 1 m.
        Result<VolumePlan> plan = planVolumes(scene, BakeConfig{});
        ASSERT_TRUE(plan.ok()) << plan.error().message;
        EXPECT_EQ(plan.value().padding[0], 0.0f);
        EXPECT_EQ(plan.value().volumes[0].layout, VolumeLayout::Bricked);
        EXPECT_EQ(plan.value().volumes[0].grid.resolution(), glm::uvec3(32, 4, 32));
    }
}
