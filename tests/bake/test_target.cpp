// Error-driven settings (baker::chooseSettings, --target-error) and the error measure of
// --verify (baker::estimateError), on synthetic numbers and on the generated Cornell box.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "methods/irradiance_error.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/target.hpp"
#include "probekit/runtime/sampler.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace {

// Sums of a few hundred float products in double: agreement to 1e-5 is float rounding only.
constexpr double kExact = 1e-5;

// Constant radiance L projects to L00 = L x integral of Y00 = L x 4 pi Y00; E(n) = pi L.
sh::ShRgb constantRadiance(glm::vec3 radiance) {
    sh::ShRgb s;
    s.rgb[0] = radiance * float(4.0 * M_PI * sh::kY00);
    return s;
}

PointBake constantReference(size_t n, glm::vec3 radiance) {
    PointBake p;
    p.sh.assign(n, constantRadiance(radiance));
    p.valid.assign(n, kProbeValid);
    return p;
}

TEST(TargetError, EstimateErrorMeasuresRelativeRmsAndSubtractsReferenceNoise) {
    const size_t n = 16;
    std::vector<glm::vec3> points(n, glm::vec3(0.0f));
    const glm::vec3 radiance(1.0f, 0.5f, 0.25f);
    const PointBake a = constantReference(n, radiance);
    // E of constant radiance L is pi L for every normal.
    const glm::vec3 e = float(M_PI) * radiance;
    auto scaled = [&](double factor) {
        return [=](glm::vec3, glm::vec3) { return e * float(factor); };
    };
    ErrorEstimate exact = estimateError(scaled(1.0), points, a, a);
    EXPECT_NEAR(exact.relRmse, 0.0, kExact);
    EXPECT_NEAR(exact.referenceNoise, 0.0, kExact);
    EXPECT_EQ(exact.points, n);
    ErrorEstimate ten = estimateError(scaled(1.1), points, a, a);
    EXPECT_NEAR(ten.relRmse, 0.1, kExact);

    // Two references 2 delta apart: their mean is the truth, each one's noise is delta, the
    // mean's variance delta^2 / 2 ... per point |a - b|^2 / 4 = delta^2: noise = delta / E.
    const PointBake lo = constantReference(n, radiance * 0.98f);
    const PointBake hi = constantReference(n, radiance * 1.02f);
    ErrorEstimate noisy = estimateError(scaled(1.1), points, lo, hi);
    EXPECT_NEAR(noisy.referenceNoise, 0.02, kExact);
    EXPECT_NEAR(noisy.relRmseRaw, 0.1, kExact);
    EXPECT_NEAR(noisy.relRmse, std::sqrt(0.1 * 0.1 - 0.02 * 0.02), kExact);

    // Points invalid in either reference are skipped.
    PointBake holes = a;
    holes.valid[3] = kProbeInvalid;
    EXPECT_EQ(estimateError(scaled(1.0), points, holes, a).points, n - 1);
}

