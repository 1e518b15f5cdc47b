// Light modes (docs/baking.md#light-modes): a light in mode indirect leaves exactly its direct
// light out of the probes, mode none bakes the scene without it, and emissive surfaces in mode
// indirect leave out their direct radiance and nothing else.
//
// The exact tests bake twice with the same seed: every random number of a path bake derives from
// (seed, volume, probe, sample) and a light's direct light at a probe is a delta projected
// without sampling (its one shadow ray draws nothing), so the two bakes differ by the projected
// delta of each unshadowed light and by float rounding only.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/config.hpp"
#include "probekit/baker/light_visibility.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/sh.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit {
namespace {

using baker::LightMode;

// The generated Cornell box (its ceiling emitter) and a point light named "key" low in the left
// of the room, so that the blocks shadow part of the grid from it.
baker::Scene cornellWithKeyLight() {
    baker::Scene scene = test::generatedScene("cornell");
    PunctualLight key;
    key.type = LightType::Point;
    key.name = "key";
    key.position = glm::vec3(0.45f, 0.12f, 0.05f);
    key.intensity = glm::vec3(0.4f, 0.3f, 0.2f);
    scene.lights.push_back(key);
    return scene;
}

// A 4x4x4 float bake over the room, nothing done to the probes after tracing (no deringing, no
// relocation, no dilation), so each stored probe is the integrator's estimate at its position.
baker::BakeConfig rawConfig(uint32_t samples, uint64_t seed) {
    baker::BakeConfig c = test::sceneVolume(samples, glm::uvec3(4));
    c.volumes[0].bounds.padding = 0.0f;
    c.volumes[0].storage = Storage::Float32;
    c.seed = seed;
    c.dering = false;
    c.relocate = false;
    c.dilate = false;
    c.visibility = false;
    return c;
}

Volume bakeVolume(const baker::Scene& scene, const baker::BakeConfig& config) {
    Result<baker::BakeResult> r = baker::bake(scene, config, test::onThreads(2));
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    return r.ok() ? r.value().file.volumes.at(0) : Volume{};
}

// The light's direct light at `p` as the probe holds it: its delta projected, or nothing when
// the scene shadows it.
sh::ShRgb shadowedDelta(const baker::RayTracer& tracer, const PunctualLight& light, glm::vec3 p) {
    const std::optional<LightDirection> to = directionToLight(light, p);
    if (!to || tracer.occluded(p, to->direction, to->distance)) {
        return sh::ShRgb{};
    }
    return sh::projectDelta(to->direction, normalIrradianceAt(light, p), sh::Order::L2);
}

float largestCoefficient(const sh::ShRgb& a) {
    float m = 0.0f;
    for (int k = 0; k < 9; ++k) {
        for (int c = 0; c < 3; ++c) {
            m = std::max(m, std::abs(a.rgb[k][c]));
        }
    }
    return m;
}

struct SampleStatistics {
    double mean, variance, standardError; // unbiased variance; standard error of the mean
};

SampleStatistics sampleStatistics(const std::vector<double>& x) {
    const double n = double(x.size());
    double mean = 0.0, var = 0.0;
    for (double v : x) {
        mean += v / n;
    }
    for (double v : x) {
        var += (v - mean) * (v - mean) / (n - 1.0);
    }
    return {mean, var, std::sqrt(var / n)};
}

constexpr std::array<glm::vec3, 6> kAxes = {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0),
                                            glm::vec3(0, 1, 0), glm::vec3(0, -1, 0),
                                            glm::vec3(0, 0, 1), glm::vec3(0, 0, -1)};

} // namespace

