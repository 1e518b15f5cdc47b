// Coordinates beyond what float32 tracing can do (baker/src/scene/coordinate_range.hpp): the bake
// refuses them with an error naming the file and what is out of range, before anything is
// traced, and no ray reaches Embree outside what it accepts.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/target.hpp"
#include "scene/coordinate_range.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {
namespace {

constexpr const char* kRange =
    "outside the coordinate range a bake supports, |x|, |y|, |z| <= 1e+07 m (beyond it float32 "
    "resolves a metre or worse and rays leave surfaces hundreds of metres off); check the "
    "scene's units (--scale) or move it near the origin";

void expectError(const Result<BakeResult>& r, const std::string& expect) {
    ASSERT_FALSE(r.ok()) << "the bake ran";
    EXPECT_NE(r.error().message.find(expect), std::string::npos) << r.error().message;
}

// probekit bake c.gltf --scale 1e20: the Cornell box 5.6e19 m across. Its farthest vertex is on
// the first triangle of node 0 (the white walls).
TEST(HugeCoordinates, SceneScaledBy1e20IsRefused) {
    Scene scene = test::generatedScene("cornell");
    applyUnitScale(scene, 1e20f);
    BakeConfig c = test::sceneVolume(4, glm::uvec3(4));
    c.scale = 1e20f;
    const Result<BakeResult> r = bake(scene, c);
    expectError(r, scene.source +
                       ": node 0 ('white'), triangle 0: vertex (0, 0, 5.592e+19) m lies " +
                       std::string(kRange));
    EXPECT_EQ(r.error().code, ErrorCode::OutOfRange);
    // The other entry points that trace refuse it too.
    EXPECT_FALSE(planVolumes(scene, c).ok());
    EXPECT_FALSE(bakePoints(scene, c, {glm::vec3(0.0f)}, 4, 0).ok());
    EXPECT_FALSE(RayTracer::create(scene).ok());
}

// Positions around 1e38: a triangle built in code, no node.
TEST(HugeCoordinates, PositionsNear1e38AreRefused) {
    Scene scene = test::openSky(glm::vec3(1.0f));
    scene.source = "far.gltf";
    scene.positions = {glm::vec3(1e38f, 0.0f, 0.0f), glm::vec3(1e38f, 1.0f, 0.0f),
                       glm::vec3(1e38f, 0.0f, 1.0f)};
    scene.bounds = {glm::vec3(1e38f, 0.0f, 0.0f), glm::vec3(1e38f, 1.0f, 1.0f)};
    const Result<BakeResult> r = bake(scene, test::sceneVolume(4, glm::uvec3(2)));
    expectError(r, "far.gltf: triangle 0: vertex (1e+38, 0, 0) m lies " + std::string(kRange));
}

TEST(HugeCoordinates, FarLightIsRefused) {
    Scene scene = test::generatedScene("cornell");
    PunctualLight light;
    light.position = glm::vec3(0.0f, 3e9f, 0.0f);
    light.intensity = glm::vec3(1.0f);
    light.name = "lamp";
    scene.lights.push_back(light);
    const Result<BakeResult> r = bake(scene, test::sceneVolume(4, glm::uvec3(2)));
    expectError(r,
                scene.source + ": light 0 ('lamp') at (0, 3e+09, 0) m lies " + std::string(kRange));
}

TEST(HugeCoordinates, FarVolumeIsRefused) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c = test::sceneVolume(4, glm::uvec3(2));
    c.volumes[0].bounds.mode = BoundsMode::Custom;
    c.volumes[0].bounds.min = glm::vec3(0.0f);
    c.volumes[0].bounds.max = glm::vec3(2e7f, 1.0f, 1.0f);
    const Result<BakeResult> r = bake(scene, c);
    expectError(r, "volumes[0] ('volume'): the box (0, 0, 0) .. (2e+07, 1, 1) m reaches " +
                       std::string(kRange));
}

// Within the range but far from the origin for the probe spacing: the bake runs and says why
// its light near surfaces is wrong. (The box itself is rounded to 0.5 m there, so its 8 probes
// are 0.0625 m apart instead of 0.07.)
TEST(HugeCoordinates, FarFromTheOriginWarns) {
    Scene scene = test::generatedScene("cornell");
    for (glm::vec3& p : scene.positions) {
        p.x += 5e6f;
    }
    scene.bounds.min.x += 5e6f;
    scene.bounds.max.x += 5e6f;
    Result<VolumePlan> plan = planVolumes(scene, test::sceneVolume(4, glm::uvec3(8)));
    ASSERT_TRUE(plan.ok()) << plan.error().message;
    const std::string expect = scene.source +
                               ": coordinates reach 5e+06 m, where float32 resolves 0.5 m and "
                               "rays leave surfaces up to 128 m off, more than a quarter of the "
                               "finest probe spacing 0.0625 m";
    const std::vector<std::string>& notes = plan.value().notes;
    EXPECT_NE(std::find_if(notes.begin(), notes.end(),
                           [&](const std::string& n) { return n.starts_with(expect); }),
              notes.end())
        << (notes.empty() ? "no notes" : notes.back());
    // Near the origin, no such note.
    Result<VolumePlan> near =
        planVolumes(test::generatedScene("cornell"), test::sceneVolume(4, glm::uvec3(8)));
    ASSERT_TRUE(near.ok());
    for (const std::string& n : near.value().notes) {
        EXPECT_EQ(n.find("coordinates reach"), std::string::npos) << n;
    }
}

// The last line of defence: a NaN or out-of-range ray is a bug, caught before Embree sees it.
TEST(HugeCoordinatesDeathTest, InvalidRayIsAPreconditionFailure) {
    // Embree's threads are running: re-execute the test binary rather than fork it.
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const Scene scene = test::generatedScene("cornell");
    const std::unique_ptr<RayTracer> tracer = std::move(RayTracer::create(scene)).value();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    EXPECT_DEATH(tracer->intersect(glm::vec3(nan, 0.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f)),
                 "precondition failed in makeRay: validRay\\(origin, dir, t_max\\)");
    EXPECT_DEATH(tracer->occluded(glm::vec3(0.0f), glm::vec3(0.0f, 2e18f, 0.0f), 1.0f),
                 "precondition failed in makeRay: validRay\\(origin, dir, t_max\\)");
    EXPECT_DEATH(tracer->intersect(glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f), nan),
                 "precondition failed in makeRay: validRay\\(origin, dir, t_max\\)");
    // At the coordinate limit, any direction and an unbounded ray are fine.
    EXPECT_FALSE(tracer->occluded(glm::vec3(-1e7f), glm::vec3(-1.0f, -1e10f, 0.0f), kInfinity));
}

} // namespace
} // namespace probekit::baker