// Equal points all carry the reference: n effective points. One point 100x brighter than 15
// others (a point near a light; 10^4 x their squared irradiance) counts as if it were at the
// bright-point cap, kBrightPointCap^2 = 16 x the median's square: weights 16 and fifteen 1s give
// 31^2 / (16^2 + 15) = 3.546 effective points, and its 10% error counts as 16 x 0.01 of 31
// (sqrt(0.16 / 31) = 0.0718), not as nearly all of the measure (0.0999 unbounded). A point 3x
// brighter is under the cap and counts in full.
TEST(TargetError, BrightPointsCountAtTheCapWithTheirOwnRelativeError) {
    const size_t n = 16;
    std::vector<glm::vec3> points(n, glm::vec3(0.0f));
    points[0] = glm::vec3(1.0f, 0.0f, 0.0f);
    const glm::vec3 radiance(1.0f);
    const PointBake even = constantReference(n, radiance);
    const glm::vec3 e = float(M_PI) * radiance;
    auto exact_everywhere = [=](glm::vec3, glm::vec3) { return e; };
    EXPECT_NEAR(estimateError(exact_everywhere, points, even, even).effectivePoints, double(n),
                kExact * double(n));

    auto hot_point = [&](float brighter) {
        PointBake hot = even;
        hot.sh[0] = constantRadiance(radiance * brighter);
        auto off_there = [=](glm::vec3 p, glm::vec3) {
            return p.x > 0.5f ? e * brighter * 1.1f : e;
        };
        return estimateError(off_there, points, hot, hot);
    };
    const double cap = kBrightPointCap * kBrightPointCap;
    const ErrorEstimate far_over = hot_point(100.0f);
    EXPECT_EQ(far_over.cappedPoints, 1u);
    const double expected_points = (cap + 15.0) * (cap + 15.0) / (cap * cap + 15.0);
    EXPECT_NEAR(far_over.effectivePoints, expected_points, kExact * expected_points);
    EXPECT_NEAR(far_over.relRmse, std::sqrt(0.01 * cap / (cap + 15.0)), kExact);

    const ErrorEstimate under = hot_point(3.0f);
    EXPECT_EQ(under.cappedPoints, 0u);
    EXPECT_NEAR(under.relRmse, std::sqrt(0.01 * 9.0 / (9.0 + 15.0)), kExact);
}

TEST(TargetError, BudgetSplitsTheTargetBetweenNoiseBandTwoAndInterpolation) {
    const Scene scene = test::generatedScene("cornell");
    const double target = 0.1;
    Result<TargetChoice> c = chooseSettings(scene, BakeConfig{}, target);
    ASSERT_TRUE(c.ok()) << c.error().message;
    const TargetChoice& t = c.value();
    std::printf("pilot noise %.4f, band 2 %.4f, samples %u, predicted noise %.4f, refine %.4f\n",
                t.pilotNoise, t.band2, t.samples, t.predictedNoise, t.interpolationBudget);
    // Samples: the count whose interpolated noise, (2/3)^3 of one probe's variance, is 0.6 t.
    const double wanted =
        t.pilotSamples * t.pilotNoise * t.pilotNoise * (8.0 / 27.0) / (0.6 * target * 0.6 * target);
    // (never fewer than kTargetMinSamples).
    EXPECT_EQ(t.samples, std::max(uint32_t(std::ceil(wanted)), kTargetMinSamples));
    EXPECT_LE(t.predictedNoise, 0.6 * target * (1.0 + kExact));
    // The Cornell box's coloured walls put a large share of the irradiance in band 2: L2.
    EXPECT_GT(t.band2, 0.4 * target);
    EXPECT_EQ(t.shOrder, sh::Order::L2);
    // Noise and interpolation use the whole target in quadrature.
    EXPECT_NEAR(t.predictedNoise * t.predictedNoise + t.interpolationBudget * t.interpolationBudget,
                target * target, kExact);
    ASSERT_EQ(t.config.volumes.size(), 1u);
    EXPECT_EQ(t.config.volumes[0].layout, VolumeLayout::Bricked);
    // Adaptive sampling carries the noise share: each probe to 0.6 t over the interpolation's
    // variance reduction, from samples / 8 (a power of two, at least the floor) to the cap.
    EXPECT_NEAR(t.probeNoiseTarget, 0.6 * target / std::sqrt(8.0 / 27.0), kExact);
    EXPECT_EQ(t.config.path.noiseTarget, float(t.probeNoiseTarget));
    EXPECT_EQ(t.minSamples, std::clamp(std::bit_floor(t.samples / 8), kTargetMinSamples, 4096u));
    EXPECT_EQ(t.config.path.samples, t.minSamples);
    EXPECT_EQ(t.config.path.maxSamples, kTargetMaxSamples);
    // Dark probes are held to the pilot's RMS irradiance (the box is lit: well above 0).
    EXPECT_GT(t.noiseFloor, 0.01);
    EXPECT_EQ(t.config.path.noiseFloor, float(t.noiseFloor));
}

