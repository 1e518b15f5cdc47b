// Adaptive sampling (path.noise_target) in whole bakes: where the directions go, that the file
// does not depend on the thread count, and that vpl and lpv spend their direct-light samples
// the same way. The estimator's own statistics are tested in test_path.cpp
// (PathTracerAdaptive).
#include <gtest/gtest.h>

#include <cstdio>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/formats/pvol.hpp"

namespace probekit::baker {
namespace {

// The thin-wall scene: a point light in the -x room; the +x room is lit only through the
// doorway at z 1.2..2 (generators.cpp).
constexpr glm::vec3 kLitPoint(-2.0f, 1.2f, 0.5f);
constexpr glm::vec3 kUnlitPoint(2.0f, 1.2f, -1.0f);

BakeStats bakeAt(const Scene& scene, glm::vec3 point, float noise_target, float floor = 0.0f) {
    BakeConfig c = test::probesAt({point}, 0.05f);
    c.path.samples = 256;
    c.path.noiseTarget = noise_target;
    c.path.noiseFloor = floor;
    Result<BakeResult> r = bake(scene, c);
    EXPECT_TRUE(r.ok()) << r.error().message;
    return r.ok() ? r.value().stats : BakeStats{};
}

// The probe lit only by what comes through the doorway has a far noisier estimate than the
// one in the lit room, so it takes many more directions for the same relative noise; without
// a target both take the minimum.
TEST(AdaptiveBake, UnlitRoomTakesMoreDirectionsThanTheLitRoom) {
    const Scene scene = test::generatedScene("thin-wall");
    const BakeStats lit = bakeAt(scene, kLitPoint, 0.1f);
    const BakeStats unlit = bakeAt(scene, kUnlitPoint, 0.1f);
    std::printf("directions to noise 0.1: lit room %.0f, unlit room %.0f\n", lit.meanSamples,
                unlit.meanSamples);
    EXPECT_GE(unlit.meanSamples, 8.0 * lit.meanSamples);
    EXPECT_EQ(unlit.probesOverTarget, 0u); // under the default cap
    EXPECT_EQ(bakeAt(scene, kUnlitPoint, 0.0f).meanSamples, 256.0);
    EXPECT_EQ(bakeAt(scene, kLitPoint, 0.0f).meanSamples, 256.0);
    // A noise floor of 1 W/m^2 (the lit probe's RMS irradiance over the axis normals is about
    // 8, the unlit one's well under 1) holds the unlit probe to a tenth of the floor instead of
    // a tenth of its own irradiance: it stops far sooner.
    const BakeStats floored = bakeAt(scene, kUnlitPoint, 0.1f, 1.0f);
    std::printf("unlit room with a 1 W/m^2 floor: %.0f directions\n", floored.meanSamples);
    EXPECT_LE(floored.meanSamples, unlit.meanSamples / 8.0);
}

TEST(AdaptiveBake, BitIdenticalForOneAndTwoThreads) {
    const Scene scene = test::generatedScene("thin-wall");
    BakeConfig c = test::sceneVolume(64, glm::uvec3(8, 2, 4));
    c.path.noiseTarget = 0.05f;
    c.path.maxSamples = 8192;
    auto [a, b] = test::bakeOnOneAndTwoThreads(scene, c);
    ASSERT_TRUE(a.ok() && b.ok());
    // Some probes (the unlit room) stop at the cap, most far below it.
    EXPECT_EQ(a.value().stats.maxSamples, 8192u);
    EXPECT_LT(a.value().stats.meanSamples, 0.75 * 8192);
    EXPECT_EQ(a.value().stats.meanSamples, b.value().stats.meanSamples);
    test::expectSameFileButTiming(a.value(), b.value());
}

// vpl and lpv: the noise target drives their direct-light samples (vpl.direct_samples and
// lpv.direct_samples become the minimum). In the Cornell box the direct light comes from an
// emissive square sampled by next-event estimation, noisy at 128 directions; a target makes
// the probes take more, relative to the whole probe (VPL gather or cascades included).
// Without a target every probe takes exactly the minimum.
TEST(AdaptiveBake, VplAndLpvDirectLightFollowTheTarget) {
    const Scene scene = test::generatedScene("cornell");
    for (const Method method : {Method::Vpl, Method::Lpv}) {
        SCOPED_TRACE(int(method));
        BakeConfig c =
            test::probesAt({glm::vec3(0.28f, 0.4f, 0.1f), glm::vec3(0.1f, 0.1f, 0.4f)}, 0.01f);
        c.method = method;
        c.vpl.directSamples = 128;
        c.lpv.directSamples = 128;
        c.lpv.direct = LpvDirect::Traced;
        Result<BakeResult> fixed = bake(scene, c);
        ASSERT_TRUE(fixed.ok()) << fixed.error().message;
        c.path.noiseTarget = 0.01f;
        Result<BakeResult> adaptive = bake(scene, c);
        ASSERT_TRUE(adaptive.ok()) << adaptive.error().message;
        std::printf("method %d: fixed %.0f directions per probe (most %u), adaptive %.0f (most "
                    "%u)\n",
                    int(method), fixed.value().stats.meanSamples, fixed.value().stats.maxSamples,
                    adaptive.value().stats.meanSamples, adaptive.value().stats.maxSamples);
        EXPECT_EQ(fixed.value().stats.maxSamples, 128u);
        EXPECT_GT(adaptive.value().stats.maxSamples, 2u * 128u);
        EXPECT_EQ(adaptive.value().stats.probesOverTarget, 0u);
    }
}

} // namespace
} // namespace probekit::baker