// Same seed: baked - indirect is, probe by probe and coefficient by coefficient, the key light's
// shadowed delta, to float rounding (a relative 1e-5 of the probe's largest coefficient: the
// estimates are sums of a few hundred float samples). So E_indirect(n) + E_direct(n) = E_baked(n)
// for every normal, with the light's direct irradiance shadowed.
TEST(LightModes, IndirectPointLightPlusItsShadowedDirectLightIsTheBakedBake) {
    const baker::Scene scene = cornellWithKeyLight();
    const baker::BakeConfig baked = rawConfig(256, 5);
    baker::BakeConfig indirect = baked;
    indirect.lights.perLight = {{"key", LightMode::Indirect}};
    const Volume a = bakeVolume(scene, baked);
    const Volume b = bakeVolume(scene, indirect);
    ASSERT_EQ(a.desc.probeCount(), 64u);
    ASSERT_EQ(b.desc.probeCount(), 64u);
    auto tracer = baker::RayTracer::create(scene);
    ASSERT_TRUE(tracer.ok());
    size_t lit = 0, shadowed = 0;
    for (size_t i = 0; i < a.desc.probeCount(); ++i) {
        if (a.validity[i] == 0) {
            continue;
        }
        const glm::vec3 p = a.desc.grid.probeWorld(a.desc.grid.probeCoords(i));
        const sh::ShRgb delta = shadowedDelta(*tracer.value(), scene.lights.back(), p);
        (largestCoefficient(delta) > 0.0f ? lit : shadowed) += 1;
        const sh::ShRgb pa = a.probe(i), pb = b.probe(i);
        const float tol = 1e-5f * largestCoefficient(pa);
        for (int k = 0; k < 9; ++k) {
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(pa.rgb[k][c] - pb.rgb[k][c], delta.rgb[k][c], tol)
                    << "probe " << i << " coefficient " << k << " channel " << c;
            }
        }
        for (const glm::vec3& n : kAxes) {
            const glm::vec3 ea = sh::irradiance(pa, sh::Order::L2, n);
            const glm::vec3 sum =
                sh::irradiance(pb, sh::Order::L2, n) + sh::irradiance(delta, sh::Order::L2, n);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(sum[c], ea[c], 1e-4f * std::max(1e-3f, std::abs(ea[c])));
            }
        }
    }
    std::printf("light modes, same seed: %zu probes lit by the key light, %zu shadowed\n", lit,
                shadowed);
    // The test means something only if both kinds of probe occur.
    EXPECT_GE(lit, 8u);
    EXPECT_GE(shadowed, 4u);
}

// Different seeds: the same identity holds in expectation. Per probe and axis normal, d =
// E_indirect + E_direct - E_baked is the difference of two independent estimates; its mean over
// the probes must lie within 4 standard errors (the spread of d over the probes / sqrt(count)).
TEST(LightModes, IndirectPlusDirectMatchesBakedWithinTheNoiseAcrossSeeds) {
    const baker::Scene scene = cornellWithKeyLight();
    baker::BakeConfig indirect = rawConfig(256, 11);
    indirect.lights.punctual = LightMode::Indirect;
    const Volume a = bakeVolume(scene, rawConfig(256, 5));
    const Volume b = bakeVolume(scene, indirect);
    auto tracer = baker::RayTracer::create(scene);
    ASSERT_TRUE(tracer.ok());
    std::vector<double> d;
    double scale = 0.0;
    for (size_t i = 0; i < a.desc.probeCount(); ++i) {
        if (a.validity[i] == 0 || b.validity[i] == 0) {
            continue;
        }
        const glm::vec3 p = a.desc.grid.probeWorld(a.desc.grid.probeCoords(i));
        const sh::ShRgb delta = shadowedDelta(*tracer.value(), scene.lights.back(), p);
        for (const glm::vec3& n : kAxes) {
            const float ea = sh::irradiance(a.probe(i), sh::Order::L2, n).y;
            d.push_back(sh::irradiance(b.probe(i), sh::Order::L2, n).y +
                        sh::irradiance(delta, sh::Order::L2, n).y - ea);
            scale += double(ea) * ea;
        }
    }
    ASSERT_GT(d.size(), 200u);
    const auto [mean, var, se] = sampleStatistics(d);
    std::printf("light modes, two seeds: %zu differences, mean %.3g W/m2, standard error %.3g, "
                "RMS difference / RMS E %.4f\n",
                d.size(), mean, se, std::sqrt(var) / std::sqrt(scale / double(d.size())));
    EXPECT_LT(std::abs(mean), 4.0 * se) << "mean " << mean << " standard error " << se;
    // And the noise itself is small next to the light: the RMS difference under 10% of the RMS
    // irradiance, so the check above is not passing on a meaningless spread.
    EXPECT_LT(std::sqrt(var), 0.1 * std::sqrt(scale / double(d.size())));
}

// Mode none bakes the scene without the light: the same bytes as removing it by hand, found by
// name and by glTF index.
TEST(LightModes, NoneIsTheSceneWithoutTheLight) {
    const baker::Scene scene = cornellWithKeyLight();
    baker::Scene without = scene;
    without.lights.pop_back();
    const Volume expected = bakeVolume(without, rawConfig(64, 3));
    for (const char* key : {"key", "0"}) {
        baker::BakeConfig none = rawConfig(64, 3);
        none.lights.perLight = {{key, LightMode::None}};
        const Volume got = bakeVolume(scene, none);
        EXPECT_EQ(got.texelsF32, expected.texelsF32) << "per_light key " << key;
    }
}

