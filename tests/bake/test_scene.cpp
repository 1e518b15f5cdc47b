// Scene loading: glTF (loadGltf) and lat-long environments (loadLatLongEnvironment).
//
// Every glTF here is written by the test into a temporary folder (JSON with data: URIs, JSON
// with an external .bin, hand-built .glb, hand-encoded PNGs), so each expected number is known
// exactly; the shared Cornell box and Uffizi map check the loaders on real exporter output, and
// the generated courtyard is checked for closed boxes, its sun, and one small bake's shading.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <numbers>
#include <string>
#include <tuple>
#include <vector>

#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bake_test_support.hpp"
#include "gltf_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"

using namespace probekit;
using namespace probekit::baker;
using nlohmann::json;
namespace fs = std::filesystem;
using namespace probekit::test;

namespace {

// Positions go through one double-precision matrix product and one rounding to float; the
// values here are below 20, so float rounding (and quaternions written with 7 digits) stays far
// below this.
constexpr float kPositionTolerance = 1e-5f;
// Values that are float products of JSON decimals (colour x intensity, cos of an angle).
constexpr float kFactorTolerance = 1e-6f;
// The Cornell numbers are the exporter's float32 values: 1e-5 m and 1e-4 W/(sr m^2) cover its
// rounding (17 x float(0.70588235) = 12 +- 1e-6) without hiding a wrong transform.
constexpr float kCornellTolerance = 1e-4f;
// sRGB 0.5 -> 0.214041 (exact EOTF). A 16-bit PNG holds 32768/65535 = 0.5 + 7.6e-6, which moves
// the linear value by 3.3e-6; float rounding adds 1e-7.
constexpr float kSrgbHalfTolerance = 1e-5f;
// Environment lookups invert the lat-long mapping with float acos/atan2, so a texel-centre
// direction lands within ~1e-5 texel of the centre; neighbours differ by at most a few x 10 in
// the Uffizi map, so the bilinear result matches the texel to this relative tolerance.
constexpr float kEnvironmentRelative = 1e-3f;

// Portable float map (OpenImageIO reads it): rows are stored bottom to top.
void writePfm(const fs::path& path, uint32_t width, uint32_t height, int channels,
              const std::vector<float>& stored_bottom_up) {
    std::string header = std::string(channels == 3 ? "PF" : "Pf") + "\n" + std::to_string(width) +
                         " " + std::to_string(height) + "\n-1.0\n";
    std::ofstream out(path, std::ios::binary);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    out.write(reinterpret_cast<const char*>(stored_bottom_up.data()),
              static_cast<std::streamsize>(stored_bottom_up.size() * sizeof(float)));
}

// Triangles as world-space corner triples, each rotated to start at its smallest corner
// (winding kept) and the list sorted: two loads that give the same surface compare equal.
std::vector<std::array<float, 9>> canonicalTriangles(const Scene& scene) {
    std::vector<std::array<float, 9>> out;
    auto less = [](glm::vec3 a, glm::vec3 b) {
        return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
    };
    for (const glm::uvec3& t : scene.triangles) {
        std::array<glm::vec3, 3> c = {scene.positions[t.x], scene.positions[t.y],
                                      scene.positions[t.z]};
        while (less(c[1], c[0]) || less(c[2], c[0])) {
            std::rotate(c.begin(), c.begin() + 1, c.end());
        }
        out.push_back({c[0].x, c[0].y, c[0].z, c[1].x, c[1].y, c[1].z, c[2].x, c[2].y, c[2].z});
    }
    std::sort(out.begin(), out.end());
    return out;
}

void expectNear(glm::vec3 actual, glm::vec3 expected, float tolerance, const std::string& what) {
    EXPECT_NEAR(actual.x, expected.x, tolerance) << what;
    EXPECT_NEAR(actual.y, expected.y, tolerance) << what;
    EXPECT_NEAR(actual.z, expected.z, tolerance) << what;
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Geometry

TEST(GltfGeometry, EveryIndexTypeStripFanAndNonIndexedGiveTheSameTriangles) {
    TempDir dir;
    const std::vector<uint32_t> list = {0, 1, 2, 0, 2, 3};
    std::vector<std::pair<std::string, GltfBuilder>> variants;
    {
        GltfBuilder b;
        const int pos = b.addPositions(kQuad);
        const int idx = b.addIndices(std::vector<uint8_t>(list.begin(), list.end()), 5121);
        b.setScene({b.addNode({{"mesh", b.addMesh(json::array({{{"attributes", {{"POSITION", pos}}},
                                                                {"indices", idx}}}))}})});
        variants.emplace_back("u8", b);
    }
    {
        GltfBuilder b;
        const int pos = b.addPositions(kQuad);
        const int idx = b.addIndices(std::vector<uint16_t>(list.begin(), list.end()), 5123);
        b.setScene({b.addNode({{"mesh", b.addMesh(json::array({{{"attributes", {{"POSITION", pos}}},
                                                                {"indices", idx}}}))}})});
        variants.emplace_back("u16", b);
    }
    {
        GltfBuilder b;
        const int pos = b.addPositions(kQuad);
        const int idx = b.addIndices(list, 5125);
        b.setScene({b.addNode({{"mesh", b.addMesh(json::array({{{"attributes", {{"POSITION", pos}}},
                                                                {"indices", idx}}}))}})});
        variants.emplace_back("u32", b);
    }
    {
        std::vector<glm::vec3> expanded;
        for (const uint32_t i : list) {
            expanded.push_back(kQuad[i]);
        }
        variants.emplace_back("non-indexed", quadDocument(4, nullptr, expanded));
    }
    {
        // Strip 1, 2, 0, 3 gives (1, 2, 0) and, odd, (2, 3, 0).
        GltfBuilder b;
        const int pos = b.addPositions(kQuad);
        const int idx = b.addIndices(std::vector<uint16_t>{1, 2, 0, 3}, 5123);
        b.setScene({b.addNode({{"mesh", b.addMesh(json::array({{{"attributes", {{"POSITION", pos}}},
                                                                {"indices", idx},
                                                                {"mode", 5}}}))}})});
        variants.emplace_back("strip", b);
    }
    // Fan 0, 1, 2, 3 gives (1, 2, 0) and (2, 3, 0).
    variants.emplace_back("fan", quadDocument(6, nullptr));

    std::vector<std::array<float, 9>> expected;
    for (const auto& [name, builder] : variants) {
        const Result<Scene> scene = loadGltf(builder.writeEmbedded(dir / (name + ".gltf")));
        ASSERT_TRUE(scene.ok()) << name << ": " << scene.error().message;
        EXPECT_EQ(scene.value().triangles.size(), 2u) << name;
        EXPECT_EQ(scene.value().warnings.size(), 0u) << name;
        const auto triangles = canonicalTriangles(scene.value());
        if (expected.empty()) {
            expected = triangles;
            const std::array<float, 9> first = {0, 0, 0, 1, 0, 0, 1, 1, 0};
            const std::array<float, 9> second = {0, 0, 0, 1, 1, 0, 0, 1, 0};
            EXPECT_EQ(expected, (std::vector<std::array<float, 9>>{first, second}));
        }
        EXPECT_EQ(triangles, expected) << name;
    }
}

TEST(GltfGeometry, EmbeddedExternalAndGlbContainersLoadTheSameScene) {
    TempDir dir;
    GltfBuilder builder;
    const int pos = builder.addPositions(kQuad);
    const int idx = builder.addIndices(std::vector<uint16_t>{0, 1, 2, 0, 2, 3}, 5123);
    builder.setScene({builder.addNode(
        {{"mesh", builder.addMesh(
                      json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}))}})});
    const std::vector<fs::path> files = {builder.writeEmbedded(dir / "embedded.gltf"),
                                         builder.writeExternal(dir / "external.gltf"),
                                         builder.writeGlb(dir / "binary.glb")};
    for (const fs::path& file : files) {
        const Result<Scene> scene = loadGltf(file);
        ASSERT_TRUE(scene.ok()) << scene.error().message;
        EXPECT_EQ(canonicalTriangles(scene.value()), canonicalTriangles(loadGltf(files[0]).value()))
            << file;
        // The hash is of the file's own bytes (not of the external .bin).
        EXPECT_EQ(scene.value().sourceHash, xxhash64(readBytes(file))) << file;
        EXPECT_EQ(scene.value().materials.size(), 1u) << "the glTF default material";
        EXPECT_EQ(scene.value().uvs.size(), scene.value().positions.size());
        EXPECT_EQ(scene.value().triangleNode, (std::vector<int32_t>{0, 0}));
    }
    // The GLB magic decides the container, not the extension.
    fs::copy_file(files[2], dir / "binary_named.gltf");
    EXPECT_TRUE(loadGltf(dir / "binary_named.gltf").ok());
}

