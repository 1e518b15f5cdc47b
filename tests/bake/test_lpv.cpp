// Method "lpv" (light propagation volumes): flux bookkeeping of a propagation step, leaks
// through a thin wall against the path reference, continuity across cascade borders,
// determinism, and the "lpv" config section.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "methods/lpv.hpp"
#include "methods/lpv_method.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/formats/pvol.hpp"
#include "trace/ray_tracer.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace {

Scene thinWallScene() {
    return test::generatedScene("thin-wall");
}

// A line of probes: a custom volume of resolution `res` (one axis > 1) between lo and hi.
VolumeConfig probeLine(glm::vec3 lo, glm::vec3 hi, glm::uvec3 res) {
    VolumeConfig v;
    v.bounds.mode = BoundsMode::Custom;
    v.bounds.min = lo;
    v.bounds.max = hi;
    v.resolution = res;
    v.storage = Storage::Float32;
    return v;
}

// Irradiance on a surface facing `normal` at every probe of the bake's first volume, green.
std::vector<double> irradianceAlong(const BakeResult& r, glm::vec3 normal) {
    const Volume& v = r.file.volumes[0];
    std::vector<double> e;
    for (size_t i = 0; i < v.probeCount(); ++i) {
        e.push_back(sh::irradiance(v.probe(i), v.desc.shOrder, normal).y);
    }
    return e;
}

double sum(const std::vector<double>& values) {
    double s = 0.0;
    for (double v : values) {
        s += v;
    }
    return s;
}

} // namespace

// Occlusion off, nothing but light in a 32^3 grid: every step moves exactly the flux it is
// given. The bookkeeping flux(before) = flux(after) + escaped holds per step to float rounding
// (kRoundingPerStep: each cell sums 6 transfers of 4 terms in float, relative error ~1e-6, the
// totals are summed in double): nothing grows, and nothing vanishes but through the border.
// The negative net flux that L1 ringing leaves in some cells is zeroed and taken from the
// positive light (lpv.hpp); its share is reported (measured: 14% of the flux at the first step
// after injection, ~3% per step later).
TEST(LpvEnergy, FluxIsConservedPerStepInOpenSpace) {
    constexpr double kRoundingPerStep = 1e-5;
    constexpr uint32_t kSteps = 40;

    const Scene empty;
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(empty);
    ASSERT_TRUE(tracer.ok());
    LpvCascadeLayout layout;
    layout.origin = glm::vec3(-16.0f);
    layout.cellSize = 1.0f;
    layout.cells = glm::ivec3(32);
    // Lights of assorted normals and colours within a metre of the centre.
    std::vector<LpvSurfaceLight> lights;
    for (int i = 0; i < 64; ++i) {
        const glm::vec3 n = sh::fibonacciDirection(i, 64);
        lights.push_back(LpvSurfaceLight{0.8f * sh::fibonacciDirection((7 * i) % 64, 64), n,
                                         glm::vec3(1.0f + 0.1f * float(i % 5), 0.5f, 0.25f)});
    }
    const LpvInjection injection =
        traceLpvInjection(*tracer.value(), lights, {}, layout.cellSize, 1, 1);
    LpvField current(layout.cellCount());
    injectLights(layout, injection, nullptr, nullptr, current);
    const LpvTransfer transfer = buildLpvTransfer(empty, layout, LpvSettings{});
    const glm::dvec3 injected = current.totalFlux();
    double emitted = 0.0;
    for (const LpvSurfaceLight& l : lights) {
        emitted += l.flux.x;
    }
    EXPECT_NEAR(injected.x, emitted, kRoundingPerStep * emitted) << "injection keeps every watt";

    double worst_redistributed = 0.0;
    double escaped_total = 0.0;
    LpvField next;
    for (uint32_t step = 0; step < kSteps; ++step) {
        const glm::dvec3 before = current.totalFlux();
        const LpvStepFlux flux = propagateStep(layout, transfer, current, next, 2);
        const glm::dvec3 after = next.totalFlux();
        for (int ch = 0; ch < 3; ++ch) {
            const double balance = after[ch] + double(flux.escaped[ch]) - before[ch];
            EXPECT_LE(std::abs(balance), kRoundingPerStep * before[ch])
                << "step " << step << " channel " << ch;
            worst_redistributed =
                std::max(worst_redistributed, -double(flux.redistributed[ch]) / before[ch]);
        }
        escaped_total += flux.escaped.x;
        std::swap(current, next);
    }
    // The light reaches the border after ~15 steps; by 40 most of it has left, and what is
    // left plus what escaped is what was injected.
    EXPECT_GT(escaped_total, 0.5 * injected.x);
    EXPECT_NEAR(current.totalFlux().x + escaped_total, injected.x,
                kSteps * kRoundingPerStep * injected.x);
    std::printf("[lpv energy] largest share redistributed in a step %.4f; %.1f%% escaped after "
                "%u steps\n",
                worst_redistributed, 100.0 * escaped_total / injected.x, kSteps);
}

