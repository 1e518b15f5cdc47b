// Stability where methods fail: each test prints its figure ("[stability ...]") and asserts a
// bound. The places where light-probe methods are known to fail, and where each test lives:
//  1. VPL corner spikes per clamp mode: VplRoom.SphericalClampKeepsTheCornerSpikeNearTheAverage
//     in test_vpl.cpp (a probe 5 cm from a corner, every clamp mode, bias against the unclamped
//     gather); not repeated here.
//  2. Flicker of VPL sampling modes under a moving light (StabilityFlicker): within 1.5x of
//     the reference where direct light dominates; ~9x in a room lit only through a doorway.
//  3. Thin-wall leak: LPV occlusion on/off is LpvThinWall.OcclusionCutsTheLeakAtLeastInHalf in
//     test_lpv.cpp; VPL shadows on/off on the same probes is StabilityLeak here.
//  4. Probes inside geometry, validity and dilation on/off (StabilityInsideGeometry).
//  5. Half storage under a very bright emitter (StabilityHalf).
//  6. SH ringing under a strong directional light, with and without deringing (StabilityRinging).
// Path references use fixed seeds and enough samples that their noise (stated per test) is far
// below the bounds.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit::baker {
namespace {

constexpr int kNormals = 64; // the compare metric's normal count (runtime/compare.hpp)

using test::generatedScene;

// A float L2 volume of `res` probes over the box lo..hi (centre placement).
VolumeConfig boxVolume(glm::vec3 lo, glm::vec3 hi, glm::uvec3 res) {
    return VolumeConfig{.bounds = {.mode = BoundsMode::Custom, .min = lo, .max = hi},
                        .resolution = res,
                        .storage = Storage::Float32};
}

BakeResult bakeOrFail(const Scene& scene, const BakeConfig& config) {
    Result<BakeResult> r = bake(scene, config);
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    return r.ok() ? std::move(r).value() : BakeResult{};
}

// E (channel mean) of every probe of every volume at the Fibonacci normals, one flat list.
std::vector<double> allIrradiance(const BakeResult& r) {
    std::vector<double> out;
    for (const Volume& v : r.file.volumes) {
        for (size_t i = 0; i < v.probeCount(); ++i) {
            const sh::ShRgb s = v.probe(i);
            for (int k = 0; k < kNormals; ++k) {
                const glm::vec3 e =
                    sh::irradiance(s, v.desc.shOrder, sh::fibonacciDirection(k, kNormals));
                out.push_back((double(e.x) + double(e.y) + double(e.z)) / 3.0);
            }
        }
    }
    return out;
}

double rmsDifference(const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
        sum += (a[i] - b[i]) * (a[i] - b[i]);
    }
    return std::sqrt(sum / double(a.size()));
}