TEST(GltfGeometry, TrsAndMatrixNodesComposeParentTimesLocal) {
    TempDir dir;
    GltfBuilder builder;
    const int mesh = builder.addMesh(
        json::array({{{"attributes",
                       {{"POSITION", builder.addPositions({{1, 0, 0}, {0, 1, 0}, {0, 0, 0}})}}}}}));
    const double s = std::sqrt(0.5);
    // nodes[0]: the mesh, matrix = translate (0, 0, 1) x scale (1, 3, 1), column-major.
    builder.addNode({{"name", "leaf"},
                     {"mesh", mesh},
                     {"matrix", {1, 0, 0, 0, 0, 3, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1}}});
    // nodes[1]: T (1, 2, 3) x R (+90 deg about Y: (x, y, z) -> (z, y, -x)) x S (2).
    builder.addNode({{"name", "middle"},
                     {"children", {0}},
                     {"translation", {1, 2, 3}},
                     {"rotation", {0, s, 0, s}},
                     {"scale", {2, 2, 2}}});
    // nodes[2]: not in the scene, so never loaded.
    builder.addNode({{"name", "orphan"}, {"mesh", mesh}});
    // nodes[3]: the root, T (10, 0, 0).
    builder.addNode({{"name", "root"}, {"children", {1}}, {"translation", {10, 0, 0}}});
    builder.setScene({3});
    const Result<Scene> result = loadGltf(builder.writeEmbedded(dir / "nodes.gltf"));
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();

    // By hand: leaf (1,0,0) -> (1,0,1) -> x2 (2,0,2) -> R (2,0,-2) -> +(1,2,3) (3,2,1) -> +10 x.
    //          leaf (0,1,0) -> (0,3,1) -> (0,6,2) -> (2,6,0) -> (3,8,3) -> (13,8,3).
    //          leaf (0,0,0) -> (0,0,1) -> (0,0,2) -> (2,0,0) -> (3,2,3) -> (13,2,3).
    ASSERT_EQ(scene.triangles.size(), 1u);
    const glm::uvec3 t = scene.triangles[0];
    expectNear(scene.positions[t.x], {13, 2, 1}, kPositionTolerance, "corner 0");
    expectNear(scene.positions[t.y], {13, 8, 3}, kPositionTolerance, "corner 1");
    expectNear(scene.positions[t.z], {13, 2, 3}, kPositionTolerance, "corner 2");

    // Scene::nodes holds the reachable nodes in glTF node order.
    ASSERT_EQ(scene.nodes.size(), 3u);
    EXPECT_EQ(scene.nodes[0].gltfIndex, 0);
    EXPECT_EQ(scene.nodes[1].gltfIndex, 1);
    EXPECT_EQ(scene.nodes[2].gltfIndex, 3);
    EXPECT_EQ(scene.nodes[0].name, "leaf");
    EXPECT_TRUE(scene.nodes[0].hasMesh);
    EXPECT_FALSE(scene.nodes[1].hasMesh);
    EXPECT_EQ(scene.triangleNode, (std::vector<int32_t>{0}));
    expectNear(scene.nodes[0].localBounds.min, {0, 0, 0}, 0.0f, "local min");
    expectNear(scene.nodes[0].localBounds.max, {1, 1, 0}, 0.0f, "local max");
    expectNear(scene.nodes[0].worldBounds.min, {13, 2, 1}, kPositionTolerance, "world min");
    expectNear(scene.nodes[0].worldBounds.max, {13, 8, 3}, kPositionTolerance, "world max");
    expectNear(scene.bounds.min, {13, 2, 1}, kPositionTolerance, "scene min");
    expectNear(scene.bounds.max, {13, 8, 3}, kPositionTolerance, "scene max");
    // The world matrix maps the leaf's origin where the triangle says.
    expectNear(glm::vec3(scene.nodes[0].world * glm::vec4(0, 0, 0, 1)), {13, 2, 3},
               kPositionTolerance, "leaf world matrix");
    expectNear(glm::vec3(scene.nodes[2].world[3]), {10, 0, 0}, 0.0f, "root world matrix");
}

TEST(GltfGeometry, PointsAndLinesAreSkippedWithAWarning) {
    TempDir dir;
    GltfBuilder builder;
    const int pos = builder.addPositions(kQuad);
    builder.doc()["meshes"].push_back(
        {{"name", "mixed"},
         {"primitives", json::array({{{"attributes", {{"POSITION", pos}}}, {"mode", 0}},
                                     {{"attributes", {{"POSITION", pos}}}, {"mode", 1}},
                                     {{"attributes", {{"POSITION", pos}}}, {"mode", 6}}})}});
    builder.setScene({builder.addNode({{"mesh", 0}})});
    const fs::path file = builder.writeEmbedded(dir / "points.gltf");
    const Result<Scene> scene = loadGltf(file);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    EXPECT_EQ(scene.value().triangles.size(), 2u);
    EXPECT_TRUE(anyWarningContains(scene.value(),
                                   {file.string(), "meshes[0] ('mixed').primitives[0]", "POINTS"}));
    EXPECT_TRUE(anyWarningContains(scene.value(), {file.string(), "primitives[1]", "LINES"}));
    EXPECT_EQ(scene.value().warnings.size(), 2u);
}

TEST(GltfGeometry, TrianglesWithNonFiniteVerticesAreSkippedWithOneWarning) {
    TempDir dir;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    // Vertices 4 and 5 are bad; triangles (0,1,2) and (0,2,3) are good, (0,1,4), (2,3,5) and
    // (4,5,0) are not.
    std::vector<glm::vec3> positions = kQuad;
    positions.push_back({nan, 0, 0});
    positions.push_back({0, inf, 0});
    GltfBuilder builder;
    const int pos = builder.addPositions(positions);
    const int idx = builder.addIndices(
        std::vector<uint16_t>{0, 1, 2, 0, 1, 4, 0, 2, 3, 2, 3, 5, 4, 5, 0}, 5123);
    builder.setScene({builder.addNode(
        {{"mesh", builder.addMesh(
                      json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}))}})});
    const fs::path file = builder.writeEmbedded(dir / "nan.gltf");
    const Result<Scene> result = loadGltf(file);
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();
    EXPECT_EQ(scene.triangles.size(), 2u);
    EXPECT_EQ(scene.positions.size(), 4u) << "bad vertices never reach the scene";
    for (const glm::vec3& p : scene.positions) {
        EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    }
    ASSERT_EQ(scene.warnings.size(), 1u);
    EXPECT_TRUE(anyWarningContains(scene, {file.string(), "primitives[0]", "3 triangles"}));
    expectNear(scene.bounds.max, {1, 1, 0}, 0.0f, "bounds ignore skipped triangles");
}