TEST(TargetError, UniformSkyChoosesL1AndTheFewestSamples) {
    // A constant sky and one tiny triangle far away: no noise, nothing in band 2.
    const Scene scene = test::openSky(glm::vec3(1.0f));
    BakeConfig config;
    VolumeConfig v;
    v.bounds.mode = BoundsMode::Custom;
    v.bounds.min = glm::vec3(-1.0f);
    v.bounds.max = glm::vec3(1.0f);
    config.volumes = {v};
    Result<TargetChoice> c = chooseSettings(scene, config, 0.05);
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_EQ(c.value().shOrder, sh::Order::L1);
    EXPECT_EQ(c.value().samples, kTargetMinSamples);               // the floor
    EXPECT_LT(c.value().samplesWanted, double(kTargetMinSamples)); // what was asked, recorded
    EXPECT_LT(c.value().band2, 1e-3);
}

// On a level the error rule alone would space level 0 1.35 m apart at target 0.1 (the
// closed arena's 16 x 2 x 16 bricks); the planner holds it to kTargetMaxSpacing, with the
// fewest power-of-two bricks that do: half as many on the level's long axes would not.
TEST(TargetError, LevelZeroIsAtMostOneMetreApartOnALevel) {
    const Scene scene = test::generatedScene("arena-sealed");
    for (double target : {0.1, 0.2}) {
        SCOPED_TRACE(target);
        Result<TargetChoice> c = chooseSettings(scene, BakeConfig{}, target);
        ASSERT_TRUE(c.ok()) << c.error().message;
        Result<VolumePlan> plan = planVolumes(scene, c.value().config);
        ASSERT_TRUE(plan.ok()) << plan.error().message;
        for (const VolumeDesc& d : plan.value().volumes) {
            const glm::vec3 extent = d.grid.bounds().size();
            const glm::uvec3 bricks = d.grid.resolution();
            const glm::vec3 spacing = extent / glm::vec3(bricks * brick::kBrickCells);
            std::printf("target %.2f: %u x %u x %u level-0 bricks, spacing %.3f x %.3f x %.3f m\n",
                        target, bricks.x, bricks.y, bricks.z, spacing.x, spacing.y, spacing.z);
            for (int a = 0; a < 3; ++a) {
                EXPECT_LE(spacing[a], kTargetMaxSpacing + 1e-4) << "axis " << a;
            }
            // x and z (65 m): 16 bricks would be 1.35 m apart.
            EXPECT_GT(2.0f * spacing.x, kTargetMaxSpacing);
            EXPECT_GT(2.0f * spacing.z, kTargetMaxSpacing);
        }
    }
}

// The pilot's noise sets the budget's split, so a seed that measures more noise chooses a lower
// refine_error and refines other bricks. Over seeds 1-4 on the closed arena the 256-point
// pilot's noise spans 0.060-0.067 (1.11x); 64 points spanned 0.054-0.079 (1.45x), and eight
// seeds at 256 points 1.17x.
TEST(TargetError, ThePilotsNoiseHardlyDependsOnTheSeed) {
    const Scene scene = test::generatedScene("arena-sealed");
    double lowest = INFINITY, highest = 0.0;
    for (uint64_t seed = 1; seed <= 4; ++seed) {
        BakeConfig base;
        base.seed = seed;
        Result<TargetChoice> c = chooseSettings(scene, base, 0.1);
        ASSERT_TRUE(c.ok()) << c.error().message;
        std::printf("seed %llu: pilot noise %.4f over %u points, refine_error %.4f\n",
                    static_cast<unsigned long long>(seed), c.value().pilotNoise,
                    c.value().pilotPoints, c.value().interpolationBudget);
        EXPECT_GT(c.value().pilotPoints, 200u);
        lowest = std::min(lowest, c.value().pilotNoise);
        highest = std::max(highest, c.value().pilotNoise);
    }
    EXPECT_LT(highest / lowest, 1.25);
}