// ---------------------------------------------------------------------------------------------
// 2. Flicker: the thin-wall scene's point light moves in kSteps steps of kStep metres towards
// the wall, and a 4 x 2 x 4 grid is re-baked at every position with the same seed, as a game
// re-bakes when a light moves. Flicker = mean over steps of the RMS frame-to-frame change of E
// over probes and normals, over the path reference's own change (the light's real change plus
// its noise, which the fixed seed keeps correlated from frame to frame). VPL runs use the
// default settings (automatic count) with each sampling mode.
//  * Lit room (direct light dominates): the default sampling must stay within
//    kDefaultFlickerBound. Measured ~1.00 for every mode.
//  * Unlit room (all light came through the doorway): measured ~9x for every mode, ~8x even
//    at 65536 VPLs. The few light paths that reach it pass the doorway after several bounces,
//    and a 2 cm move of their origin changes where they land, so the room's VPLs are
//    re-drawn every frame: an open problem of the method, bounded here only against
//    regression (kUnlitRegressionBound).
TEST(StabilityFlicker, DefaultVplSamplingFollowsTheReferenceChange) {
    constexpr int kSteps = 16;
    constexpr float kStep = 0.02f;
    constexpr uint32_t kReferenceSamples = 4096;
    constexpr double kDefaultFlickerBound = 1.5;
    constexpr double kUnlitRegressionBound = 15.0;
    Scene scene = generatedScene("thin-wall");
    ASSERT_EQ(scene.lights.size(), 1u);
    const glm::vec3 start = scene.lights[0].position;

    const auto flicker = [&](const BakeConfig& config) {
        std::vector<double> previous;
        double sum = 0.0;
        for (int step = 0; step <= kSteps; ++step) {
            scene.lights[0].position = start + glm::vec3(kStep * float(step), 0.0f, 0.0f);
            const std::vector<double> e = allIrradiance(bakeOrFail(scene, config));
            if (!previous.empty()) {
                sum += rmsDifference(e, previous) / kSteps;
            }
            previous = e;
        }
        return sum;
    };
    const VplConfig defaults;
    for (const bool lit : {true, false}) {
        BakeConfig base;
        base.volumes = {lit ? boxVolume(glm::vec3(-3.5f, 0.5f, -1.5f), glm::vec3(-0.5f, 2.0f, 1.5f),
                                        glm::uvec3(4, 2, 4))
                            : boxVolume(glm::vec3(0.5f, 0.5f, -1.5f), glm::vec3(3.5f, 2.0f, 1.5f),
                                        glm::uvec3(4, 2, 4))};
        BakeConfig path = base;
        path.path.samples = kReferenceSamples;
        path.path.maxBounces = 64;
        const double reference = flicker(path);
        ASSERT_GT(reference, 0.0);
        double default_ratio = 0.0;
        for (const VplSampling sampling :
             {VplSampling::Random, VplSampling::Stratified, VplSampling::Jittered}) {
            BakeConfig vpl = base;
            vpl.method = Method::Vpl;
            vpl.vpl.sampling = sampling;
            const double ratio = flicker(vpl) / reference;
            std::printf("[stability flicker] %-5s room, %-10s sampling: frame-to-frame change "
                        "%.3f x the path reference's (%d steps of %.0f cm)\n",
                        lit ? "lit" : "unlit", std::string(toString(sampling)).c_str(), ratio,
                        kSteps, kStep * 100.0f);
            if (sampling == defaults.sampling) {
                default_ratio = ratio;
            }
        }
        EXPECT_LE(default_ratio, lit ? kDefaultFlickerBound : kUnlitRegressionBound);
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Thin-wall leak for VPL: the probes of LpvThinWall (30 cm from the 5 cm wall, in the unlit
// room, away from the doorway), irradiance facing the wall over the path reference's. Without
// shadows every VPL of the lit room shines through the wall; with them the excess (ratio - 1)
// must be cut at least by kRequiredCut, the bound the LPV occlusion meets.
TEST(StabilityLeak, VplShadowsCutTheThinWallLeak) {
    constexpr uint32_t kPathSamples = 32768; // two seeds differ by ~7% in the sum
    constexpr double kRequiredCut = 0.5;
    const Scene scene = generatedScene("thin-wall");
    const VolumeConfig line = boxVolume(glm::vec3(0.275f, 1.2f, -1.75f),
                                        glm::vec3(0.375f, 1.3f, 0.25f), glm::uvec3(1, 1, 4));
    const glm::vec3 facing_wall(-1.0f, 0.0f, 0.0f);
    const auto towardsWall = [&](const BakeResult& r) {
        double sum = 0.0;
        const Volume& v = r.file.volumes.at(0);
        for (size_t i = 0; i < v.probeCount(); ++i) {
            sum += sh::irradiance(v.probe(i), v.desc.shOrder, facing_wall).y;
        }
        return sum;
    };
    BakeConfig path;
    path.volumes = {line};
    path.path.samples = kPathSamples;
    path.path.maxBounces = 64;
    const double reference = towardsWall(bakeOrFail(scene, path));
    ASSERT_GT(reference, 0.0);
    BakeConfig vpl;
    vpl.method = Method::Vpl;
    vpl.volumes = {line};
    const double ratio_on = towardsWall(bakeOrFail(scene, vpl)) / reference;
    vpl.vpl.shadows = false;
    const double ratio_off = towardsWall(bakeOrFail(scene, vpl)) / reference;
    std::printf("[stability leak] VPL / path irradiance facing the thin wall, unlit side: "
                "shadows on %.3f, off %.3f\n",
                ratio_on, ratio_off);
    EXPECT_GT(ratio_off, 1.0);
    EXPECT_LE(std::abs(ratio_on - 1.0), (1.0 - kRequiredCut) * (ratio_off - 1.0));
}

// ---------------------------------------------------------------------------------------------
// 4. Probes inside geometry. An 8^3 grid over the Cornell box puts probes inside both blocks.
// What matters is the surfaces those probes light: points 2 cm in front of every block face
// (three heights per side face, the top faces), sampled through the runtime's trilinear
// VolumeSet with a normal offset of kNormalOffset (as a renderer samples: it keeps a face from
// interpolating probes behind it), against a path probe exactly at each point. With validity
// and dilation on, none may be darker than half or brighter than twice the reference; with
// them off (no probe invalid, no dilation) the black inside probes bleed into the faces:
// counted and printed, and the darkest face must be darker than with them on.
// Without the offset the figures are printed too: there one point (the short block's front
// face, looking out of the open box, 1% of the mean irradiance) comes out ~3x too bright with
// dilation, which fills an inside probe with the mean of its neighbours, including the lit
// ones above the block. All of this is run with visibility (formats/.../visibility.hpp) off,
// the behaviour it was written for, and on (the default), where the inside probes are hidden
// from the faces whatever their validity: the bounds for each are stated below.
struct ShadingPoint {
    glm::vec3 position;
    glm::vec3 normal;
};

std::vector<ShadingPoint> blockFacePoints() {
    constexpr float kOffset = 0.02f; // metres in front of the face
    // Footprints (x, z, metres) and heights of the generated Cornell blocks (generators.cpp).
    struct Block {
        glm::vec2 corners[4];
        float height;
    };
    const Block blocks[] = {
        {{{0.130f, 0.065f}, {0.290f, 0.114f}, {0.240f, 0.272f}, {0.082f, 0.225f}}, 0.165f},
        {{{0.423f, 0.247f}, {0.472f, 0.406f}, {0.314f, 0.456f}, {0.265f, 0.296f}}, 0.330f}};
    std::vector<ShadingPoint> points;
    for (const Block& b : blocks) {
        const glm::vec2 centre =
            0.25f * (b.corners[0] + b.corners[1] + b.corners[2] + b.corners[3]);
        for (int side = 0; side < 4; ++side) {
            const glm::vec2 mid = 0.5f * (b.corners[side] + b.corners[(side + 1) % 4]);
            const glm::vec2 out = glm::normalize(mid - centre);
            for (const float fraction : {0.25f, 0.5f, 0.75f}) {
                const glm::vec2 p = mid + kOffset * out;
                points.push_back(
                    {glm::vec3(p.x, fraction * b.height, p.y), glm::vec3(out.x, 0.0f, out.y)});
            }
        }
        points.push_back(
            {glm::vec3(centre.x, b.height + kOffset, centre.y), glm::vec3(0.0f, 1.0f, 0.0f)});
    }
    return points;
}

TEST(StabilityInsideGeometry, DilatedProbesLightBlockFacesWithinAFactorOfTwo) {
    constexpr uint32_t kGridSamples = 1024;
    constexpr uint32_t kReferenceSamples = 8192; // ~1% noise per point
    constexpr double kLow = 0.5, kHigh = 2.0;
    constexpr float kNormalOffset = 0.02f; // metres, ~0.3 probe spacings
    const Scene scene = generatedScene("cornell");
    const std::vector<ShadingPoint> points = blockFacePoints();

    BakeConfig reference;
    reference.path.samples = kReferenceSamples;
    reference.path.maxBounces = 64;
    reference.dilate = false;
    for (const ShadingPoint& p : points) {
        reference.volumes.push_back(boxVolume(p.position - glm::vec3(0.005f),
                                              p.position + glm::vec3(0.005f), glm::uvec3(1)));
        reference.volumes.back().name = "p";
        reference.volumes.back().name += std::to_string(reference.volumes.size());
    }
    const BakeResult ref = bakeOrFail(scene, reference);
    ASSERT_EQ(ref.file.volumes.size(), points.size());

    // A ratio says little where the reference is nearly black: the short block's front face
    // looks out of the open box (about 1% of the mean). Such points (below kDarkShare of the
    // mean reference) are held to an absolute error instead: kDarkError of the mean.
    constexpr double kDarkShare = 0.05, kDarkError = 0.05;
    double mean_ref = 0.0;
    for (size_t i = 0; i < points.size(); ++i) {
        const glm::vec3 e_ref =
            sh::irradiance(ref.file.volumes[i].probe(0), sh::Order::L2, points[i].normal);
        mean_ref += double(e_ref.x + e_ref.y + e_ref.z) / double(points.size());
    }
    struct Outliers {
        int count = 0;          // bright points outside [kLow, kHigh] x path
        int dark = 0;           // dark points
        double darkError = 0.0; // largest |E - E_ref| / mean at dark points
        double darkest = kHigh;
        double brightest = 0.0;
    };
    const auto outliers = [&](const runtime::VolumeSet& set, float offset) {
        Outliers o;
        for (size_t i = 0; i < points.size(); ++i) {
            const glm::vec3 e = set.irradiance(points[i].position, points[i].normal, offset);
            const glm::vec3 e_ref =
                sh::irradiance(ref.file.volumes[i].probe(0), sh::Order::L2, points[i].normal);
            const double sum = double(e.x + e.y + e.z),
                         sum_ref = double(e_ref.x + e_ref.y + e_ref.z);
            if (sum_ref < kDarkShare * mean_ref) {
                ++o.dark;
                o.darkError = std::max(o.darkError, std::abs(sum - sum_ref) / mean_ref);
                continue;
            }
            const double ratio = sum / sum_ref;
            o.darkest = std::min(o.darkest, ratio);
            o.brightest = std::max(o.brightest, ratio);
            o.count += (ratio < kLow || ratio > kHigh) ? 1 : 0;
        }
        return o;
    };
    // [visibility][validity on / off], at the normal offset.
    Outliers with_offset[2][2];
    for (const bool visibility : {true, false}) {
        for (const bool validity_on : {true, false}) {
            BakeConfig grid;
            grid.path.samples = kGridSamples;
            grid.path.maxBounces = 64;
            grid.volumes = {boxVolume(scene.bounds.min, scene.bounds.max, glm::uvec3(8))};
            grid.dilate = validity_on;
            grid.visibility = visibility;
            grid.backfaceThreshold = validity_on ? BakeConfig{}.backfaceThreshold : 1.0f;
            const BakeResult r = bakeOrFail(scene, grid);
            const runtime::VolumeSet set(r.file.volumes);
            for (const float offset : {kNormalOffset, 0.0f}) {
                const Outliers o = outliers(set, offset);
                std::printf("[stability inside] visibility %-3s, validity and dilation %-3s (%llu "
                            "invalid probes), normal offset %.2f m: %d of %zu bright block-face "
                            "points outside [%.1f, %.1f] x path (range %.3f .. %.3f); %d dark "
                            "points within %.3f of the mean E\n",
                            visibility ? "on" : "off", validity_on ? "on" : "off",
                            static_cast<unsigned long long>(r.stats.invalidProbes), double(offset),
                            o.count, points.size() - size_t(o.dark), kLow, kHigh, o.darkest,
                            o.brightest, o.dark, o.darkError);
                if (offset > 0.0f) {
                    with_offset[visibility ? 0 : 1][validity_on ? 0 : 1] = o;
                }
            }
        }
    }
    // Without visibility, dilation keeps every bright face point within a factor of two.
    EXPECT_EQ(with_offset[1][0].count, 0);
    EXPECT_LE(with_offset[1][0].darkError, kDarkError);
    // With visibility the probes inside the block are hidden, so the two points of the short
    // block's front face that look out of the open box (cells whose other valid probes are all
    // on the dark, open side) take the dark probes alone: measured 0.28 x path at one and
    // 0.058 of the mean E at the other. Everything else stays within a factor of two.
    EXPECT_LE(with_offset[0][0].count, 1);
    EXPECT_LE(with_offset[0][0].darkError, 1.5 * kDarkError);
    EXPECT_GT(with_offset[0][0].darkest, 0.25);
    EXPECT_LE(with_offset[0][0].brightest, kHigh);
    // Without visibility, the black inside probes bleed into the faces unless validity hides
    // them (dilation); with visibility they are hidden either way.
    EXPECT_LT(with_offset[1][1].darkest, with_offset[1][0].darkest);
}

// ---------------------------------------------------------------------------------------------
// 5. Half storage under a very bright emitter: the Cornell light 10^5 times brighter puts
// coefficients far beyond binary16's 65504. A half bake must not fail after the work (issue 29,
// item 5) nor store an infinity: it stores that volume in float and warns, naming the volume,
// the value and the flag; its probes match the float bake's up to deringing's half margin.
TEST(StabilityHalf, BrightEmitterIsStoredInFloatWithAWarningNeverAnInfinity) {
    constexpr float kBoost = 1e5f;
    Scene scene = generatedScene("cornell");
    for (Material& m : scene.materials) {
        m.emission *= kBoost;
    }
    BakeConfig config;
    config.path.samples = 64;
    config.volumes = {
        boxVolume(glm::vec3(0.2f, 0.3f, 0.2f), glm::vec3(0.35f, 0.45f, 0.35f), glm::uvec3(2))};
    config.volumes[0].name = "bright";
    config.volumes[0].storage = Storage::Float16;
    const BakeResult half = bakeOrFail(scene, config);
    ASSERT_EQ(half.file.volumes.size(), 1u);
    EXPECT_EQ(half.file.volumes[0].desc.storage, Storage::Float32);
    std::string message;
    for (const std::string& w : half.warnings) {
        message += w.find("65504") != std::string::npos ? w : "";
    }
    std::printf("[stability half] half storage asked: %s\n", message.c_str());
    EXPECT_EQ(message.rfind("volume 'bright': SH coefficient ", 0), 0u) << message;
    EXPECT_NE(message.find("stored as float (--format float chooses it up front)"),
              std::string::npos)
        << message;

    config.volumes[0].storage = Storage::Float32;
    const BakeResult full = bakeOrFail(scene, config);
    float largest = 0.0f;
    for (size_t i = 0; i < full.file.volumes.at(0).probeCount(); ++i) {
        for (const glm::vec3& c : full.file.volumes[0].probe(i).rgb) {
            ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z));
            largest = std::max({largest, std::abs(c.x), std::abs(c.y), std::abs(c.z)});
        }
    }
    std::printf("[stability half] float storage: largest coefficient %.3g = %.0f x the half "
                "maximum, all finite\n",
                double(largest), double(largest / kHalfMax));
    EXPECT_GT(largest, kHalfMax);
    // The storage is settled before deringing, so the two files hold the same probes.
    for (size_t i = 0; i < full.file.volumes[0].probeCount(); ++i) {
        const sh::ShRgb a = half.file.volumes[0].probe(i);
        const sh::ShRgb b = full.file.volumes[0].probe(i);
        for (size_t k = 0; k < a.rgb.size(); ++k) {
            for (int c = 0; c < 3; ++c) {
                EXPECT_EQ(a.rgb[k][c], b.rgb[k][c]) << i << " " << k;
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 6. SH ringing: a scene of nothing but a 100 W/m^2 directional light and a sky of radiance
// 0.1 (E = 0.31 W/m^2 from every side). The exact irradiance is
// E(n) = 100 max(0, n . -d) + 0.1 pi; L2 SH of the delta dips to about -0.04 x 100 on the far
// side, below the sky, so the probe baked without deringing has negative irradiance. The bake's
// deringing (BakeConfig::dering, sh.hpp) must remove every negative value over a dense set of
// normals; its cost is the change in error against the exact answer, printed with the window's
// own relative change.
TEST(StabilityRinging, DeringingRemovesNegativeIrradianceAtAStatedCost) {
    constexpr float kSun = 100.0f;
    constexpr float kSky = 0.1f;
    constexpr int kTestNormals = 20000;
    Scene scene;
    scene.materials.push_back(Material{});
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
    sun.intensity = glm::vec3(kSun);
    scene.lights.push_back(sun);
    scene.environment.type = Environment::Type::Constant;
    scene.environment.constant = glm::vec3(kSky);

    BakeConfig config;
    config.path.samples = 4096;
    config.volumes = {boxVolume(glm::vec3(-0.5f), glm::vec3(0.5f), glm::uvec3(1))};
    config.dering = false;
    const BakeResult off = bakeOrFail(scene, config);
    config.dering = true;
    const BakeResult on = bakeOrFail(scene, config);
    ASSERT_EQ(off.file.volumes.size(), 1u);
    ASSERT_EQ(on.file.volumes.size(), 1u);
    const sh::ShRgb raw = off.file.volumes[0].probe(0);
    const sh::ShRgb stored = on.file.volumes[0].probe(0);
    // The bake stores exactly what deringing the raw probe gives.
    const sh::DeringResult dering = sh::deringIrradiance(raw, sh::Order::L2);
    EXPECT_EQ(stored, dering.sh);
    EXPECT_EQ(off.stats.deringedProbes, 0u);
    EXPECT_EQ(on.stats.deringedProbes, 1u);
    EXPECT_FLOAT_EQ(float(on.stats.deringMaxChange), dering.relativeChange);

    struct Figures {
        int negative = 0;
        double minimum = 0.0;
        double relError = 0.0;
    };
    const auto figures = [&](const sh::ShRgb& s) {
        Figures f;
        double num = 0.0, den = 0.0;
        for (int k = 0; k < kTestNormals; ++k) {
            const glm::vec3 n = sh::fibonacciDirection(k, kTestNormals);
            const double e = sh::irradiance(s, sh::Order::L2, n).y;
            const double exact = kSun * std::max(0.0f, glm::dot(n, -sun.direction)) +
                                 double(kSky) * 3.14159265358979;
            f.negative += e < 0.0 ? 1 : 0;
            f.minimum = std::min(f.minimum, e);
            num += (e - exact) * (e - exact);
            den += exact * exact;
        }
        f.relError = std::sqrt(num / den);
        return f;
    };
    const Figures before = figures(raw);
    const Figures after = figures(stored);
    std::printf("[stability ringing] without deringing: %d of %d normals negative (min %.3f "
                "W/m^2), rel RMSE vs exact %.4f; with: %d negative (min %.3g), rel RMSE %.4f "
                "(cost %+.4f; window s1 %.4f s2 %.4f changes E by %.3f RMS)\n",
                before.negative, kTestNormals, before.minimum, before.relError, after.negative,
                after.minimum, after.relError, after.relError - before.relError,
                double(dering.band1Scale.y), double(dering.band2Scale.y),
                double(dering.relativeChange));
    EXPECT_GT(before.negative, 0);
    EXPECT_EQ(after.negative, 0);
    // Measured: the least-change window that lifts the -3.6 W/m^2 dip (s1 0.869, s2 0.918)
    // changes E by 0.097 RMS and raises the error against the exact answer from 0.088 to 0.131
    // (Sloan's window, used before: 0.41 and 0.42). The bounds catch a window that smooths more
    // than it must.
    constexpr double kMaxRelativeChange = 0.12;
    constexpr double kMaxRelError = 0.15;
    EXPECT_LT(dering.relativeChange, kMaxRelativeChange);
    EXPECT_LT(after.relError, kMaxRelError);
}

} // namespace
} // namespace probekit::baker