TEST(GltfGeometry, SparseInterleavedAndQuantizedAccessors) {
    TempDir dir;
    GltfBuilder builder;
    // Interleaved: position (3 floats) + uv (2 floats) per vertex, byteStride 20.
    std::vector<float> interleaved;
    const std::vector<glm::vec2> uvs = {{0, 0}, {1, 0}, {1, 1}};
    for (int i = 0; i < 3; ++i) {
        interleaved.insert(interleaved.end(), {kQuad[i].x, kQuad[i].y, kQuad[i].z});
        interleaved.insert(interleaved.end(), {uvs[i].x, uvs[i].y});
    }
    const int view = builder.addView(interleaved);
    builder.doc()["bufferViews"][view]["byteStride"] = 20;
    // Sparse: vertex 1 moved to (5, 0, 0).
    const int sparse_indices = builder.addView(std::vector<uint8_t>{1, 0, 0, 0});
    const int sparse_values = builder.addView(std::vector<float>{5, 0, 0});
    const int pos = builder.addAccessor(
        {{"bufferView", view},
         {"componentType", 5126},
         {"count", 3},
         {"type", "VEC3"},
         {"sparse",
          {{"count", 1},
           {"indices", {{"bufferView", sparse_indices}, {"componentType", 5121}}},
           {"values", {{"bufferView", sparse_values}}}}}});
    const int uv = builder.addAccessor({{"bufferView", view},
                                        {"byteOffset", 12},
                                        {"componentType", 5126},
                                        {"count", 3},
                                        {"type", "VEC2"}});
    // KHR_mesh_quantization: int16 positions (unnormalized) and normalized uint16 uvs.
    const int qpos = builder.addAccessor(
        {{"bufferView", builder.addView(std::vector<int16_t>{0, 0, -2, 4, 0, -2, 4, 8, -2, 0})},
         {"componentType", 5122},
         {"count", 3},
         {"type", "VEC3"}});
    const int quv = builder.addAccessor(
        {{"bufferView", builder.addView(std::vector<uint16_t>{0, 65535, 32768, 0, 65535, 13107})},
         {"componentType", 5123},
         {"normalized", true},
         {"count", 3},
         {"type", "VEC2"}});
    // No bufferView: zeros, then sparse values (vertex 2 at (0, 0, 9)).
    const int zpos = builder.addAccessor(
        {{"componentType", 5126},
         {"count", 3},
         {"type", "VEC3"},
         {"sparse",
          {{"count", 1},
           {"indices",
            {{"bufferView", builder.addView(std::vector<uint16_t>{2, 0})},
             {"componentType", 5123}}},
           {"values", {{"bufferView", builder.addView(std::vector<float>{0, 0, 9})}}}}}});
    builder.doc()["extensionsUsed"] = {"KHR_mesh_quantization"};
    builder.doc()["extensionsRequired"] = {"KHR_mesh_quantization"};
    builder.setScene({builder.addNode(
        {{"mesh",
          builder.addMesh(json::array({{{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}}},
                                       {{"attributes", {{"POSITION", qpos}, {"TEXCOORD_0", quv}}}},
                                       {{"attributes", {{"POSITION", zpos}}}}}))}})});
    const Result<Scene> result = loadGltf(builder.writeEmbedded(dir / "accessors.gltf"));
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();
    ASSERT_EQ(scene.triangles.size(), 3u);
    const glm::uvec3 a = scene.triangles[0];
    EXPECT_EQ(scene.positions[a.x], glm::vec3(0, 0, 0));
    EXPECT_EQ(scene.positions[a.y], glm::vec3(5, 0, 0));
    EXPECT_EQ(scene.positions[a.z], glm::vec3(1, 1, 0));
    EXPECT_EQ(scene.uvs[a.y], glm::vec2(1, 0));
    EXPECT_EQ(scene.uvs[a.z], glm::vec2(1, 1));
    const glm::uvec3 b = scene.triangles[1];
    EXPECT_EQ(scene.positions[b.x], glm::vec3(0, 0, -2));
    EXPECT_EQ(scene.positions[b.y], glm::vec3(4, 0, -2));
    EXPECT_EQ(scene.positions[b.z], glm::vec3(4, 8, -2));
    EXPECT_EQ(scene.uvs[b.x], glm::vec2(0, 1));
    EXPECT_NEAR(scene.uvs[b.y].x, 32768.0f / 65535.0f, 1e-7f);
    EXPECT_EQ(scene.uvs[b.z], glm::vec2(1, 0.2f));
    const glm::uvec3 c = scene.triangles[2];
    EXPECT_EQ(scene.positions[c.x], glm::vec3(0, 0, 0));
    EXPECT_EQ(scene.positions[c.z], glm::vec3(0, 0, 9));
    EXPECT_EQ(scene.uvs[c.z], glm::vec2(0, 0)) << "no TEXCOORD_0";
}

// Issue 31 class 6: normals with denormal components, and huge ones, keep their direction and
// come out unit length; a zero normal stays zero (the face normal is used).
TEST(GltfGeometry, DenormalAndHugeNormalsAreNormalised) {
    TempDir dir;
    GltfBuilder builder;
    const int pos = builder.addPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}});
    const float tiny = std::numeric_limits<float>::denorm_min(); // 1.4e-45
    const std::vector<float> normals = {1e-40f, 0, 0, 3e38f, 3e38f, 0, 0, tiny, tiny, 0, 0, 0};
    const int nrm = builder.addAccessor({{"bufferView", builder.addView(normals)},
                                         {"componentType", 5126},
                                         {"count", 4},
                                         {"type", "VEC3"}});
    const int idx = builder.addIndices(std::vector<uint16_t>{0, 1, 2, 1, 3, 2}, 5123);
    builder.setScene({builder.addNode(
        {{"mesh",
          builder.addMesh(json::array(
              {{{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}}}, {"indices", idx}}}))}})});
    const Result<Scene> result = loadGltf(builder.writeEmbedded(dir / "normals.gltf"));
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();
    ASSERT_EQ(scene.normals.size(), 4u);
    const float half = std::sqrt(0.5f);
    EXPECT_EQ(scene.normals[0], glm::vec3(1, 0, 0));
    EXPECT_NEAR(scene.normals[1].x, half, 1e-7f);
    EXPECT_NEAR(scene.normals[1].y, half, 1e-7f);
    EXPECT_EQ(scene.normals[1].z, 0.0f);
    EXPECT_NEAR(scene.normals[2].y, half, 1e-7f);
    EXPECT_NEAR(scene.normals[2].z, half, 1e-7f);
    EXPECT_EQ(scene.normals[3], glm::vec3(0.0f));
}

TEST(GltfGeometry, AFileWithoutGeometryIsValid) {
    TempDir dir;
    GltfBuilder builder;
    builder.setScene({builder.addNode({{"name", "empty"}})});
    const Result<Scene> scene = loadGltf(builder.writeEmbedded(dir / "empty.gltf"));
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    EXPECT_FALSE(scene.value().hasGeometry());
    EXPECT_EQ(scene.value().materials.size(), 1u);
    EXPECT_EQ(scene.value().bounds.min, glm::vec3(0));
    EXPECT_EQ(scene.value().bounds.max, glm::vec3(0));
    EXPECT_EQ(scene.value().nodes.size(), 1u);
}

TEST(GltfGeometry, SceneIndexSelectsTheScene) {
    TempDir dir;
    GltfBuilder builder = quadDocument(4, nullptr);
    builder.doc()["scenes"].push_back({{"nodes", json::array()}});
    builder.doc()["scene"] = 1;
    const fs::path file = builder.writeEmbedded(dir / "scenes.gltf");
    const Result<Scene> by_default = loadGltf(file);
    ASSERT_TRUE(by_default.ok()) << by_default.error().message;
    EXPECT_FALSE(by_default.value().hasGeometry()) << "the default scene (1) is empty";
    const Result<Scene> first = loadGltf(file, LoadOptions{0});
    ASSERT_TRUE(first.ok()) << first.error().message;
    EXPECT_EQ(first.value().triangles.size(), 1u);
}

// ---------------------------------------------------------------------------------------------
// Materials

