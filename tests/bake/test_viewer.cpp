// probekit::viewer: a scene put on the renderer (flattening, lights, environment, framing, the
// placeholder volume) and on the dynamic GI (lights and sun, sky SH, cascades). CPU only: what
// the renderer then draws is tested against its CPU twins in tests/gpu.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bake_test_support.hpp"
#include "probekit/viewer/scene_gi.hpp"
#include "probekit/viewer/scene_view.hpp"
#include "probekit/viewer/surface_view.hpp"

namespace probekit {
namespace {

constexpr float kPi = 3.14159265f;

// Two triangles and one degenerate one (all three corners on a line) in the z = 0 plane, one
// material; `normals` gives vertex normals of +z tilted in x for the first triangle.
baker::Scene twoTriangles(bool normals) {
    baker::Scene s;
    s.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 0, 0}, {3, 0, 0}};
    s.uvs.assign(s.positions.size(), glm::vec2(0.0f));
    s.triangles = {{0, 1, 2}, {1, 3, 2}, {0, 4, 5}};
    s.triangleMaterial = {0, 0, 0};
    baker::Material m;
    m.baseColor = glm::vec3(0.5f, 0.25f, 0.125f);
    m.emission = glm::vec3(2.0f);
    s.materials = {m};
    if (normals) {
        const glm::vec3 tilted = glm::normalize(glm::vec3(0.6f, 0.0f, 0.8f));
        s.normals = {tilted, tilted, tilted, glm::vec3(0.0f), tilted, tilted};
    }
    s.bounds = {glm::vec3(0.0f), glm::vec3(3.0f, 1.0f, 0.0f)};
    return s;
}

TEST(ViewerFlatten, DegenerateTrianglesAreSkippedAndNormalsFallBackToTheFace) {
    const viewer::RenderScene flat = viewer::flattenScene(twoTriangles(true));
    // Three vertices per kept triangle, indexed in order; the line (0, 4, 5) is left out.
    ASSERT_EQ(flat.vertices.size(), 6u);
    ASSERT_EQ(flat.indices.size(), 6u);
    ASSERT_EQ(flat.triangleTextures.size(), 2u);
    for (uint32_t i = 0; i < 6; ++i) {
        EXPECT_EQ(flat.indices[i], i);
    }
    // Triangle 0 has all three given normals; triangle 1 has a zero normal at vertex 3, so all
    // three of its vertices take the face normal +z.
    const glm::vec3 tilted = glm::normalize(glm::vec3(0.6f, 0.0f, 0.8f));
    for (int k = 0; k < 3; ++k) {
        EXPECT_LT(glm::length(flat.vertices[size_t(k)].normal - tilted), 1e-6f) << k;
        EXPECT_LT(glm::length(flat.vertices[size_t(3 + k)].normal - glm::vec3(0, 0, 1)), 1e-6f);
    }
    EXPECT_EQ(flat.vertices[4].position, glm::vec3(1, 1, 0));
    EXPECT_EQ(flat.vertices[0].albedo, glm::vec3(0.5f, 0.25f, 0.125f));
    EXPECT_EQ(flat.vertices[0].emission, glm::vec3(2.0f));
    EXPECT_EQ(flat.triangleTextures[0], -1);
    EXPECT_TRUE(flat.textures.empty());
    EXPECT_TRUE(flat.warnings.empty());
}

TEST(ViewerFlatten, WithoutNormalsEveryVertexTakesItsFaceNormal) {
    const viewer::RenderScene flat = viewer::flattenScene(twoTriangles(false));
    ASSERT_EQ(flat.vertices.size(), 6u);
    for (const runtime::RenderVertex& v : flat.vertices) {
        EXPECT_LT(glm::length(v.normal - glm::vec3(0, 0, 1)), 1e-6f);
    }
}