// Emissive surfaces in mode indirect: what the probe loses is the emitter's direct radiance.
// Its DC coefficient is Y00 L Omega exactly in expectation (Omega the solid angle the emitter
// subtends, L its radiance), checked at probes under an unoccluded emissive square over a grey
// floor; per probe the relative deviation is Monte Carlo noise, so the mean over the probes must
// lie within 4 standard errors of 0 and the spread be small.
TEST(LightModes, EmissiveIndirectLeavesOutTheEmittersDirectRadiance) {
    baker::Scene scene = test::emptyScene();
    const glm::vec3 emission(2.0f, 1.0f, 0.5f);
    const uint32_t lamp = test::addMaterial(scene, glm::vec3(0.0f), emission);
    const uint32_t floor = test::addMaterial(scene, glm::vec3(0.5f), glm::vec3(0.0f));
    auto quad = [&](std::array<glm::vec3, 4> q, uint32_t material) {
        const uint32_t base = uint32_t(scene.positions.size());
        for (const glm::vec3& p : q) {
            scene.positions.push_back(p);
            scene.uvs.push_back(glm::vec2(0.0f));
        }
        for (const glm::uvec3 t : {glm::uvec3(0, 1, 2), glm::uvec3(0, 2, 3)}) {
            scene.triangles.push_back(t + base);
            scene.triangleMaterial.push_back(material);
            scene.triangleNode.push_back(-1);
        }
    };
    const std::array<glm::vec3, 4> lampQuad = {glm::vec3(-0.5f, 2, -0.5f),
                                               glm::vec3(0.5f, 2, -0.5f), glm::vec3(0.5f, 2, 0.5f),
                                               glm::vec3(-0.5f, 2, 0.5f)};
    quad(lampQuad, lamp);
    quad({glm::vec3(-3, 0, -3), glm::vec3(-3, 0, 3), glm::vec3(3, 0, 3), glm::vec3(3, 0, -3)},
         floor);
    scene.bounds = {glm::vec3(-3, 0, -3), glm::vec3(3, 2, 3)};
    std::vector<glm::vec3> points;
    for (int i = 0; i < 16; ++i) {
        points.push_back(glm::vec3(-0.9f + 0.12f * i, 0.4f + 0.07f * i, 0.3f - 0.04f * i));
    }
    baker::BakeConfig baked = test::probesAt(points, 0.01f);
    baked.path.samples = 1024;
    baked.dering = false;
    baked.relocate = false;
    baked.visibility = false;
    baker::BakeConfig indirect = baked;
    indirect.lights.emissive = LightMode::Indirect;
    Result<baker::BakeResult> a = baker::bake(scene, baked, test::onThreads(2));
    Result<baker::BakeResult> b = baker::bake(scene, indirect, test::onThreads(2));
    ASSERT_TRUE(a.ok() && b.ok());
    // Van Oosterom-Strackee: the solid angle of triangle (r1, r2, r3) seen from the origin.
    auto triangleSolidAngle = [](glm::dvec3 r1, glm::dvec3 r2, glm::dvec3 r3) {
        const double l1 = glm::length(r1), l2 = glm::length(r2), l3 = glm::length(r3);
        const double num = glm::dot(r1, glm::cross(r2, r3));
        const double den =
            l1 * l2 * l3 + glm::dot(r1, r2) * l3 + glm::dot(r1, r3) * l2 + glm::dot(r2, r3) * l1;
        return 2.0 * std::abs(std::atan2(num, den));
    };
    std::vector<double> rel;
    for (size_t i = 0; i < points.size(); ++i) {
        std::array<glm::dvec3, 4> r;
        for (int k = 0; k < 4; ++k) {
            r[k] = glm::dvec3(lampQuad[k]) - glm::dvec3(points[i]);
        }
        const double omega =
            triangleSolidAngle(r[0], r[1], r[2]) + triangleSolidAngle(r[0], r[2], r[3]);
        const double expected = 0.2820947917738781 * emission.x * omega;
        const double lost = a.value().file.volumes[i].probe(0).rgb[0][0] -
                            b.value().file.volumes[i].probe(0).rgb[0][0];
        rel.push_back(lost / expected - 1.0);
    }
    const auto [mean, var, se] = sampleStatistics(rel);
    std::printf("emissive indirect: DC lost / Y00 L Omega - 1 over %zu probes: mean %.4f, "
                "standard error %.4f, spread %.4f\n",
                rel.size(), mean, se, std::sqrt(var));
    EXPECT_LT(std::abs(mean), 4.0 * se + 1e-4) << "mean relative deviation " << mean;
    EXPECT_LT(std::sqrt(var), 0.05) << "spread of the per-probe deviation";
}