TEST(GltfMaterials, EmissionIsFactorTimesStrengthAndDefaultMaterialIsAppended) {
    TempDir dir;
    GltfBuilder builder;
    const int pos = builder.addPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    builder.addMaterial(
        {{"name", "lamp"},
         {"emissiveFactor", {1.0, 0.5, 0.25}},
         {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 4.0}}}}},
         {"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.25, 1.0, 0.1}}}}});
    builder.addMaterial({{"name", "plain"}, {"emissiveFactor", {0.5, 0.5, 0.5}}});
    builder.doc()["extensionsUsed"] = {"KHR_materials_emissive_strength"};
    builder.doc()["extensionsRequired"] = {"KHR_materials_emissive_strength"};
    builder.setScene({builder.addNode(
        {{"mesh", builder.addMesh(
                      json::array({{{"attributes", {{"POSITION", pos}}}, {"material", 1}},
                                   {{"attributes", {{"POSITION", pos}}}},
                                   {{"attributes", {{"POSITION", pos}}}, {"material", 0}}}))}})});
    const Result<Scene> result = loadGltf(builder.writeEmbedded(dir / "materials.gltf"));
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();
    ASSERT_EQ(scene.materials.size(), 3u);
    EXPECT_EQ(scene.materials[0].name, "lamp");
    EXPECT_EQ(scene.materials[0].emission, glm::vec3(4.0f, 2.0f, 1.0f));
    EXPECT_EQ(scene.materials[0].baseColor, glm::vec3(0.5f, 0.25f, 1.0f)) << "alpha ignored";
    EXPECT_EQ(scene.materials[1].emission, glm::vec3(0.5f)) << "strength defaults to 1";
    EXPECT_EQ(scene.materials[2].baseColor, glm::vec3(1.0f)) << "glTF default material";
    EXPECT_FALSE(scene.materials[2].isEmissive());
    EXPECT_EQ(scene.triangleMaterial, (std::vector<uint32_t>{1, 2, 0}));
    EXPECT_EQ(scene.emissionAt(2, glm::vec2(0.3f)), glm::vec3(4.0f, 2.0f, 1.0f));
}

TEST(GltfMaterials, TexturesAreSrgbDecodedToLinear) {
    TempDir dir;
    // Base colour: 8-bit 2 x 2, texel (0, 0) = sRGB (128, 0, 255), others grey 64.
    std::vector<uint16_t> base_rgba(16, 64);
    for (int t = 0; t < 4; ++t) {
        base_rgba[t * 4 + 3] = 255;
    }
    base_rgba[0] = 128;
    base_rgba[1] = 0;
    base_rgba[2] = 255;
    // Emissive: 16-bit 1 x 1, sRGB (32768, 65535, 0) / 65535, i.e. (0.5, 1, 0); an external file.
    const std::vector<uint8_t> emissive_png = encodePng(1, 1, 16, {32768, 65535, 0, 65535});
    writeBytes(dir / "glow.png", emissive_png.data(), emissive_png.size());

    GltfBuilder builder;
    const int pos = builder.addPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    // Every corner at the centre of texel (0, 0), so any barycentric samples it exactly.
    const int uv = builder.addUvs({{0.25f, 0.25f}, {0.25f, 0.25f}, {0.25f, 0.25f}});
    builder.doc()["images"] = {
        {{"uri", "data:image/png;base64," + base64(encodePng(2, 2, 8, base_rgba))}},
        {{"uri", "glow.png"}}};
    builder.doc()["textures"] = {{{"source", 0}}, {{"source", 1}}};
    builder.addMaterial(
        {{"pbrMetallicRoughness",
          {{"baseColorFactor", {0.5, 1, 1, 1}}, {"baseColorTexture", {{"index", 0}}}}},
         {"emissiveFactor", {1, 1, 1}},
         {"emissiveTexture", {{"index", 1}}}});
    builder.setScene({builder.addNode(
        {{"mesh",
          builder.addMesh(json::array(
              {{{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}}, {"material", 0}}}))}})});
    const Result<Scene> result = loadGltf(builder.writeExternal(dir / "textured.gltf"));
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();
    ASSERT_EQ(scene.images.size(), 2u);
    const Material& material = scene.materials[0];
    ASSERT_GE(material.baseColorTexture, 0);
    ASSERT_GE(material.emissiveTexture, 0);

    auto srgb = [](double c) {
        return static_cast<float>(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
    };
    const Image& base = scene.images[size_t(material.baseColorTexture)];
    ASSERT_EQ(base.width, 2u);
    ASSERT_EQ(base.height, 2u);
    EXPECT_FLOAT_EQ(base.texels[0].x, srgb(128.0 / 255.0));
    EXPECT_NEAR(base.texels[0].x, 0.2158605f, 1e-6f);
    EXPECT_EQ(base.texels[0].y, 0.0f);
    EXPECT_EQ(base.texels[0].z, 1.0f);
    EXPECT_FLOAT_EQ(base.texels[3].x, srgb(64.0 / 255.0));
    EXPECT_EQ(base.texels[3].w, 1.0f);
    const Image& glow = scene.images[size_t(material.emissiveTexture)];
    EXPECT_NEAR(glow.texels[0].x, 0.21404114f, kSrgbHalfTolerance) << "sRGB 0.5";
    EXPECT_EQ(glow.texels[0].y, 1.0f);
    EXPECT_EQ(glow.texels[0].z, 0.0f);

    const glm::vec3 albedo = scene.albedoAt(0, glm::vec2(0.2f, 0.3f));
    EXPECT_NEAR(albedo.x, 0.5f * srgb(128.0 / 255.0), kFactorTolerance);
    EXPECT_NEAR(albedo.z, 1.0f, kFactorTolerance);
    EXPECT_NEAR(scene.emissionAt(0, glm::vec2(0.2f, 0.3f)).x, glow.texels[0].x, kFactorTolerance);
}

// ---------------------------------------------------------------------------------------------
// Lights

TEST(GltfLights, PunctualLightsTakeTheirNodesFrame) {
    TempDir dir;
    GltfBuilder builder;
    const double s = std::sqrt(0.5);
    builder.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
    builder.doc()["extensionsRequired"] = {"KHR_lights_punctual"};
    builder.doc()["extensions"]["KHR_lights_punctual"]["lights"] = {
        {{"name", "bulb"},
         {"type", "point"},
         {"color", {1, 0.5, 0.25}},
         {"intensity", 8},
         {"range", 5}},
        {{"name", "cone"},
         {"type", "spot"},
         {"intensity", 2},
         {"spot", {{"innerConeAngle", 0.3}, {"outerConeAngle", 0.6}}}},
        {{"name", "sun"}, {"type", "directional"}, {"intensity", 3}},
        {{"name", "default cone"}, {"type", "spot"}, {"spot", json::object()}}};
    auto light = [](int index) { return json{{"KHR_lights_punctual", {{"light", index}}}}; };
    builder.addNode({{"translation", {1, 2, 3}}, {"extensions", light(0)}});
    // -90 deg about X turns -Z into -Y; the scale of 2 must not change the direction's length.
    builder.addNode({{"translation", {0, 4, 0}},
                     {"rotation", {-s, 0, 0, s}},
                     {"scale", {2, 2, 2}},
                     {"extensions", light(1)}});
    // +90 deg about Y: (x, y, z) -> (z, y, -x), so -Z -> -X; under a parent translated by 7.
    builder.addNode({{"rotation", {0, s, 0, s}}, {"extensions", light(2)}});
    builder.addNode({{"translation", {7, 0, 0}}, {"children", {2}}});
    builder.addNode({{"extensions", light(3)}});
    builder.setScene({0, 1, 3, 4});
    const Result<Scene> result = loadGltf(builder.writeEmbedded(dir / "lights.gltf"));
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();
    ASSERT_EQ(scene.lights.size(), 4u);

    const PunctualLight& point = scene.lights[0];
    EXPECT_EQ(point.type, LightType::Point);
    EXPECT_EQ(point.name, "bulb");
    EXPECT_EQ(point.position, glm::vec3(1, 2, 3));
    EXPECT_EQ(point.intensity, glm::vec3(8, 4, 2));
    EXPECT_EQ(point.range, 5.0f);

    const PunctualLight& spot = scene.lights[1];
    EXPECT_EQ(spot.type, LightType::Spot);
    expectNear(spot.position, {0, 4, 0}, kPositionTolerance, "spot position");
    expectNear(spot.direction, {0, -1, 0}, kPositionTolerance, "spot direction");
    EXPECT_EQ(spot.intensity, glm::vec3(2));
    EXPECT_EQ(spot.range, 0.0f) << "infinite";
    EXPECT_NEAR(spot.innerConeCos, std::cos(0.3), kFactorTolerance);
    EXPECT_NEAR(spot.outerConeCos, std::cos(0.6), kFactorTolerance);

    const PunctualLight& sun = scene.lights[2];
    EXPECT_EQ(sun.type, LightType::Directional);
    expectNear(sun.direction, {-1, 0, 0}, kPositionTolerance, "sun direction");
    expectNear(sun.position, {7, 0, 0}, kPositionTolerance, "sun position");
    EXPECT_EQ(sun.intensity, glm::vec3(3)) << "white by default";

    const PunctualLight& default_cone = scene.lights[3];
    EXPECT_EQ(default_cone.innerConeCos, 1.0f);
    EXPECT_NEAR(default_cone.outerConeCos, std::cos(std::numbers::pi / 4), kFactorTolerance);
    expectNear(default_cone.direction, {0, 0, -1}, 0.0f, "untransformed -Z");
    EXPECT_EQ(default_cone.intensity, glm::vec3(1)) << "intensity 1 by default";
}

