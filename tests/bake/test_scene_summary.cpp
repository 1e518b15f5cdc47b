// What the baker sees in a scene (summarizeScene, `probekit info SCENE.gltf`) and the refusal to
// bake a scene that emits no light (checkSceneLit, bake()).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/scene_summary.hpp"
#include "probekit/formats/pvol.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace {

// Float sums of a handful of products: a few float ulps of values up to ~1000.
constexpr double kSumTolerance = 1e-4;
constexpr double kPi = std::numbers::pi;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// A scene loaded from a generated glTF in this test's own folder.
Scene loadGenerated(const std::string& name, const std::string& folder) {
    const auto dir = test::tempDir(folder);
    EXPECT_TRUE(writeGeneratedScene(name, dir / (name + ".gltf")).ok());
    return test::loadOrFail(dir / (name + ".gltf"));
}

BakeConfig tinyBake() {
    return test::sceneVolume(16, glm::uvec3(2, 2, 2));
}

} // namespace

// The overcast courtyard has no sun and no emitter: without a sky every probe is zero by
// construction, so bake() refuses it, naming the file and what to add.
TEST(SceneLit, UnlitSceneFailsTheBakeNamingTheFileAndWhatToAdd) {
    Scene scene = loadGenerated("courtyard-overcast", "unlit_overcast");
    const Result<BakeResult> refused = bake(scene, tinyBake());
    ASSERT_FALSE(refused.ok());
    const std::string& message = refused.error().message;
    EXPECT_TRUE(contains(message, "courtyard-overcast.gltf: ")) << message;
    EXPECT_TRUE(contains(message, "emits no light")) << message;
    EXPECT_TRUE(contains(message, "KHR_lights_punctual light")) << message;
    EXPECT_TRUE(contains(message, "emissive material")) << message;
    EXPECT_TRUE(contains(message, "--env R,G,B|FILE")) << message;
    EXPECT_TRUE(contains(message, "\"environment\"")) << message;

    // Opting out bakes zeros, with the same message as a warning.
    BakeOptions allow;
    allow.allowUnlit = true;
    const Result<BakeResult> black = bake(scene, tinyBake(), allow);
    ASSERT_TRUE(black.ok()) << black.error().message;
    ASSERT_EQ(black.value().warnings.size(), 1u);
    EXPECT_EQ(black.value().warnings[0], message);
    for (const uint16_t texel : black.value().file.volumes[0].texelsF16) {
        EXPECT_EQ(texel & 0x7fff, 0) << "an unlit bake is zero everywhere";
    }

    // A sky (what the bake config's environment gives the scene) lights it: no error, no
    // warning.
    scene.environment.constant = glm::vec3(0.3f);
    const Result<BakeResult> sky = bake(scene, tinyBake());
    ASSERT_TRUE(sky.ok()) << sky.error().message;
    EXPECT_TRUE(sky.value().warnings.empty());
}

TEST(SceneLit, AnyLightEmitterOrSkyCountsAndZeroIntensityDoesNot) {
    Scene scene = test::openSky(glm::vec3(0.0f));
    ASSERT_FALSE(checkSceneLit(scene).ok()) << "black sky, nothing else";
    EXPECT_TRUE(contains(checkSceneLit(scene).error().message, "scene: ")) << "built in code";

    PunctualLight off;
    off.intensity = glm::vec3(0.0f);
    scene.lights.push_back(off);
    EXPECT_FALSE(checkSceneLit(scene).ok()) << "a light of intensity 0 gives no light";

    scene.lights[0].intensity = glm::vec3(0.0f, 0.0f, 1.0f);
    EXPECT_TRUE(checkSceneLit(scene).ok()) << "one channel is light";

    scene.lights.clear();
    scene.materials[0].emission = glm::vec3(1.0f, 0.0f, 0.0f);
    EXPECT_TRUE(checkSceneLit(scene).ok()) << "an emissive triangle";

    // An emissive material no triangle uses emits nothing.
    scene.materials.push_back(scene.materials[0]);
    scene.materials[0].emission = glm::vec3(0.0f);
    EXPECT_FALSE(checkSceneLit(scene).ok());

    scene.environment.constant = glm::vec3(0.1f);
    EXPECT_TRUE(checkSceneLit(scene).ok()) << "a sky";
}