// The bundled thin-wall scene: light in the -x room, probes 30 cm from the 5 cm wall in the
// other room, away from the doorway (z <= 0; the doorway is z 1.2..2). LPV irradiance facing
// the wall over the path reference's. Without occlusion the lit room's light passes the wall
// (measured ratio ~56); the geometry volume must cut the excess (ratio - 1) at least in half
// (measured: to ~0.2, 99.6% less). The reference's noise (two seeds at kPathSamples differ by
// ~5% in the sum) is far below what is tested.
TEST(LpvThinWall, OcclusionCutsTheLeakAtLeastInHalf) {
    constexpr uint32_t kPathSamples = 65536;
    constexpr double kRequiredCut = 0.5;
    const Scene scene = thinWallScene();
    ASSERT_TRUE(scene.hasGeometry());
    // Probes at x = 0.325 (the wall face is x = 0.025), y = 1.25, z = -1.5, -1, -0.5, 0.
    const VolumeConfig line = probeLine(glm::vec3(0.275f, 1.2f, -1.75f),
                                        glm::vec3(0.375f, 1.3f, 0.25f), glm::uvec3(1, 1, 4));
    const glm::vec3 facing_wall(-1.0f, 0.0f, 0.0f);

    BakeConfig path;
    path.volumes = {line};
    path.path.samples = kPathSamples;
    path.path.maxBounces = 64;
    Result<BakeResult> reference = bake(scene, path);
    ASSERT_TRUE(reference.ok()) << reference.error().message;
    const double e_path = sum(irradianceAlong(reference.value(), facing_wall));
    ASSERT_GT(e_path, 0.0);

    BakeConfig lpv;
    lpv.method = Method::Lpv;
    lpv.volumes = {line};
    Result<BakeResult> on = bake(scene, lpv);
    lpv.lpv.occlusion = false;
    Result<BakeResult> off = bake(scene, lpv);
    ASSERT_TRUE(on.ok() && off.ok());
    const double ratio_on = sum(irradianceAlong(on.value(), facing_wall)) / e_path;
    const double ratio_off = sum(irradianceAlong(off.value(), facing_wall)) / e_path;
    std::printf("[lpv thin wall] leak ratio LPV / path: occlusion on %.3f, off %.3f (excess cut "
                "by %.1f%%)\n",
                ratio_on, ratio_off, 100.0 * (1.0 - (ratio_on - 1.0) / (ratio_off - 1.0)));
    EXPECT_GT(ratio_off, 1.0);
    EXPECT_LE(ratio_on - 1.0, (1.0 - kRequiredCut) * (ratio_off - 1.0));
}