// Materials share a texture slot per image; past the renderer's limit the rest fall back to
// per-vertex albedo (texture -1), with one warning however many are dropped.
TEST(ViewerFlatten, TexturesGetOneSlotPerImageUpToTheRendererLimit) {
    baker::Scene s = twoTriangles(false);
    const size_t images = runtime::kMaxRenderTextures + 2;
    s.images.assign(images, RgbaImage{1, 1, {glm::vec4(0.5f)}});
    s.materials.clear();
    s.positions.clear();
    s.triangles.clear();
    s.triangleMaterial.clear();
    for (size_t i = 0; i < images; ++i) {
        baker::Material m;
        m.baseColorTexture = int(i);
        s.materials.push_back(m);
        const glm::vec3 o(float(i), 0.0f, 0.0f);
        const uint32_t base = uint32_t(s.positions.size());
        s.positions.insert(s.positions.end(), {o, o + glm::vec3(1, 0, 0), o + glm::vec3(0, 1, 0)});
        s.triangles.push_back({base, base + 1, base + 2});
        s.triangleMaterial.push_back(uint32_t(i));
    }
    // A second triangle on image 0 reuses its slot.
    s.triangles.push_back({0, 1, 2});
    s.triangleMaterial.push_back(0);
    s.uvs.assign(s.positions.size(), glm::vec2(0.0f));
    const viewer::RenderScene flat = viewer::flattenScene(s);
    ASSERT_EQ(flat.triangleTextures.size(), images + 1);
    EXPECT_EQ(flat.textures.size(), runtime::kMaxRenderTextures);
    EXPECT_EQ(flat.triangleTextures[0], 0);
    EXPECT_EQ(flat.triangleTextures[runtime::kMaxRenderTextures - 1],
              int32_t(runtime::kMaxRenderTextures - 1));
    EXPECT_EQ(flat.triangleTextures[runtime::kMaxRenderTextures], -1);
    EXPECT_EQ(flat.triangleTextures[images - 1], -1);
    EXPECT_EQ(flat.triangleTextures[images], 0);
    ASSERT_EQ(flat.warnings.size(), 1u);
    EXPECT_NE(flat.warnings[0].find("1024 base-colour textures"), std::string::npos)
        << flat.warnings[0];
}

TEST(ViewerScene, FramedBoxIsTheSceneOrTheVolumesWithoutGeometry) {
    const baker::Scene with = twoTriangles(false);
    EXPECT_EQ(viewer::framedBox(with, {}).max, glm::vec3(3.0f, 1.0f, 0.0f));

    baker::Scene empty;
    empty.bounds = {glm::vec3(-1.0f), glm::vec3(1.0f)};
    std::vector<Volume> volumes;
    for (const glm::vec3 corner : {glm::vec3(0.0f), glm::vec3(5.0f, -2.0f, 1.0f)}) {
        baker::Scene holder;
        holder.bounds = {corner, corner + glm::vec3(1.0f)};
        Result<Volume> v = viewer::placeholderVolume(holder);
        ASSERT_TRUE(v.ok()) << v.error().message;
        volumes.push_back(std::move(v.value()));
    }
    const grid::Aabb box = viewer::framedBox(empty, volumes);
    EXPECT_EQ(box.min, glm::vec3(0.0f, -2.0f, 0.0f));
    EXPECT_EQ(box.max, glm::vec3(6.0f, 1.0f, 2.0f));
}

TEST(ViewerScene, PlaceholderIsEightZeroProbesOverTheScene) {
    baker::Scene flat_scene = twoTriangles(false); // zero extent in z
    Result<Volume> v = viewer::placeholderVolume(flat_scene);
    ASSERT_TRUE(v.ok()) << v.error().message;
    EXPECT_EQ(v.value().desc.grid.resolution(), glm::uvec3(2));
    EXPECT_EQ(v.value().desc.shOrder, sh::Order::L1);
    const grid::Aabb b = v.value().desc.grid.worldBounds();
    EXPECT_EQ(b.min, glm::vec3(0.0f));
    EXPECT_NEAR(b.max.z, 1e-3f, 1e-7f); // a flat scene gets a millimetre of depth
    const sh::ShRgb probe = v.value().probe(0);
    EXPECT_EQ(sh::irradiance(probe, sh::Order::L1, glm::vec3(0, 1, 0)), glm::vec3(0.0f));
}

