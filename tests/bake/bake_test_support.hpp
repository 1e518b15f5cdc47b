// Helpers shared by the bake test files: temporary folders, generated scenes, probes placed at
// points, and table-driven config-error checks.
#pragma once

#include <unistd.h>

#include <array>
#include <filesystem>
#include <numbers>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"

namespace probekit::test {

constexpr double kPi = std::numbers::pi;

// The Monte Carlo checks of test_path.cpp and test_vpl.cpp (their file comments say why): a mean
// must lie within kSigmas standard errors of the exact answer, plus kFloatSlack (relative to the
// largest reference coefficient) for float accumulation.
constexpr double kSigmas = 5.0;
constexpr double kFloatSlack = 2e-5;

// Gauss-Legendre, 8 points on [-1, 1]: exact for polynomials of degree 15.
constexpr std::array<double, 8> kGaussNodes = {
    -0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
    0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
constexpr std::array<double, 8> kGaussWeights = {
    0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
    0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};

// A fresh, empty folder under the system temporary directory.
// The process id keeps test processes that ctest -j runs at once out of each other's folders.
inline std::filesystem::path tempDir(const std::string& name) {
    auto dir = std::filesystem::temp_directory_path() /
               ("probekit_test_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

// Loads a glTF, failing the current test (and returning an empty scene) when it cannot.
inline baker::Scene loadOrFail(const std::filesystem::path& path) {
    Result<baker::Scene> s = baker::loadGltf(path);
    EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
    return s.ok() ? std::move(s).value() : baker::Scene{};
}

// Writes one of the bundled generated scenes (generators.hpp) and loads it.
inline baker::Scene generatedScene(const std::string& name) {
    const auto dir = tempDir("generated_" + name);
    const auto file = dir / (name + ".gltf");
    EXPECT_TRUE(baker::writeGeneratedScene(name, file).ok());
    return loadOrFail(file);
}

// One dense volume of `resolution` probes over the whole scene, `samples` path directions per
// probe, every other setting at its default.
// One volume of `resolution` probes over the whole scene, every other setting at its default.
inline std::vector<baker::VolumeConfig> wholeSceneVolume(glm::uvec3 resolution) {
    baker::VolumeConfig v;
    v.resolution = resolution;
    return {v};
}

// One dense volume of `resolution` probes over the whole scene, `samples` path directions per
// probe, every other setting at its default.
inline baker::BakeConfig sceneVolume(uint32_t samples, glm::uvec3 resolution) {
    baker::BakeConfig c;
    c.path.samples = samples;
    c.volumes = wholeSceneVolume(resolution);
    return c;
}

// A bake by `method` of one volume of `resolution` probes over the whole scene, every other
// setting at its default.
inline baker::BakeConfig methodVolume(baker::Method method, glm::uvec3 resolution) {
    baker::BakeConfig c;
    c.method = method;
    c.volumes = wholeSceneVolume(resolution);
    return c;
}

// BakeOptions with `threads` worker threads, every other option at its default.
inline baker::BakeOptions onThreads(uint32_t threads) {
    baker::BakeOptions options;
    options.threads = threads;
    return options;
}

// The same bake on one thread and on two, for the determinism tests.
inline std::pair<Result<baker::BakeResult>, Result<baker::BakeResult>>
bakeOnOneAndTwoThreads(const baker::Scene& scene, const baker::BakeConfig& config) {
    return {baker::bake(scene, config, onThreads(1)), baker::bake(scene, config, onThreads(2))};
}

// One 1x1x1 centre-mode float volume per point (a box of +-half_extent), so each probe sits
// exactly at its point.
inline baker::BakeConfig probesAt(const std::vector<glm::vec3>& points, float half_extent) {
    baker::BakeConfig c;
    for (size_t i = 0; i < points.size(); ++i) {
        baker::VolumeConfig v;
        // Appending (not operator+) avoids a GCC 12 -Wrestrict false positive.
        v.name = "p";
        v.name += std::to_string(i);
        v.bounds.mode = baker::BoundsMode::Custom;
        v.bounds.min = points[i] - glm::vec3(half_extent);
        v.bounds.max = points[i] + glm::vec3(half_extent);
        v.resolution = glm::uvec3(1);
        v.storage = Storage::Float32;
        c.volumes.push_back(v);
    }
    return c;
}

// A scene of nothing but the default material (index 0) under a black sky, to build on.
inline baker::Scene emptyScene() {
    baker::Scene scene;
    scene.materials.push_back(baker::Material{});
    scene.environment.type = baker::Environment::Type::Constant;
    scene.environment.constant = glm::vec3(0.0f);
    return scene;
}

// Appends a material of `albedo` and `emission` to `scene`; its index.
inline uint32_t addMaterial(baker::Scene& scene, glm::vec3 albedo, glm::vec3 emission) {
    baker::Material material;
    material.baseColor = albedo;
    material.emission = emission;
    scene.materials.push_back(material);
    return uint32_t(scene.materials.size() - 1);
}

// An open sky of constant radiance `sky` and nothing else nearby: a bake needs geometry for its
// ray tracer, so one 1 cm triangle sits ~170 m away (it hides ~3e-9 sr of the sky).
inline baker::Scene openSky(glm::vec3 sky) {
    baker::Scene scene;
    scene.materials.push_back(baker::Material{});
    scene.positions = {glm::vec3(100.0f), glm::vec3(100.01f, 100.0f, 100.0f),
                       glm::vec3(100.0f, 100.01f, 100.0f)};
    scene.uvs.assign(3, glm::vec2(0.0f));
    scene.triangles = {glm::uvec3(0, 1, 2)};
    scene.triangleMaterial = {0};
    scene.triangleNode = {-1};
    scene.bounds = {glm::vec3(100.0f), glm::vec3(100.01f, 100.01f, 100.0f)};
    scene.environment.type = baker::Environment::Type::Constant;
    scene.environment.constant = sky;
    return scene;
}

// Timing differs run to run; everything else in the two bakes' files must be the same bytes.
// Zeroes both files' bake time.
inline void expectSameFileButTiming(baker::BakeResult& a, baker::BakeResult& b) {
    a.file.metadata.bakeSeconds = b.file.metadata.bakeSeconds = 0;
    EXPECT_EQ(encodePvol(a.file), encodePvol(b.file));
}

// Another seed (7) changes the texels (binary16) of `config`'s bake `first`.
inline void expectOtherSeedChangesTexels(const baker::Scene& scene, baker::BakeConfig config,
                                         const baker::BakeResult& first) {
    config.seed = 7;
    Result<baker::BakeResult> other = baker::bake(scene, config, onThreads(1));
    ASSERT_TRUE(other.ok());
    EXPECT_NE(other.value().file.volumes[0].texelsF16, first.file.volumes[0].texelsF16);
}

// Each JSON config must be rejected with a message containing `expect`.
struct ConfigErrorCase {
    const char* json;
    const char* expect;
};

inline void expectConfigErrors(std::span<const ConfigErrorCase> cases) {
    for (const ConfigErrorCase& c : cases) {
        Result<baker::BakeConfig> r = baker::parseBakeConfig(c.json, "bake.json");
        ASSERT_FALSE(r.ok()) << c.json;
        EXPECT_NE(r.error().message.find(c.expect), std::string::npos)
            << "message: " << r.error().message << "\nexpected to contain: " << c.expect;
    }
}

} // namespace probekit::test