// Three cascades (ratio 2) in the lit room of the thin-wall scene (8 m, larger than the finest
// cascade, 2.2 m): a vertical line of probes 3.75 cm apart crosses the borders of both finer
// cascades (at y 0.43, 0.84, 1.66, 2.07). The fade band spreads the difference between two
// cascades over 2 cells (0.14 m and 0.27 m), so no step between neighbouring probes may exceed
// the largest step the one-cascade bake has along the same line (0.16 W/m^2, where the light
// itself changes fastest, under the ceiling): the borders add no jump of their own. Without the
// fade band the border steps are three times that (checked, so the test can fail).
TEST(LpvCascades, IrradianceIsContinuousAcrossCascadeBorders) {
    const Scene scene = thinWallScene();
    ASSERT_TRUE(scene.hasGeometry());
    const VolumeConfig line = probeLine(glm::vec3(-1.05f, 0.05f, 0.45f),
                                        glm::vec3(-0.95f, 2.45f, 0.55f), glm::uvec3(1, 64, 1));
    const glm::vec3 normal(1.0f, 0.0f, 0.0f);
    auto steps = [&](uint32_t cascades, float fade_cells) {
        BakeConfig c;
        c.method = Method::Lpv;
        c.volumes = {line};
        c.lpv.cascades = cascades;
        c.lpv.fadeCells = fade_cells;
        Result<BakeResult> r = bake(scene, c);
        EXPECT_TRUE(r.ok());
        const std::vector<double> e =
            r.ok() ? irradianceAlong(r.value(), normal) : std::vector<double>(2, 0.0);
        double largest = 0.0;
        for (size_t i = 0; i + 1 < e.size(); ++i) {
            largest = std::max(largest, std::abs(e[i + 1] - e[i]));
        }
        return largest;
    };
    const double single = steps(1, 2.0f);
    const double cascaded = steps(3, 2.0f);
    const double hard = steps(3, 0.0f);
    std::printf("[lpv cascades] largest step between probes 3.75 cm apart: 1 cascade %.4f, 3 "
                "cascades %.4f (fade 2 cells), %.4f (no fade) W/m^2\n",
                single, cascaded, hard);
    EXPECT_LE(cascaded, single);
    EXPECT_GT(hard, single);
}

// Same input, bit-identical file for 1 and 2 threads (propagation and escape rays are split
// across threads); another seed changes the VPLs and so the result.
TEST(LpvDeterminism, BitIdenticalForOneAndTwoThreads) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c = test::methodVolume(Method::Lpv, glm::uvec3(4, 4, 2));
    c.lpv.cascades = 2;
    c.lpv.directSamples = 16;
    auto [a, b] = test::bakeOnOneAndTwoThreads(scene, c);
    ASSERT_TRUE(a.ok() && b.ok());
    test::expectSameFileButTiming(a.value(), b.value());
    test::expectOtherSeedChangesTexels(scene, c, a.value());
}

TEST(LpvConfig, ParsesTheSectionAndRecordsResolvedValues) {
    const char* text = R"({"method": "lpv",
      "lpv": {"grid": 16, "cascades": 2, "cascade_ratio": 3, "iterations": "auto",
              "propagation_weight": 0.9, "fade_cells": 1.5, "occlusion": "off",
              "direct": "propagated", "direct_samples": 64, "vpl_count": 4096,
              "intensity": 2}})";
    Result<BakeConfig> c = parseBakeConfig(text, "bake.json");
    ASSERT_TRUE(c.ok()) << c.error().message;
    const LpvConfig& l = c.value().lpv;
    EXPECT_EQ(c.value().method, Method::Lpv);
    EXPECT_EQ(l.grid, 16u);
    EXPECT_EQ(l.cascades, 2u);
    EXPECT_EQ(l.cascadeRatio, 3.0f);
    EXPECT_FALSE(l.iterations.has_value());
    EXPECT_EQ(resolveLpvSettings(l).iterations, 16u) << "auto iterations = grid";
    EXPECT_EQ(l.propagationWeight, 0.9f);
    EXPECT_EQ(l.fadeCells, 1.5f);
    EXPECT_FALSE(l.occlusion);
    EXPECT_EQ(l.direct, LpvDirect::Propagated);
    EXPECT_EQ(l.directSamples, 64u);
    EXPECT_EQ(l.vplCount, 4096u);
    EXPECT_EQ(l.intensity, 2.0f);
    const std::string described = describeConfig(c.value());
    EXPECT_NE(described.find(R"("direct":"propagated")"), std::string::npos) << described;
    EXPECT_NE(described.find(R"("iterations":"auto")"), std::string::npos) << described;
}