TEST(ViewerScene, DirectLightsKeepTheRendererLimitAndCountTheRest) {
    baker::Scene s;
    s.lights.resize(runtime::kMaxRenderLights + 3);
    for (size_t i = 0; i < s.lights.size(); ++i) {
        s.lights[i].name = std::to_string(i);
    }
    // A file that records no light modes: every light is the renderer's to add.
    const Result<viewer::LightSelection> chosen = viewer::directLights(s, BakeMetadata{}, "f");
    ASSERT_TRUE(chosen.ok()) << chosen.error().message;
    ASSERT_EQ(chosen.value().lights.size(), runtime::kMaxRenderLights);
    EXPECT_EQ(chosen.value().lights.back().name, std::to_string(runtime::kMaxRenderLights - 1));
    EXPECT_EQ(chosen.value().dropped, 3u);
    EXPECT_EQ(chosen.value().baked, 0u);
}

// With recorded light modes only the lights whose direct light the bake left out are added:
// here light "1" (indirect, by name) and light 2 (none, by index); the rest are baked.
TEST(ViewerScene, DirectLightsAreTheLightsTheBakeLeftOut) {
    baker::Scene s;
    s.lights.resize(4);
    for (size_t i = 0; i < s.lights.size(); ++i) {
        s.lights[i].name = "l"; // appended, not operator+: a GCC 12 -Wrestrict false positive
        s.lights[i].name += std::to_string(i);
    }
    BakeMetadata m;
    m.parametersJson =
        R"({"lights": {"mode": "baked", "per_light": {"l1": "indirect", "2": "none"}}})";
    const Result<viewer::LightSelection> chosen = viewer::directLights(s, m, "f.pvol");
    ASSERT_TRUE(chosen.ok()) << chosen.error().message;
    ASSERT_EQ(chosen.value().lights.size(), 2u);
    EXPECT_EQ(chosen.value().lights[0].name, "l1");
    EXPECT_EQ(chosen.value().lights[1].name, "l2");
    EXPECT_EQ(chosen.value().baked, 2u);
    // A recorded key the scene shown has no light for names the file.
    m.parametersJson = R"({"lights": {"per_light": {"lamp": "indirect"}}})";
    const Result<viewer::LightSelection> bad = viewer::directLights(s, m, "f.pvol");
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("f.pvol: lights.per_light.\"lamp\""), std::string::npos)
        << bad.error().message;
}

TEST(ViewerEnvironment, SpecsAreReadAsBakeReadsThem) {
    Result<Environment> none = viewer::environmentFromSpec("none", "--env");
    ASSERT_TRUE(none.ok()) << none.error().message;
    EXPECT_TRUE(none.value().isBlack());

    Result<Environment> constant = viewer::environmentFromSpec("0.5,0.25,2", "--env");
    ASSERT_TRUE(constant.ok()) << constant.error().message;
    EXPECT_EQ(constant.value().radiance(glm::vec3(0, -1, 0)), glm::vec3(0.5f, 0.25f, 2.0f));

    // Anything else is a lat-long file; a missing one is an error naming it.
    Result<Environment> missing = viewer::environmentFromSpec("no-such-sky.hdr", "--env");
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.error().message.find("no-such-sky.hdr"), std::string::npos)
        << missing.error().message;
}

TEST(ViewerEnvironment, RecordedSettingsGiveTheBakesEnvironmentOrBlackWithAWarning) {
    std::string warning;
    BakeMetadata metadata;
    // The working directory, where "gone.exr" below would be.
    const std::vector<std::filesystem::path> roots = {std::filesystem::current_path()};
    metadata.parametersJson = R"({"path": {"samples": 64}})";
    Result<Environment> unrecorded =
        viewer::recordedEnvironment(metadata, "v.pvol", roots, warning);
    ASSERT_TRUE(unrecorded.ok());
    EXPECT_TRUE(unrecorded.value().isBlack());
    EXPECT_TRUE(warning.empty());

    metadata.parametersJson = R"({"environment": {"type": "constant", "radiance": [1, 2, 3]}})";
    Result<Environment> constant = viewer::recordedEnvironment(metadata, "v.pvol", roots, warning);
    ASSERT_TRUE(constant.ok()) << constant.error().message;
    EXPECT_EQ(constant.value().radiance(glm::vec3(1, 0, 0)), glm::vec3(1.0f, 2.0f, 3.0f));
    EXPECT_TRUE(warning.empty());

    // A recorded file that is gone: black, and the warning names it.
    metadata.parametersJson = R"({"environment": {"type": "latlong", "file": "gone.exr"}})";
    Result<Environment> gone = viewer::recordedEnvironment(metadata, "v.pvol", roots, warning);
    ASSERT_TRUE(gone.ok());
    EXPECT_TRUE(gone.value().isBlack());
    EXPECT_NE(warning.find("gone.exr"), std::string::npos) << warning;

    // A record that is not a valid environment is an error naming the .pvol.
    warning.clear();
    metadata.parametersJson = R"({"environment": {"type": "sunny"}})";
    Result<Environment> bad = viewer::recordedEnvironment(metadata, "v.pvol", roots, warning);
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("v.pvol"), std::string::npos) << bad.error().message;
}