// The generated Cornell box (generators.hpp): the emitter of radiance (17, 12, 4) is the
// published 130 mm x 105 mm light, two-sided: power 2 pi x area x radiance.
TEST(SceneSummary, CornellCountsMaterialsAndEmitter) {
    const Scene scene = loadGenerated("cornell", "summary_cornell");
    const SceneSummary s = summarizeScene(scene);
    EXPECT_EQ(s.triangles, scene.triangles.size());
    EXPECT_EQ(s.vertices, scene.positions.size());
    EXPECT_TRUE(s.lights.empty());
    ASSERT_EQ(s.materials.size(), scene.materials.size());
    uint64_t triangles = 0;
    for (const MaterialSummary& m : s.materials) {
        triangles += m.triangles;
    }
    EXPECT_EQ(triangles, s.triangles) << "every triangle counted under its material";

    EXPECT_EQ(s.emitters.triangles, 2u);
    const double area = 0.130 * 0.105;
    EXPECT_NEAR(s.emitters.area, area, kSumTolerance);
    EXPECT_NEAR(s.emitters.power.x, 2.0 * kPi * area * 17.0, kSumTolerance * 17.0);
    EXPECT_NEAR(s.emitters.power.y, 2.0 * kPi * area * 12.0, kSumTolerance * 12.0);
    EXPECT_NEAR(s.emitters.power.z, 2.0 * kPi * area * 4.0, kSumTolerance * 4.0);
    EXPECT_EQ(s.bounds.min, scene.bounds.min);
    EXPECT_EQ(s.bounds.max, scene.bounds.max);
    EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
}

// The courtyard's sun as the glTF gives it (generators.hpp: 3 lux x colour (1, 0.95, 0.85))
// and as the baker takes it (3, 2.85, 2.55) W/m^2; no power (it is not a finite source).
TEST(SceneSummary, CourtyardSunKeepsItsGltfIntensityAndColour) {
    const SceneSummary s = summarizeScene(loadGenerated("courtyard", "summary_courtyard"));
    EXPECT_EQ(s.triangles, 192u);
    ASSERT_EQ(s.lights.size(), 1u);
    const LightSummary& sun = s.lights[0];
    EXPECT_EQ(sun.type, LightType::Directional);
    EXPECT_FLOAT_EQ(sun.gltfIntensity, 3.0f);
    EXPECT_FLOAT_EQ(sun.color.y, 0.95f);
    EXPECT_FLOAT_EQ(sun.intensity.z, 2.55f);
    EXPECT_EQ(sun.power, glm::vec3(0.0f));
    EXPECT_EQ(s.emitters.triangles, 0u);
    EXPECT_FLOAT_EQ(s.bounds.size().x, 16.4f);
    EXPECT_FLOAT_EQ(s.bounds.size().y, 6.1f);

    // Without its sun nothing lights it: the summary carries checkSceneLit's warning.
    const SceneSummary overcast =
        summarizeScene(loadGenerated("courtyard-overcast", "summary_overcast"));
    ASSERT_EQ(overcast.warnings.size(), 1u);
    EXPECT_TRUE(contains(overcast.warnings[0], "emits no light")) << overcast.warnings[0];
}

// Point light: power 4 pi I (candela taken as W/sr, formats/CONVENTIONS.md). Spot light: I x
// the solid-angle integral of the glTF falloff t^2, which ramps linearly in cos from the outer
// cone to the inner one: 2 pi [(1 - cos_inner) + (cos_inner - cos_outer) / 3].
TEST(SceneSummary, PointAndSpotPowerFromTheirIntensity) {
    Scene scene = test::openSky(glm::vec3(0.0f));
    PunctualLight point;
    point.intensity = glm::vec3(8.0f, 4.0f, 2.0f);
    PunctualLight spot;
    spot.type = LightType::Spot;
    spot.intensity = glm::vec3(2.0f);
    spot.innerConeCos = float(std::cos(0.3));
    spot.outerConeCos = float(std::cos(0.6));
    scene.lights = {point, spot};
    const SceneSummary s = summarizeScene(scene);
    ASSERT_EQ(s.lights.size(), 2u);
    EXPECT_NEAR(s.lights[0].power.x, 4.0 * kPi * 8.0, kSumTolerance * 8.0);
    EXPECT_NEAR(s.lights[0].power.z, 4.0 * kPi * 2.0, kSumTolerance * 2.0);
    // Built in code: the largest channel is the intensity, the rest the colour.
    EXPECT_EQ(s.lights[0].gltfIntensity, 8.0f);
    EXPECT_EQ(s.lights[0].color, glm::vec3(1.0f, 0.5f, 0.25f));
    const double ci = spot.innerConeCos;
    const double co = spot.outerConeCos;
    EXPECT_NEAR(s.lights[1].power.x, 2.0 * 2.0 * kPi * ((1.0 - ci) + (ci - co) / 3.0),
                kSumTolerance);
    EXPECT_TRUE(s.warnings.empty()) << "lit by its lights";
}