// The claim of --target-error, end to end on the Cornell box: the measured error (the same
// measure as --verify, against two independent 2048-direction path estimates at 256 points,
// their own noise subtracted) lands within 1.5x of the target. Everything is seeded, so this
// is a fixed number (0.141 at target 0.1 when written), not a flaky one.
// A --target-error bake measured the way --verify does: 256 points, two 2048-direction path
// estimates, their noise subtracted; with its prediction and its bricks.
struct TargetBake {
    ErrorEstimate measured;
    double predicted = 0.0;
    size_t bricks = 0;              // of the first volume
    double plannedDirections = 0.0; // the plan's directions per probe
    double meanDirections = 0.0;    // the bake's
    uint64_t plannedLevelZero = 0;  // the plan's level-0 probes
    uint64_t levelZero = 0;         // the baked level 0's lattice probes
};

TargetBake measureTargetBake(const Scene& scene, const BakeConfig& base, double target) {
    TargetBake out;
    Result<TargetChoice> c = chooseSettings(scene, base, target);
    EXPECT_TRUE(c.ok()) << c.error().message;
    if (!c.ok()) {
        return out;
    }
    EXPECT_GE(c.value().samples, kTargetMinSamples);
    Result<BakeResult> baked = bake(scene, c.value().config);
    EXPECT_TRUE(baked.ok()) << baked.error().message;
    if (!baked.ok()) {
        return out;
    }
    std::vector<VolumeDesc> descs;
    for (const Volume& v : baked.value().file.volumes) {
        descs.push_back(v.desc);
    }
    const std::vector<glm::vec3> points = volumeSamplePoints(descs, 256);
    Result<PointBake> a = bakePoints(scene, c.value().config, points, 2048, 1);
    Result<PointBake> b = bakePoints(scene, c.value().config, points, 2048, 2);
    EXPECT_TRUE(a.ok() && b.ok());
    if (!a.ok() || !b.ok()) {
        return out;
    }
    const runtime::VolumeSet set(baked.value().file.volumes);
    out.measured = estimateError([&](glm::vec3 p, glm::vec3 n) { return set.irradiance(p, n); },
                                 points, a.value(), b.value());
    out.predicted = predictError(c.value(), baked.value().stats);
    out.bricks = baked.value().file.volumes[0].desc.bricks.bricks.size();
    out.plannedDirections = c.value().expectedDirections;
    out.meanDirections = baked.value().stats.meanSamples;
    out.plannedLevelZero = c.value().levelZeroProbes;
    for (const Volume& v : baked.value().file.volumes) {
        const glm::uvec3 n = v.desc.grid.resolution() * brick::kBrickCells + 1u;
        out.levelZero += uint64_t(n.x) * n.y * n.z;
    }
    EXPECT_GT(out.measured.points, 200u);
    return out;
}

// Assets nobody tuned the baker for (generators.hpp): a textured, thin-legged creature in
// centimetres (loaded with scale 0.01), thin 3D text under a point and a spot light, and a
// single closed textured box in open space under a sun and a sky (automatic padding). Each
// lands within 1.5x of the target; everything is seeded, so these are fixed numbers (0.123,
// 0.106 and 0.092 measured at target 0.1 when written), not flaky ones.
TEST(TargetError, RealWorldLikeAssetsLandWithinOneAndAHalfTimesTheTarget) {
    const double target = 0.1;
    struct Case {
        const char* name;
        float scale;
        glm::vec3 sky;
    };
    for (const Case& k :
         {Case{"critter-cm", 0.01f, glm::vec3(0.0f)}, Case{"text-floor", 1.0f, glm::vec3(0.0f)},
          Case{"lone-box", 1.0f, glm::vec3(0.3f, 0.4f, 0.6f)}}) {
        SCOPED_TRACE(k.name);
        const auto dir = test::tempDir(std::string("target_") + k.name);
        ASSERT_TRUE(writeGeneratedScene(k.name, dir / "scene.gltf").ok());
        LoadOptions load;
        load.scale = k.scale;
        Result<Scene> scene = loadGltf(dir / "scene.gltf", load);
        ASSERT_TRUE(scene.ok()) << scene.error().message;
        scene.value().environment.constant = k.sky;
        BakeConfig base;
        base.scale = k.scale;
        const TargetBake t = measureTargetBake(scene.value(), base, target);
        std::printf("%s target %.3f: measured %.4f, predicted %.4f\n", k.name, target,
                    t.measured.relRmse, t.predicted);
        EXPECT_LE(t.measured.relRmse, target * 1.5);
    }
}