// ---------------------------------------------------------------------------------------------
// Errors

TEST(GltfErrors, UnsupportedRequiredExtensionIsNamed) {
    TempDir dir;
    for (const char* extension : {"KHR_texture_transform", "KHR_draco_mesh_compression"}) {
        GltfBuilder builder = quadDocument(4, nullptr);
        builder.doc()["extensionsUsed"] = {"KHR_lights_punctual", extension};
        builder.doc()["extensionsRequired"] = {"KHR_lights_punctual", extension};
        const fs::path file = builder.writeEmbedded(dir / "required.gltf");
        const Result<Scene> scene = loadGltf(file);
        ASSERT_FALSE(scene.ok()) << extension;
        EXPECT_TRUE(contains(scene.error().message, extension)) << scene.error().message;
        EXPECT_TRUE(contains(scene.error().message, file.string())) << scene.error().message;
    }
}

TEST(GltfErrors, MissingFile) {
    TempDir dir;
    const fs::path file = dir / "does_not_exist.gltf";
    const Result<Scene> scene = loadGltf(file);
    ASSERT_FALSE(scene.ok());
    EXPECT_EQ(scene.error().code, ErrorCode::Io);
    EXPECT_TRUE(contains(scene.error().message, file.string())) << scene.error().message;
}

TEST(GltfErrors, MissingExternalBufferOrTexture) {
    TempDir dir;
    GltfBuilder builder = quadDocument(4, nullptr);
    const fs::path file = builder.writeExternal(dir / "external.gltf");
    fs::remove(fs::path(file).replace_extension(".bin"));
    const Result<Scene> no_buffer = loadGltf(file);
    ASSERT_FALSE(no_buffer.ok());
    EXPECT_TRUE(contains(no_buffer.error().message, file.string())) << no_buffer.error().message;
    EXPECT_TRUE(contains(no_buffer.error().message, "external.bin")) << no_buffer.error().message;

    builder.doc()["images"] = {{{"uri", "nowhere.png"}}};
    builder.doc()["textures"] = {{{"source", 0}}};
    builder.addMaterial({{"emissiveFactor", {1, 1, 1}}, {"emissiveTexture", {{"index", 0}}}});
    const fs::path textured = builder.writeEmbedded(dir / "textured.gltf");
    const Result<Scene> no_texture = loadGltf(textured);
    ASSERT_FALSE(no_texture.ok());
    EXPECT_TRUE(contains(no_texture.error().message, textured.string()))
        << no_texture.error().message;
    EXPECT_TRUE(contains(no_texture.error().message, "nowhere.png")) << no_texture.error().message;
}

// Issue 31 class 5: a buffer file larger than its byteLength was read whole (charged to the
// memory limit, or refused by it) before tinygltf refused the size. Its size is now checked
// from the file system first; the 64 MiB file here is sparse and never read.
TEST(GltfErrors, ABufferFileOfTheWrongSizeIsRefusedBeforeItIsRead) {
    TempDir dir;
    const GltfBuilder builder = quadDocument(4, nullptr);
    const fs::path file = builder.writeExternal(dir / "external.gltf");
    const fs::path bin = fs::path(file).replace_extension(".bin");
    const uint64_t length = fs::file_size(bin);
    fs::resize_file(bin, uint64_t(64) << 20);
    LoadOptions options;
    options.maxMemoryBytes = uint64_t(16) << 20;
    const Result<Scene> big = loadGltf(file, options);
    ASSERT_FALSE(big.ok());
    EXPECT_EQ(big.error().code, ErrorCode::InconsistentSize);
    std::string expected = file.string();
    expected += ": buffers[0].uri 'external.bin' holds 67108864 bytes, but ";
    expected += "buffers[0].byteLength is ";
    expected += std::to_string(length);
    EXPECT_TRUE(big.error().message.starts_with(expected)) << big.error().message;

    fs::resize_file(bin, length - 1);
    const Result<Scene> short_file = loadGltf(file, options);
    ASSERT_FALSE(short_file.ok());
    std::string holds = "holds ";
    holds += std::to_string(length - 1);
    EXPECT_TRUE(contains(short_file.error().message, holds)) << short_file.error().message;
}

TEST(GltfErrors, MalformedJsonAndBrokenContainers) {
    TempDir dir;
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"truncated.gltf", R"({"asset": {"version": "2.0"}, "nodes": [)"},
        {"not_json.gltf", "this is not JSON at all"},
        {"empty.gltf", ""},
        {"no_asset.gltf", R"({"nodes": []})"},
        {"bad_magic.glb", "glTX not really a binary glTF"},
        {"truncated.glb", std::string("glTF\x02\0\0\0\x40\0\0\0", 12)}};
    for (const auto& [name, text] : cases) {
        const fs::path file = dir / name;
        writeText(file, text);
        const Result<Scene> scene = loadGltf(file);
        ASSERT_FALSE(scene.ok()) << name;
        EXPECT_TRUE(contains(scene.error().message, file.string())) << scene.error().message;
        EXPECT_GT(scene.error().message.size(), file.string().size() + 4)
            << "carries tinygltf's reason: " << scene.error().message;
    }
}

TEST(GltfErrors, BadSceneIndexIsNamed) {
    TempDir dir;
    const fs::path file = quadDocument(4, nullptr).writeEmbedded(dir / "scene.gltf");
    for (const int index : {1, -1, 42}) {
        const Result<Scene> scene = loadGltf(file, LoadOptions{index});
        ASSERT_FALSE(scene.ok()) << index;
        EXPECT_EQ(scene.error().code, ErrorCode::OutOfRange);
        EXPECT_TRUE(contains(scene.error().message, "scene index " + std::to_string(index)))
            << scene.error().message;
        EXPECT_TRUE(contains(scene.error().message, file.string())) << scene.error().message;
    }
}