// A 2 x 1 grey PFM lat-long map of radiance `value` everywhere.
void writeGreyPfm(const std::filesystem::path& path, float value) {
    const std::string header = "Pf\n2 1\n-1.0\n";
    const float texels[2] = {value, value};
    std::ofstream out(path, std::ios::binary);
    out.write(header.data(), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(texels), sizeof texels);
}

// Settings recording a lat-long environment `file`.
BakeMetadata recordingEnvironment(const std::string& file) {
    BakeMetadata m;
    nlohmann::json settings;
    settings["environment"] = {{"type", "latlong"}, {"file", file}};
    m.parametersJson = settings.dump();
    return m;
}

// Issue 31: a .pvol is untrusted, so the environment file it records is opened only under the
// allowed folders (render: the scene's and the .pvol's). Outside them, by an absolute path, by
// `..` or through a link, nothing is opened: black, as without a record, and a warning naming
// the file. Inside, the map loads.
TEST(ViewerEnvironment, RecordedFilesOutsideTheAllowedFoldersAreNotOpened) {
    const std::filesystem::path dir = test::tempDir("viewer_env_rule");
    std::filesystem::create_directories(dir / "scene");
    std::filesystem::create_directories(dir / "outside");
    writeGreyPfm(dir / "scene" / "sky.pfm", 3.0f);
    writeGreyPfm(dir / "outside" / "sky.pfm", 5.0f);
    std::filesystem::create_symlink(dir / "outside" / "sky.pfm", dir / "scene" / "link.pfm");
    const std::vector<std::filesystem::path> roots = {dir / "scene"};

    std::string warning;
    Result<Environment> inside = viewer::recordedEnvironment(
        recordingEnvironment((dir / "scene" / "sky.pfm").string()), "v.pvol", roots, warning);
    ASSERT_TRUE(inside.ok()) << inside.error().message;
    // The 2 x 1 map is 3 everywhere; bilinear weights summing to 1 round within a few ulps.
    const glm::vec3 seen = inside.value().radiance(glm::vec3(1, 0, 0));
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(seen[c], 3.0f, 1e-5f) << c;
    }
    EXPECT_TRUE(warning.empty()) << warning;

    const std::string outside_files[] = {
        (dir / "outside" / "sky.pfm").string(),                  // absolute, outside
        (dir / "scene" / ".." / "outside" / "sky.pfm").string(), // `..` out of the folder
        "../../outside/sky.pfm",               // relative to the working directory
        (dir / "scene" / "link.pfm").string(), // a link inside pointing out
        "/etc/passwd",
    };
    for (const std::string& file : outside_files) {
        warning.clear();
        Result<Environment> refused =
            viewer::recordedEnvironment(recordingEnvironment(file), "v.pvol", roots, warning);
        ASSERT_TRUE(refused.ok()) << file << ": " << refused.error().message;
        EXPECT_TRUE(refused.value().isBlack()) << file;
        EXPECT_EQ(refused.value().radiance(glm::vec3(1, 0, 0)), glm::vec3(0.0f)) << file;
        std::string expected = "v.pvol: environment file ";
        expected += file;
        expected += " recorded in the volume is outside the scene folder; not opened (pass --env "
                    "to use it)";
        EXPECT_TRUE(warning.starts_with(expected)) << warning;
    }
    std::filesystem::remove_all(dir);
}