TEST(TargetError, CornellLandsWithinOneAndAHalfTimesTheTarget) {
    const Scene scene = test::generatedScene("cornell");
    const double target = 0.1;
    const TargetBake t = measureTargetBake(scene, BakeConfig{}, target);
    const ErrorEstimate& e = t.measured;
    std::printf("target %.3f: measured %.4f (reference noise %.4f, %zu points), predicted %.4f, "
                "%zu bricks\n",
                target, e.relRmse, e.referenceNoise, e.points, t.predicted, t.bricks);
    EXPECT_GT(e.points, 200u);
    EXPECT_GE(e.relRmse, target / 1.5);
    EXPECT_LE(e.relRmse, target * 1.5);
    // The plan printed before the bake: level 0's probes exactly, and the directions adaptive
    // sampling gives a probe (278 planned, 195 baked when written). Each pilot point's noise
    // comes from one pair of estimates, but the mean over 256 points varies by well under 10%;
    // 1.5x leaves room for the finer probes, which the plan does not model.
    std::printf("plan: %llu level-0 probes (baked %llu), %.0f directions per probe (baked mean "
                "%.0f)\n",
                static_cast<unsigned long long>(t.plannedLevelZero),
                static_cast<unsigned long long>(t.levelZero), t.plannedDirections,
                t.meanDirections);
    EXPECT_EQ(t.plannedLevelZero, t.levelZero);
    EXPECT_GT(t.plannedDirections, t.meanDirections / 1.5);
    EXPECT_LT(t.plannedDirections, t.meanDirections * 1.5);
}

TEST(TargetError, ConfigFieldIsParsedAndChecked) {
    Result<BakeConfig> ok = parseBakeConfig(R"({"target_error": 0.05})", "bake.json");
    ASSERT_TRUE(ok.ok()) << ok.error().message;
    ASSERT_TRUE(ok.value().targetError.has_value());
    EXPECT_DOUBLE_EQ(*ok.value().targetError, 0.05);
    const test::ConfigErrorCase cases[] = {
        {R"({"target_error": 1.5})", "bake.json: target_error: must be in (0, 1)"},
        {R"({"target_error": 0})", "bake.json: target_error: must be in (0, 1)"},
        {R"({"target_error": "small"})", "bake.json: target_error"},
    };
    test::expectConfigErrors(cases);
}

} // namespace

// A missed target names its largest term and the limit that held it.
TEST(TargetError, ExplainNamesTheLargestTermAndItsLimit) {
    TargetChoice c;
    c.target = 0.1;
    c.predictedNoise = 0.02;
    c.interpolationBudget = 0.08;
    c.samples = kTargetMinSamples;
    BakeStats s;
    s.predictedInterpolationError = 0.3;
    const auto has = [](const std::string& text, const char* part) {
        return text.find(part) != std::string::npos;
    };
    EXPECT_TRUE(has(explainError(c, s), "interpolation 0.3 is the largest term (budget 0.08)"));
    EXPECT_TRUE(has(explainError(c, s), "deepest level"));
    s.budgetDropped = 5;
    EXPECT_TRUE(has(explainError(c, s), "GPU budget dropped finer bricks"));
    s.memoryUntested = 2;
    EXPECT_TRUE(has(explainError(c, s), "working memory left candidate bricks unrefined"));
    s.predictedInterpolationError = 0.01;
    c.predictedNoise = 0.2;
    c.samples = kTargetMaxSamples;
    EXPECT_TRUE(has(explainError(c, s), "noise 0.2 is the largest term at 65536 directions per "
                                        "probe (the cap)"));
    c.predictedNoise = 0.01;
    c.shOrder = sh::Order::L1;
    c.band2 = 0.3;
    EXPECT_TRUE(has(explainError(c, s), "SH band 2 0.3, dropped by L1"));
}