TEST(GltfErrors, OutOfRangeAccessorsAreNamed) {
    TempDir dir;
    struct Case {
        std::string name;
        std::function<void(json&)> corrupt;
        std::string expected; // part of the message
    };
    // quadDocument(4, indices): accessors[0] POSITION (4 vertices), accessors[1] u16 indices.
    const std::vector<Case> cases = {
        {"count", [](json& d) { d["accessors"][0]["count"] = 100; }, "accessors[0]"},
        {"offset", [](json& d) { d["accessors"][0]["byteOffset"] = 40; }, "accessors[0]"},
        {"huge count", [](json& d) { d["accessors"][1]["count"] = 4294967295u; }, "accessors[1]"},
        {"view", [](json& d) { d["bufferViews"][0]["byteLength"] = 4096; }, "bufferViews[0]"},
        {"stride", [](json& d) { d["bufferViews"][0]["byteStride"] = 8; }, "byteStride"},
        {"missing accessor",
         [](json& d) { d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 99; },
         "accessors[99]"},
        {"no data", [](json& d) { d["accessors"][0].erase("bufferView"); }, "accessors[0]"},
        {"wrong type", [](json& d) { d["accessors"][0]["type"] = "VEC2"; }, "accessors[0]"},
        {"float indices", [](json& d) { d["accessors"][1]["componentType"] = 5126; },
         "accessors[1]"},
        {"material", [](json& d) { d["meshes"][0]["primitives"][0]["material"] = 3; },
         "material 3"},
        {"node", [](json& d) { d["scenes"][0]["nodes"] = {7}; }, "node 7"},
        {"cycle", [](json& d) { d["nodes"][0]["children"] = {0}; }, "node 0"},
    };
    for (const Case& c : cases) {
        GltfBuilder builder = quadDocument(
            4, {{"bufferView", 1}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}});
        builder.addView(std::vector<uint16_t>{0, 1, 2, 0, 2, 3});
        c.corrupt(builder.doc());
        const fs::path file = builder.writeEmbedded(dir / "broken.gltf");
        const Result<Scene> scene = loadGltf(file);
        ASSERT_FALSE(scene.ok()) << c.name;
        EXPECT_TRUE(contains(scene.error().message, file.string())) << scene.error().message;
        EXPECT_TRUE(contains(scene.error().message, c.expected))
            << c.name << ": " << scene.error().message;
    }

    // An index that points past the vertices names the index accessor and the value.
    GltfBuilder builder = quadDocument(
        4, {{"bufferView", 1}, {"componentType", 5123}, {"count", 3}, {"type", "SCALAR"}});
    builder.addView(std::vector<uint16_t>{0, 1, 7});
    const Result<Scene> scene = loadGltf(builder.writeEmbedded(dir / "index.gltf"));
    ASSERT_FALSE(scene.ok());
    EXPECT_TRUE(contains(scene.error().message, "accessors[1]")) << scene.error().message;
    EXPECT_TRUE(contains(scene.error().message, "index 7")) << scene.error().message;
}

// ---------------------------------------------------------------------------------------------
// The shared Cornell box (../shared/scenes/cornell-box, see its SOURCE.txt)

TEST(SceneCornellBox, LoadsWithItsNodeRotationAndEmissiveLight) {
    const fs::path file =
        fs::path(PROBEKIT_SHARED_DIR) / "scenes/cornell-box/cornell_from_obj.gltf";
    const Result<Scene> result = loadGltf(file);
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Scene& scene = result.value();

    // 5 walls/floor/ceiling x 2 + 2 boxes x 12 + the light quad x 2.
    EXPECT_EQ(scene.triangles.size(), 36u);
    EXPECT_EQ(scene.materials.size(), 8u) << "every primitive has a material";
    EXPECT_TRUE(scene.warnings.empty()) << scene.warnings.front();
    ASSERT_EQ(scene.nodes.size(), 1u);

    // The node's +90 deg rotation about X maps the file's (x, y, z) to (x, -z, y): the OBJ
    // frame, +Y up, floor at y = 0, ceiling at 1.99, open side at z = +0.99.
    expectNear(scene.bounds.min, {-1.02f, 0.0f, -1.04f}, kCornellTolerance, "min");
    expectNear(scene.bounds.max, {1.0f, 1.99f, 0.99f}, kCornellTolerance, "max");
    expectNear(scene.nodes[0].localBounds.min, {-1.02f, -1.04f, -1.99f}, kCornellTolerance,
               "local min");

    int emissive = -1;
    for (size_t m = 0; m < scene.materials.size(); ++m) {
        if (scene.materials[m].isEmissive()) {
            EXPECT_EQ(emissive, -1) << "a second emissive material: " << scene.materials[m].name;
            emissive = static_cast<int>(m);
        }
    }
    ASSERT_GE(emissive, 0);
    const Material& light = scene.materials[size_t(emissive)];
    EXPECT_EQ(light.name, "light");
    expectNear(light.emission, {17, 12, 4}, kCornellTolerance, "emissiveFactor x strength");
    expectNear(light.baseColor, glm::vec3(0.78f), kCornellTolerance, "light albedo");

    size_t light_triangles = 0;
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
        if (scene.triangleMaterial[t] != uint32_t(emissive)) {
            continue;
        }
        ++light_triangles;
        expectNear(scene.albedoAt(uint32_t(t), glm::vec2(0.25f)), glm::vec3(0.78f),
                   kCornellTolerance, "albedoAt");
        for (int k = 0; k < 3; ++k) {
            // 1 cm below the ceiling.
            EXPECT_NEAR(scene.positions[scene.triangles[t][k]].y, 1.98f, kCornellTolerance);
        }
    }
    EXPECT_EQ(light_triangles, 2u);
}

// ---------------------------------------------------------------------------------------------
// The generated courtyard (generators.hpp)

namespace {
// The signed volume of the boxes, sum of det(p0, p1, p2) / 6 over the triangles in double, is
// exact to the float rounding of the corners (~5e-7 m on coordinates up to 8.2 m), ~1e-4 m^3
// over the 124 m^3; a missing face or a flipped box moves it by metres cubed.
constexpr double kVolumeTolerance = 1e-3;
// The sun's direction is a quaternion written as float JSON numbers and turned back into a
// vector: float rounding of a unit quaternion, a few 1e-7.
constexpr float kSunDirectionTolerance = 1e-5f;
// Bake figures at 1024 directions per probe. The open probe's irradiance from +Y is the sun's
// (3 W/m^2 x sin 50 deg = 2.30 in red) plus most of the sky's (pi x 0.3 = 0.94) plus a little
// bounce light: 3.08..3.12 in red over seeds 1..8. The covered one sees neither the sun nor the
// sky above it, only the roof's underside and the courtyard through the arcade: 0.48..0.58,
// the noisy one (~7% standard deviation). Their ratio is ~5.5; a bound of 2 would need the
// covered value to be off by 1 W/m^2, over 20 standard deviations, yet catches a roof that
// lets the sun or sky through.
constexpr float kOpenOverCoveredRatio = 2.0f;
constexpr uint32_t kCourtyardSamples = 1024;

// The courtyard written into this test's own folder: test::generatedScene shares one folder per
// scene name, which two test processes (ctest -j) would empty under each other.
Scene courtyardScene(const TempDir& dir) {
    const fs::path file = dir / "courtyard.gltf";
    EXPECT_TRUE(writeGeneratedScene("courtyard", file).ok());
    return test::loadOrFail(file);
}
} // namespace