// Settings nested past the JSON depth limit are an error naming the source, not a crash.
TEST(ViewerScene, DeeplyNestedSettingsAreAnErrorNamingTheSource) {
    BakeMetadata m;
    m.parametersJson.assign(100000, '[');
    m.parametersJson.append(100000, ']');
    std::string warning;
    const Result<Environment> env = viewer::recordedEnvironment(m, "deep.pvol", {}, warning);
    ASSERT_FALSE(env.ok());
    EXPECT_TRUE(env.error().message.starts_with("deep.pvol: JSON arrays and objects nest 100000"))
        << env.error().message;
    const Result<viewer::LightSelection> lights =
        viewer::directLights(baker::Scene{}, m, "deep.pvol");
    ASSERT_FALSE(lights.ok());
    EXPECT_TRUE(lights.error().message.starts_with("deep.pvol: JSON arrays and objects nest"))
        << lights.error().message;
}

// The dynamic GI's lights: with a volume only the directional ones (the volume holds the
// rest), without one every light; --sun-path makes a sun when there is none.
TEST(ViewerGi, DynamicLightsAndTheSun) {
    baker::Scene s;
    PunctualLight point;
    point.type = LightType::Point;
    PunctualLight directional;
    directional.type = LightType::Directional;
    s.lights = {point, directional};

    viewer::DynamicLights baked = viewer::dynamicLights(s, true, false);
    ASSERT_EQ(baked.lights.size(), 1u);
    EXPECT_EQ(baked.sun, 0u);
    viewer::DynamicLights alone = viewer::dynamicLights(s, false, false);
    ASSERT_EQ(alone.lights.size(), 2u);
    EXPECT_EQ(alone.sun, 1u);
    ASSERT_NE(alone.sunLight(), nullptr);
    EXPECT_EQ(alone.sunLight()->type, LightType::Directional);

    s.lights = {point};
    viewer::DynamicLights no_sun = viewer::dynamicLights(s, false, false);
    EXPECT_EQ(no_sun.sun, 1u);
    EXPECT_EQ(no_sun.sunLight(), nullptr);
    viewer::DynamicLights made = viewer::dynamicLights(s, false, true);
    ASSERT_EQ(made.lights.size(), 2u);
    EXPECT_EQ(made.sun, 0u);
    EXPECT_EQ(made.lights[0].intensity, glm::vec3(3.0f));
    EXPECT_EQ(made.lights[1].type, LightType::Point);
}

TEST(ViewerGi, SunTravelFollowsAzimuthAndElevation) {
    const std::array<float, 4> path = {0.0f, 90.0f, 90.0f, 0.0f};
    // Overhead: the light travels straight down. Azimuth 90 on the horizon: the sun stands in
    // +x, its light travels along -x. Half way: azimuth 45, elevation 45.
    EXPECT_LT(glm::length(viewer::sunTravel(path, 0.0f) - glm::vec3(0, -1, 0)), 1e-6f);
    EXPECT_LT(glm::length(viewer::sunTravel(path, 1.0f) - glm::vec3(-1, 0, 0)), 1e-6f);
    const glm::vec3 half = -glm::vec3(0.5f, std::sqrt(0.5f), 0.5f);
    EXPECT_LT(glm::length(viewer::sunTravel(path, 0.5f) - half), 1e-6f);
}