TEST(LpvConfig, ErrorsNameTheField) {
    const test::ConfigErrorCase cases[] = {
        {R"({"lpv": {"gird": 32}})", "bake.json: lpv.gird: unknown field"},
        {R"({"lpv": {"grid": 2}})", "lpv.grid: must be in 4..256"},
        {R"({"lpv": {"cascades": 5}})", "lpv.cascades"},
        {R"({"lpv": {"cascade_ratio": 1}})", "lpv.cascade_ratio"},
        {R"({"lpv": {"iterations": 0}})", "lpv.iterations"},
        {R"({"lpv": {"propagation_weight": 1.5}})", "lpv.propagation_weight"},
        {R"({"lpv": {"occlusion": true}})", "lpv.occlusion: must be a string"},
        {R"({"lpv": {"direct": "probe"}})", "lpv.direct: \"probe\" is not one of"},
        {R"({"lpv": {"intensity": -1}})", "lpv.intensity"},
        {R"({"method": "lvp"})", "method: \"lvp\" is not one of path, vpl, lpv"},
    };
    test::expectConfigErrors(cases);
}

// Direct light propagated instead of traced: the point light of the thin-wall scene enters the
// grid as its intensity distribution and reaches the probes of its room through the cells.
// The LPV's direct light is coarse (Cornell box rel RMSE ~0.3 against ~0.1 traced), so this
// checks the bookkeeping, not accuracy: in the lit room the two modes agree within
// kPropagatedFactor (measured: propagated / traced 0.92), and behind the wall the propagated
// light stays below a tenth of the lit room's (measured 1.4%).
TEST(LpvPropagated, LightsReachTheProbesThroughTheGrid) {
    constexpr double kPropagatedFactor = 2.0;
    const Scene scene = thinWallScene();
    ASSERT_TRUE(scene.hasGeometry());
    // Probes 2 m from the light in the lit room (z = 1) and behind the wall (x = 2, z = -1).
    BakeConfig c;
    c.method = Method::Lpv;
    c.volumes = {
        probeLine(glm::vec3(-3.05f, 0.95f, 0.95f), glm::vec3(-2.95f, 1.05f, 1.05f), glm::uvec3(1)),
        probeLine(glm::vec3(1.95f, 0.95f, -1.05f), glm::vec3(2.05f, 1.05f, -0.95f), glm::uvec3(1))};
    c.volumes[1].name = "behind";
    Result<BakeResult> traced = bake(scene, c);
    c.lpv.direct = LpvDirect::Propagated;
    Result<BakeResult> propagated = bake(scene, c);
    ASSERT_TRUE(traced.ok() && propagated.ok());
    auto mean_irradiance = [](const BakeResult& r, size_t volume) {
        // Band 0: E averaged over all normals, pi Y00 L00.
        return double(sh::kPi * sh::kY00 * r.file.volumes[volume].probe(0).rgb[0].y);
    };
    const double lit_traced = mean_irradiance(traced.value(), 0);
    const double lit_propagated = mean_irradiance(propagated.value(), 0);
    const double behind = mean_irradiance(propagated.value(), 1);
    std::printf("[lpv propagated] mean irradiance in the lit room: traced %.3f, propagated %.3f; "
                "behind the wall %.4f W/m^2\n",
                lit_traced, lit_propagated, behind);
    EXPECT_GT(lit_propagated, lit_traced / kPropagatedFactor);
    EXPECT_LT(lit_propagated, lit_traced * kPropagatedFactor);
    EXPECT_LT(behind, 0.1 * lit_propagated);
}