TEST(SceneCourtyard, LoadsAsClosedOutwardBoxesUnderOneSun) {
    TempDir dir;
    const Scene scene = courtyardScene(dir);
    // Paving, four walls, roof, eight columns, plinth and pedestal: 16 boxes x 12 triangles.
    EXPECT_EQ(scene.triangles.size(), 192u);
    EXPECT_TRUE(scene.warnings.empty()) << scene.warnings.front();
    expectNear(scene.bounds.min, {-8.2f, -0.1f, -8.2f}, kPositionTolerance, "min");
    expectNear(scene.bounds.max, {8.2f, 6.0f, 8.2f}, kPositionTolerance, "max");

    // Closed and facing out: every box adds its volume (outward winding), and the sum is the
    // boxes' known total. Paving 16.4 x 0.1 x 16.4, walls 2 x 16.4 x 6 x 0.2 + 2 x 0.2 x 6 x 16,
    // roof 16 x 0.25 x 2.5, columns 8 x 0.4 x 0.4 x 3.5, plinth 2.8 x 0.5 x 2.8, pedestal
    // 0.6 x 0.7 x 0.6.
    double volume = 0.0;
    for (const glm::uvec3& t : scene.triangles) {
        const glm::dvec3 a = scene.positions[t.x], b = scene.positions[t.y],
                         c = scene.positions[t.z];
        volume += glm::dot(a, glm::cross(b, c)) / 6.0;
    }
    EXPECT_NEAR(volume, 26.896 + 39.36 + 38.4 + 10.0 + 4.48 + 3.92 + 0.252, kVolumeTolerance);

    // Five materials, none emissive, two walls coloured so the bounce light is.
    ASSERT_EQ(scene.materials.size(), 5u) << "every primitive has a material";
    for (const Material& m : scene.materials) {
        EXPECT_FALSE(m.isEmissive()) << m.name;
    }
    EXPECT_EQ(scene.materials[2].name, "terracotta");
    expectNear(scene.materials[2].baseColor, {0.66f, 0.3f, 0.18f}, kFactorTolerance, "terracotta");
    EXPECT_EQ(scene.materials[3].name, "sage");

    // The sun: 50 deg up, shining from +z turned 30 deg towards +x.
    ASSERT_EQ(scene.lights.size(), 1u);
    const PunctualLight& sun = scene.lights[0];
    EXPECT_EQ(sun.type, LightType::Directional);
    const double elevation = 50.0 * std::numbers::pi / 180.0;
    const double azimuth = 30.0 * std::numbers::pi / 180.0;
    const glm::vec3 to_sun(std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                           std::cos(azimuth) * std::cos(elevation));
    expectNear(sun.direction, -to_sun, kSunDirectionTolerance, "sun direction");
    expectNear(sun.intensity, {3.0f, 2.85f, 2.55f}, kFactorTolerance, "colour x intensity");
}

TEST(SceneCourtyard, OpenMiddleOutshinesTheColonnadeAndColumnsAreInside) {
    TempDir dir;
    Scene scene = courtyardScene(dir);
    // The sky of examples/courtyard-bake.json.
    EnvironmentConfig sky;
    sky.type = EnvironmentConfig::Type::Constant;
    sky.radiance = glm::vec3(0.3f, 0.4f, 0.6f);
    Result<Environment> environment = makeEnvironment(sky);
    ASSERT_TRUE(environment.ok()) << environment.error().message;
    scene.environment = std::move(environment).value();

    const glm::vec3 open(3.0f, 2.0f, 4.0f);
    // Under the roof near the back wall: the sun, 50 deg up, would have to pass the roof's edge
    // 2.5 m away and 1 m higher, so the roof shades the probe.
    const glm::vec3 covered(-2.0f, 2.5f, -7.5f);
    const glm::vec3 in_column(1.0f, 1.5f, -5.7f); // the column at x = 1 spans z -5.9..-5.5
    BakeConfig config = test::probesAt({open, covered, in_column}, 0.05f);
    config.path.samples = kCourtyardSamples;
    config.dilate = false; // a lone invalid probe has no neighbour to fill it from
    const Result<BakeResult> result = bake(scene, config);
    ASSERT_TRUE(result.ok()) << result.error().message;
    const std::vector<Volume>& volumes = result.value().file.volumes;
    ASSERT_EQ(volumes.size(), 3u);

    const glm::vec3 up(0.0f, 1.0f, 0.0f);
    const glm::vec3 open_up = sh::irradiance(volumes[0].probe(0), sh::Order::L2, up);
    const glm::vec3 covered_up = sh::irradiance(volumes[1].probe(0), sh::Order::L2, up);
    std::printf("[courtyard] E(+Y) open (%.3f, %.3f, %.3f), covered (%.3f, %.3f, %.3f)\n",
                open_up.x, open_up.y, open_up.z, covered_up.x, covered_up.y, covered_up.z);
    for (int c = 0; c < 3; ++c) {
        EXPECT_GT(covered_up[c], 0.0f) << "channel " << c << ": bounce light reaches the walkway";
        EXPECT_GT(open_up[c], kOpenOverCoveredRatio * covered_up[c]) << "channel " << c;
    }
    EXPECT_EQ(volumes[0].validity, std::vector<uint8_t>{1});
    EXPECT_EQ(volumes[1].validity, std::vector<uint8_t>{1});
    EXPECT_EQ(volumes[2].validity, std::vector<uint8_t>{0}) << "inside a column";
    EXPECT_EQ(result.value().stats.invalidProbes, 1u);
}

// ---------------------------------------------------------------------------------------------
// Environments

namespace {
// The world direction of the centre of texel (column x, row y) of a width x height lat-long map,
// following the mapping documented on Environment.
glm::vec3 texelDirection(uint32_t x, uint32_t y, uint32_t width, uint32_t height) {
    const double u = (x + 0.5) / width;
    const double v = (y + 0.5) / height;
    const double phi = 2.0 * std::numbers::pi * u;
    const double theta = std::numbers::pi * v;
    return glm::vec3(std::sin(theta) * std::sin(phi), std::cos(theta),
                     -std::sin(theta) * std::cos(phi));
}

void expectRelative(glm::vec3 actual, glm::vec3 expected, float relative, const std::string& what) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(actual[c], expected[c], relative * std::max(std::abs(expected[c]), 1e-3f))
            << what << " channel " << c;
    }
}
} // namespace

TEST(EnvironmentLatLong, UffiziCentreLooksAlongPlusZAndRotatesCounterClockwise) {
    const fs::path file = fs::path(PROBEKIT_SHARED_DIR) / "env/uffizi.hdr";
    const Result<Environment> result = loadLatLongEnvironment(file, 1.0f, 0.0f);
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Environment& env = result.value();
    ASSERT_EQ(env.type, Environment::Type::LatLong);
    ASSERT_EQ(env.image.width, 256u);
    ASSERT_EQ(env.image.height, 128u);
    EXPECT_EQ(env.source, file.string());
    EXPECT_FALSE(env.isBlack());

    auto texel = [&](uint32_t x, uint32_t y) { return glm::vec3(env.image.texels[y * 256 + x]); };
    // Texel (128, 64) sits just right of and below the image centre, i.e. next to +Z.
    const glm::vec3 centre_dir = texelDirection(128, 64, 256, 128);
    EXPECT_GT(centre_dir.z, 0.999f);
    expectRelative(env.radiance(centre_dir), texel(128, 64), kEnvironmentRelative, "centre");
    // +Z itself is the corner of four texels: bilinear gives their mean.
    const glm::vec3 mean =
        0.25f * (texel(127, 63) + texel(128, 63) + texel(127, 64) + texel(128, 64));
    expectRelative(env.radiance({0, 0, 1}), mean, kEnvironmentRelative, "+Z");
    // Top row is +Y.
    expectRelative(env.radiance(texelDirection(10, 0, 256, 128)), texel(10, 0),
                   kEnvironmentRelative, "top row");

    // Rotating the map by +90 deg about +Y (counter-clockwise from above) carries what was seen
    // along d to R_y(90) d = (d.z, d.y, -d.x): +Z goes to +X.
    const Result<Environment> rotated = loadLatLongEnvironment(file, 2.0f, 90.0f);
    ASSERT_TRUE(rotated.ok()) << rotated.error().message;
    const glm::vec3 moved(centre_dir.z, centre_dir.y, -centre_dir.x);
    EXPECT_GT(moved.x, 0.999f);
    expectRelative(rotated.value().radiance(moved), 2.0f * texel(128, 64), kEnvironmentRelative,
                   "rotated centre");
}

TEST(EnvironmentLatLong, GreyMapsAndPfmOrientation) {
    TempDir dir;
    // 4 x 2 grey PFM; stored bottom row first, so the top row is the second half.
    const fs::path file = dir / "grey.pfm";
    writePfm(file, 4, 2, 1, {1, 2, 3, 4, 10, 20, 30, 40});
    const Result<Environment> result = loadLatLongEnvironment(file, 1.0f, 0.0f);
    ASSERT_TRUE(result.ok()) << result.error().message;
    const Image& image = result.value().image;
    ASSERT_EQ(image.width, 4u);
    ASSERT_EQ(image.height, 2u);
    EXPECT_EQ(image.texels[0], glm::vec4(10, 10, 10, 1)) << "row 0 is the top";
    EXPECT_EQ(image.texels[7], glm::vec4(4, 4, 4, 1));
}