// Sky SH from 4096 Fibonacci directions. A constant sky's irradiance is pi x its radiance in
// every direction: band 0 integrates exactly, the higher bands sum to zero up to the
// quadrature's ~1e-4. A sky of 1 above the horizon and 0 below has the exact L2 irradiance pi
// up, pi/2 sideways and 0 down (its band 2 projection is zero); the Fibonacci points are
// stratified in height, so the step costs little, and the lat-long image's bilinear row across
// the horizon is antisymmetric about it: 1% of pi holds both with margin.
TEST(ViewerGi, SkyShIntegratesTheEnvironment) {
    Environment constant;
    constant.constant = glm::vec3(0.5f, 1.0f, 2.0f);
    const sh::ShRgb sky = viewer::skySh(constant);
    for (const glm::vec3 n : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0),
                              glm::normalize(glm::vec3(1, -2, 3))}) {
        const glm::vec3 e = sh::irradiance(sky, sh::Order::L2, n);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(e[c], kPi * constant.constant[c], 1e-3f * kPi * constant.constant[c]);
        }
    }

    Environment upper;
    upper.type = Environment::Type::LatLong;
    upper.image.width = 8;
    upper.image.height = 64;
    for (uint32_t row = 0; row < upper.image.height; ++row) {
        const float value = row < upper.image.height / 2 ? 1.0f : 0.0f; // row 0 is +y
        upper.image.texels.insert(upper.image.texels.end(), upper.image.width,
                                  glm::vec4(value, value, value, 1.0f));
    }
    const sh::ShRgb step = viewer::skySh(upper);
    EXPECT_NEAR(sh::irradiance(step, sh::Order::L2, glm::vec3(0, 1, 0)).x, kPi, 0.01f * kPi);
    EXPECT_NEAR(sh::irradiance(step, sh::Order::L2, glm::vec3(0, -1, 0)).x, 0.0f, 0.01f * kPi);
    EXPECT_NEAR(sh::irradiance(step, sh::Order::L2, glm::vec3(0, 0, 1)).x, 0.5f * kPi, 0.01f * kPi);
}

TEST(ViewerGi, FittedCascadesHoldTheSceneCentredOnIt) {
    baker::Scene s;
    s.bounds = {glm::vec3(-1.0f, 0.0f, 2.0f), glm::vec3(4.0f, 3.0f, 14.0f)}; // longest: 12 m
    runtime::DynamicGiSettings settings;
    settings.cascades = 2;
    settings.resolution = 32;
    settings.iterations = 7;
    const runtime::DynamicGiSettings fitted = viewer::fitCascades(settings, s);
    // The coarsest cascade (cell x 2) spans 12 m in resolution - 2 = 30 cells.
    EXPECT_FLOAT_EQ(fitted.cellSize * 2.0f * 30.0f, 12.0f);
    EXPECT_EQ(fitted.aheadFraction, 0.0f);
    EXPECT_EQ(fitted.iterations, 7u);
}

// Pixel rays row by row from the top, through the pixel centres: a 3 x 3 view's centre ray
// looks at the target, its first ray up and to the left.
TEST(ViewerSurface, ViewRaysAndTheReferenceImageKeepPixelOrder) {
    runtime::Camera camera;
    camera.eye = glm::vec3(1.0f, 2.0f, 3.0f);
    camera.target = glm::vec3(1.0f, 2.0f, 0.0f);
    const std::vector<baker::SurfaceRay> rays = viewer::viewRays(camera, 3, 3);
    ASSERT_EQ(rays.size(), 9u);
    EXPECT_LT(glm::length(rays[4].direction - glm::vec3(0, 0, -1)), 1e-6f);
    EXPECT_EQ(rays[0].origin, camera.eye);
    EXPECT_GT(rays[0].direction.y, 0.0f);
    EXPECT_LT(rays[0].direction.x, 0.0f);
    EXPECT_LT(rays[8].direction.y, 0.0f);
    EXPECT_GT(rays[8].direction.x, 0.0f);

    baker::SurfaceReference traced;
    traced.samples.resize(2);
    traced.samples[1].hit = true;
    traced.samples[1].irradiance = glm::vec3(4.0f, 5.0f, 6.0f);
    traced.samples[1].standardError = glm::vec3(0.5f);
    const runtime::SurfaceReferenceImage image = viewer::referenceImage(traced, 2, 1);
    EXPECT_EQ(image.width, 2u);
    EXPECT_EQ(image.height, 1u);
    ASSERT_EQ(image.hit.size(), 2u);
    EXPECT_EQ(image.hit[0], 0);
    EXPECT_EQ(image.hit[1], 1);
    EXPECT_EQ(image.irradiance[1], glm::vec3(4.0f, 5.0f, 6.0f));
    EXPECT_EQ(image.standardError[1], glm::vec3(0.5f));
}

} // namespace
} // namespace probekit