// A per_light key no light has is an error naming the field and listing the scene's lights; an
// indirect light with lpv's propagated direct light is refused, with traced direct light taken.
TEST(LightModes, ConfigErrorsNameTheFieldAndTheLights) {
    const baker::Scene scene = cornellWithKeyLight();
    baker::BakeConfig c = rawConfig(16, 1);
    c.lights.perLight = {{"fill", LightMode::Indirect}};
    Result<baker::BakeResult> r = baker::bake(scene, c, test::onThreads(1));
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("lights.per_light.\"fill\""), std::string::npos)
        << r.error().message;
    EXPECT_NE(r.error().message.find("0 'key'"), std::string::npos) << r.error().message;

    baker::BakeConfig lpv = test::methodVolume(baker::Method::Lpv, glm::uvec3(4));
    lpv.lights.punctual = LightMode::Indirect;
    lpv.lpv.direct = baker::LpvDirect::Propagated;
    r = baker::bake(scene, lpv, test::onThreads(1));
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("lpv.direct traced"), std::string::npos) << r.error().message;

    Result<baker::BakeConfig> parsed = baker::parseBakeConfig(
        R"({"lights": {"mode": "indirect", "per_light": {"key": "bright"}}})", "c.json");
    ASSERT_FALSE(parsed.ok());
    EXPECT_NE(parsed.error().message.find("lights.per_light.key"), std::string::npos)
        << parsed.error().message;
}

} // namespace probekit

namespace probekit {

// baker::lightVisibility, the shadows `probekit render --direct-light` applies: a point light
// 2 m above a floor, a 1 m square roof 1 m above the floor under it, and a sun straight down.
// Floor points under the roof (|x|, |z| < 0.5 - margin) see neither; points outside the roof's
// shadow from the point light (its shadow on the floor spans |x|, |z| < 1) see both; a point with
// its normal turned away sees nothing; a point with no surface (zero normal) gets mask 0.
TEST(LightModes, LightVisibilityTracesEachLightsShadow) {
    baker::Scene scene = test::emptyScene();
    const uint32_t grey = test::addMaterial(scene, glm::vec3(0.5f), glm::vec3(0.0f));
    auto quad = [&](float y, float half) {
        const uint32_t base = uint32_t(scene.positions.size());
        for (const glm::vec2 c :
             {glm::vec2(-1, -1), glm::vec2(1, -1), glm::vec2(1, 1), glm::vec2(-1, 1)}) {
            scene.positions.push_back(glm::vec3(half * c.x, y, half * c.y));
            scene.uvs.push_back(glm::vec2(0.0f));
        }
        for (const glm::uvec3 t : {glm::uvec3(0, 1, 2), glm::uvec3(0, 2, 3)}) {
            scene.triangles.push_back(t + base);
            scene.triangleMaterial.push_back(grey);
            scene.triangleNode.push_back(-1);
        }
    };
    quad(0.0f, 4.0f); // floor
    quad(1.0f, 0.5f); // roof
    scene.bounds = {glm::vec3(-4, 0, -4), glm::vec3(4, 1, 4)};
    PunctualLight point;
    point.type = LightType::Point;
    point.position = glm::vec3(0, 2, 0);
    point.intensity = glm::vec3(1.0f);
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::vec3(0, -1, 0);
    sun.intensity = glm::vec3(1.0f);
    const std::vector<PunctualLight> lights = {point, sun};
    const glm::vec3 up(0, 1, 0);
    struct Case {
        baker::SurfacePoint p;
        uint32_t mask;
    };
    std::vector<Case> cases;
    for (float x : {-0.45f, 0.0f, 0.3f}) {
        cases.push_back({{glm::vec3(x, 0, 0.2f), up}, 0u});      // under the roof
        cases.push_back({{glm::vec3(x, 0, 1.2f), up}, 3u});      // beyond both shadows
        cases.push_back({{glm::vec3(0.7f, 0, x), up}, 2u});      // the point light's shadow only
        cases.push_back({{glm::vec3(x, 1, 0.2f), up}, 3u});      // on the roof
        cases.push_back({{glm::vec3(x, 0.99f, 0.2f), -up}, 0u}); // its underside
    }
    cases.push_back({{glm::vec3(3, 0, 3), glm::vec3(0.0f)}, 0u}); // no surface
    std::vector<baker::SurfacePoint> points;
    for (const Case& c : cases) {
        points.push_back(c.p);
    }
    Result<std::vector<uint32_t>> masks = baker::lightVisibility(scene, points, lights, 2);
    ASSERT_TRUE(masks.ok()) << masks.error().message;
    for (size_t i = 0; i < cases.size(); ++i) {
        EXPECT_EQ(masks.value()[i], cases[i].mask)
            << "point " << i << " at (" << points[i].position.x << ", " << points[i].position.y
            << ", " << points[i].position.z << ")";
    }
    EXPECT_FALSE(baker::lightVisibility(scene, points, std::vector<PunctualLight>(33, point)).ok());
}

} // namespace probekit