// The file holds no wall time, so two bakes of the same input give the same bytes, for any
// thread count (ARCHITECTURE.md: output is deterministic), without zeroing anything first.
TEST(BakeReproducibility, EncodedBytesEqualForOneAndTwoThreads) {
    const Scene scene = loadGenerated("cornell", "reproducible_cornell");
    BakeOptions one;
    one.threads = 1;
    BakeOptions two;
    two.threads = 2;
    for (const Method method : {Method::Path, Method::Vpl}) {
        BakeConfig c = tinyBake();
        c.method = method;
        c.vpl.count = 1024;
        const Result<BakeResult> a = bake(scene, c, one);
        const Result<BakeResult> b = bake(scene, c, two);
        const Result<BakeResult> again = bake(scene, c, two);
        ASSERT_TRUE(a.ok() && b.ok() && again.ok());
        EXPECT_EQ(a.value().file.metadata.bakeSeconds, 0.0);
        EXPECT_GT(a.value().stats.seconds, 0.0) << "the wall time is in the stats";
        EXPECT_EQ(encodePvol(a.value().file), encodePvol(b.value().file)) << toString(method);
        EXPECT_EQ(encodePvol(b.value().file), encodePvol(again.value().file)) << toString(method);
    }
}

namespace {

// A stand-in for another process: hands the batch's chunks out in reverse order, one every
// `stride` to "this" process and the rest computed into a scratch copy that is then copied
// over, as a distributor receiving them would; counts what it saw.
class ReversedChunks : public ProbeDistributor {
public:
    explicit ReversedChunks(size_t chunk) : m_chunk(chunk) {}
    ProbeChunkStats run(size_t count, std::span<sh::ShRgb> sh, std::span<uint8_t> valid,
                        const Compute& compute) override {
        ProbeChunkStats total;
        const size_t chunks = (count + m_chunk - 1) / m_chunk;
        for (size_t i = chunks; i-- > 0;) {
            const size_t begin = i * m_chunk;
            const size_t end = std::min(count, begin + m_chunk);
            // The "remote" chunk's results travel: compute, save, scramble, restore.
            total += compute(begin, end);
            const std::vector<sh::ShRgb> sent(sh.begin() + long(begin), sh.begin() + long(end));
            const std::vector<uint8_t> sent_valid(valid.begin() + long(begin),
                                                  valid.begin() + long(end));
            std::fill(sh.begin() + long(begin), sh.begin() + long(end), sh::ShRgb{});
            std::copy(sent.begin(), sent.end(), sh.begin() + long(begin));
            std::copy(sent_valid.begin(), sent_valid.end(), valid.begin() + long(begin));
            ++chunksSeen;
        }
        ++batches;
        probes += count;
        return total;
    }
    size_t chunksSeen = 0;
    size_t batches = 0;
    size_t probes = 0;

private:
    size_t m_chunk;
};

} // namespace

// Every batch of probes goes through BakeOptions::distributor (docs/baking.md#distributed-bakes):
// chunks in any order on any process give the same bytes and the same statistics as one
// process, for a dense and a bricked volume (whose refinement bakes level by level) and the
// vpl method.
TEST(BakeDistributor, ChunksInAnyOrderGiveTheSameBytesAndStats) {
    const Scene scene = loadGenerated("cornell", "distributed_cornell");
    for (const bool bricked : {false, true}) {
        for (const Method method : {Method::Path, Method::Vpl}) {
            BakeConfig c = tinyBake();
            c.method = method;
            c.vpl.count = 1024;
            if (bricked) {
                c.volumes[0].layout = VolumeLayout::Bricked;
                c.volumes[0].resolution = glm::uvec3(2);
                c.volumes[0].maxLevel = 2;
                c.volumes[0].refineError = 0.05f;
            }
            BakeOptions plain;
            plain.threads = 2;
            ReversedChunks distributor(7);
            BakeOptions spread = plain;
            spread.distributor = &distributor;
            const Result<BakeResult> a = bake(scene, c, plain);
            const Result<BakeResult> b = bake(scene, c, spread);
            ASSERT_TRUE(a.ok() && b.ok());
            std::string what = bricked ? "bricked " : "dense ";
            what += toString(method);
            EXPECT_EQ(encodePvol(a.value().file), encodePvol(b.value().file)) << what;
            EXPECT_EQ(a.value().stats.rays, b.value().stats.rays) << what;
            EXPECT_EQ(a.value().stats.probes, b.value().stats.probes) << what;
            EXPECT_EQ(a.value().stats.maxSamples, b.value().stats.maxSamples) << what;
            EXPECT_EQ(a.value().stats.meanSamples, b.value().stats.meanSamples) << what;
            EXPECT_EQ(distributor.probes, b.value().stats.probes) << what;
            EXPECT_GE(distributor.batches, bricked ? 2u : 1u) << what;
            EXPECT_GT(distributor.chunksSeen, distributor.batches) << what;
        }
    }
}