// Issue 31 class 6: an 8-bit (or 16-bit) sRGB PNG stores encoded values, not radiance; read as
// they stand, sRGB 188 gave 0.737 instead of 0.5029 (1.47x) and mid-grey 128 gave 0.502 instead
// of 0.2159 (2.3x). The colour channels are decoded, alpha is not used.
TEST(EnvironmentLatLong, SrgbPngMapsAreDecodedToLinear) {
    TempDir dir;
    std::vector<uint16_t> rgba(4 * 2 * 4, 255);
    rgba[0] = 188;
    rgba[1] = 128;
    rgba[2] = 0;
    rgba[4] = 10; // below the sRGB curve's linear segment's end (0.04045 x 255 = 10.3)
    const fs::path file8 = dir / "sky8.png";
    const std::vector<uint8_t> png8 = encodePng(4, 2, 8, rgba);
    writeBytes(file8, png8.data(), png8.size());
    const Result<Environment> env8 = loadLatLongEnvironment(file8, 1.0f, 0.0f);
    ASSERT_TRUE(env8.ok()) << env8.error().message;
    const Image& image8 = env8.value().image;
    ASSERT_EQ(image8.width, 4u);
    EXPECT_NEAR(image8.texels[0].x, 0.5029f, 1e-4f);
    EXPECT_NEAR(image8.texels[0].y, 0.2158605f, 1e-6f);
    EXPECT_EQ(image8.texels[0].z, 0.0f);
    EXPECT_NEAR(image8.texels[1].x, 10.0f / 255.0f / 12.92f, 1e-7f);
    EXPECT_EQ(image8.texels[7], glm::vec4(1.0f));

    // 16 bits: 32768 / 65535 is sRGB 0.5, linear 0.21404.
    std::vector<uint16_t> rgba16(4 * 2 * 4, 65535);
    rgba16[0] = 32768;
    const fs::path file16 = dir / "sky16.png";
    const std::vector<uint8_t> png16 = encodePng(4, 2, 16, rgba16);
    writeBytes(file16, png16.data(), png16.size());
    const Result<Environment> env16 = loadLatLongEnvironment(file16, 1.0f, 0.0f);
    ASSERT_TRUE(env16.ok()) << env16.error().message;
    EXPECT_NEAR(env16.value().image.texels[0].x, 0.21404114f, 1e-5f);
    EXPECT_EQ(env16.value().image.texels[0].y, 1.0f);
}

// Issue 17: the map is untrusted input like the scene. A FIFO is refused without waiting on it
// (before, is_regular_file refused it too, but as "no such file"), and a header claiming more
// pixels than the limit is refused before its pixels are allocated (the file holds 20 bytes).
TEST(EnvironmentErrors, SpecialFilesAndForgedHeaders) {
    TempDir dir;
    const fs::path fifo = dir / "sky.hdr";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const Result<Environment> from_fifo = loadLatLongEnvironment(fifo, 1.0f, 0.0f);
    ASSERT_FALSE(from_fifo.ok());
    EXPECT_EQ(from_fifo.error().message,
              fifo.string() + ": the environment map is not a regular file (it is a FIFO)");
    fs::create_directories(dir / "folder.hdr");
    const Result<Environment> from_dir = loadLatLongEnvironment(dir / "folder.hdr", 1.0f, 0.0f);
    ASSERT_FALSE(from_dir.ok());
    EXPECT_TRUE(contains(from_dir.error().message, "(it is a directory)"))
        << from_dir.error().message;

    const fs::path forged = dir / "forged.pfm";
    writeText(forged, "PF\n40000 20000\n-1.0\n");
    const Result<Environment> huge = loadLatLongEnvironment(forged, 1.0f, 0.0f);
    ASSERT_FALSE(huge.ok());
    EXPECT_EQ(huge.error().code, ErrorCode::OutOfRange);
    EXPECT_TRUE(contains(huge.error().message, forged.string() +
                                                   ": 40000 x 20000 pixels, more than the "
                                                   "environment map limit of 67108864"))
        << huge.error().message;
}

// Issue 31 class 5: the memory limit applies to the map's decode, from its header, before the
// pixels are allocated. This 20-byte PFM claims 11584 x 5792 RGB pixels (within the pixel
// limit): 768 MiB of float pixels and 1024 MiB of texels. Before, the pixels were allocated
// whatever max_memory_mb said and the refusal came from the decode, as an I/O error.
TEST(EnvironmentErrors, TheMemoryLimitAppliesBeforeTheDecode) {
    TempDir dir;
    const fs::path forged = dir / "forged.pfm";
    writeText(forged, "PF\n11584 5792\n-1.0\n");
    const Result<Environment> env =
        loadLatLongEnvironment(forged, 1.0f, 0.0f, uint64_t(1024) << 20);
    ASSERT_FALSE(env.ok());
    EXPECT_EQ(env.error().code, ErrorCode::OutOfRange);
    std::string expected = forged.string();
    expected += ": the environment map decodes to 1791 MiB (11584 x 5792 pixels, 3 channels as ";
    expected += "float, then RGBA float texels), more than the memory limit of 1024 MiB";
    EXPECT_TRUE(env.error().message.starts_with(expected)) << env.error().message;

    // Through the config, as probekit bake passes max_memory_mb: a real 4 x 2 map needs
    // 8 x (12 + 16) = 224 bytes.
    const fs::path small = dir / "small.pfm";
    writePfm(small, 4, 2, 3, std::vector<float>(24, 1.0f));
    EnvironmentConfig config;
    config.type = EnvironmentConfig::Type::LatLong;
    config.file = small.string();
    EXPECT_TRUE(makeEnvironment(config, 224).ok());
    const Result<Environment> refused = makeEnvironment(config, 223);
    ASSERT_FALSE(refused.ok());
    EXPECT_TRUE(refused.error().message.starts_with(small.string() + ": the environment map"))
        << refused.error().message;
}

TEST(EnvironmentErrors, MissingUnreadableWrongShapeAndBadTexels) {
    TempDir dir;
    const fs::path missing = dir / "missing.hdr";
    const Result<Environment> none = loadLatLongEnvironment(missing, 1.0f, 0.0f);
    ASSERT_FALSE(none.ok());
    EXPECT_EQ(none.error().code, ErrorCode::Io);
    EXPECT_TRUE(contains(none.error().message, missing.string())) << none.error().message;

    const fs::path garbage = dir / "garbage.exr";
    writeText(garbage, "not an image");
    const Result<Environment> unreadable = loadLatLongEnvironment(garbage, 1.0f, 0.0f);
    ASSERT_FALSE(unreadable.ok());
    EXPECT_TRUE(contains(unreadable.error().message, garbage.string()))
        << unreadable.error().message;

    const fs::path square = dir / "square.pfm";
    writePfm(square, 4, 4, 3, std::vector<float>(48, 1.0f));
    const Result<Environment> wrong_shape = loadLatLongEnvironment(square, 1.0f, 0.0f);
    ASSERT_FALSE(wrong_shape.ok());
    EXPECT_TRUE(contains(wrong_shape.error().message, "4 x 4")) << wrong_shape.error().message;

    // The first stored value is the bottom-left pixel: (0, 1) in top-down coordinates.
    for (const float bad :
         {std::numeric_limits<float>::quiet_NaN(), -1.0f, std::numeric_limits<float>::infinity()}) {
        std::vector<float> values(24, 1.0f);
        values[0] = bad;
        const fs::path file = dir / "bad.pfm";
        writePfm(file, 4, 2, 3, values);
        const Result<Environment> env = loadLatLongEnvironment(file, 1.0f, 0.0f);
        ASSERT_FALSE(env.ok()) << bad;
        EXPECT_TRUE(contains(env.error().message, file.string())) << env.error().message;
        EXPECT_TRUE(contains(env.error().message, "pixel (0, 1)")) << env.error().message;
    }
}
