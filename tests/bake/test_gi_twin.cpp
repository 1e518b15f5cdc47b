// The dynamic GI's CPU twin (runtime/src/gi_twin.hpp) against the offline LPV it rebuilds
// (baker/src/methods/lpv.hpp) and against the path reference: the same transport on the same grid,
// the relit cascade after a sun move, and how far the runtime's light is from the path method's.
#include <cmath>
#include <cstdio>
#include <span>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "gi_twin.hpp"
#include "methods/lpv.hpp"
#include "methods/lpv_method.hpp"
#include "methods/path_integrator.hpp"
#include "probekit/baker/generators.hpp"
#include "trace/ray_tracer.hpp"

using namespace probekit;
using namespace probekit::baker;
using namespace probekit::runtime;

namespace {

// A baker scene as the renderer's (and DynamicGi's) triangle arrays: three vertices per
// triangle, albedo sampled at the corners.
struct Triangles {
    std::vector<RenderVertex> vertices;
    std::vector<uint32_t> indices;
};
Triangles trianglesOf(const Scene& scene) {
    Triangles out;
    const glm::vec2 bary[3] = {{0.0f, 0.0f}, {1.0f, 0.0f}, {0.0f, 1.0f}};
    for (uint32_t t = 0; t < scene.triangles.size(); ++t) {
        const glm::uvec3 tri = scene.triangles[t];
        for (int k = 0; k < 3; ++k) {
            RenderVertex v;
            v.position = scene.positions[tri[k]];
            v.albedo = scene.albedoAt(t, bary[k]);
            out.indices.push_back(uint32_t(out.vertices.size()));
            out.vertices.push_back(v);
        }
    }
    return out;
}

// A cube of n^3 cells around the scene's bounds, one cell of margin on every side.
GiCascadeLayout cubeAround(const grid::Aabb& bounds, int n) {
    const glm::vec3 size = bounds.max - bounds.min;
    const float longest = std::max({size.x, size.y, size.z});
    GiCascadeLayout l;
    l.cells = n;
    l.cellSize = longest / float(n - 2);
    l.origin = 0.5f * (bounds.min + bounds.max) - 0.5f * float(n) * l.cellSize;
    return l;
}

LpvCascadeLayout offlineLayout(const GiCascadeLayout& l) {
    LpvCascadeLayout o;
    o.origin = l.origin;
    o.cellSize = l.cellSize;
    o.cells = glm::ivec3(l.cells);
    return o;
}

// The offline LPV method's settings on a 32-cell grid.
LpvConfig offlineConfig(uint32_t iterations) {
    LpvConfig lpv;
    lpv.grid = 32;
    lpv.iterations = iterations;
    return lpv;
}

// The offline LPV method's cascade on `layout`: its lights (VPLs of every bounce, escape rays;
// seed 1) propagated on the same grid as the twin's.
LpvCascades offlineCascade(const Scene& scene, const LpvConfig& lpv,
                           const GiCascadeLayout& layout) {
    const std::unique_ptr<RayTracer> tracer = std::move(RayTracer::create(scene).value());
    VolumeDesc desc;
    desc.grid = grid::GridLayout(scene.bounds, glm::uvec3(4), grid::PositionMode::Center);
    const LpvLights lights = prepareLpvLights(scene, *tracer, lpv, {desc}, 1, 2);
    return LpvCascades(scene, lights.injection, {offlineLayout(layout)}, resolveLpvSettings(lpv),
                       2);
}

// Irradiance (all channels) of L1 radiance at the six axis normals.
std::array<glm::vec3, 6> axisIrradiance(const sh::ShRgb& radiance) {
    static const std::array<glm::vec3, 6> normals = {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0),
                                                     glm::vec3(0, 1, 0), glm::vec3(0, -1, 0),
                                                     glm::vec3(0, 0, 1), glm::vec3(0, 0, -1)};
    std::array<glm::vec3, 6> e{};
    for (int d = 0; d < 6; ++d) {
        e[size_t(d)] = sh::irradiance(radiance, sh::Order::L1, normals[size_t(d)]);
    }
    return e;
}

// Relative RMS difference of the axis irradiances of a against b over points:
// sqrt(sum |E_a - E_b|^2 / sum |E_b|^2).
double relativeRms(const std::vector<sh::ShRgb>& a, const std::vector<sh::ShRgb>& b) {
    double diff = 0.0;
    double ref = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
        const auto ea = axisIrradiance(a[i]);
        const auto eb = axisIrradiance(b[i]);
        for (int d = 0; d < 6; ++d) {
            const glm::dvec3 delta = glm::dvec3(ea[size_t(d)]) - glm::dvec3(eb[size_t(d)]);
            diff += glm::dot(delta, delta);
            ref += glm::dot(glm::dvec3(eb[size_t(d)]), glm::dvec3(eb[size_t(d)]));
        }
    }
    return std::sqrt(diff / ref);
}

// relativeRms, over `points`, of the twin's radiance from the `relit` fields and from the
// `stale` ones against the offline LPV's.
struct TwinVsOffline {
    double relit;
    double stale;
};

TwinVsOffline twinVsOffline(std::span<const GiCascadeLayout> layouts,
                            std::span<const GiField> relit, std::span<const GiField> stale,
                            const LpvCascades& offline, const std::vector<glm::vec3>& points) {
    std::vector<sh::ShRgb> twin_relit, twin_stale, offline_lpv;
    for (const glm::vec3& p : points) {
        twin_relit.push_back(giSampleRadiance(layouts, relit, 0.0f, false, p));
        twin_stale.push_back(giSampleRadiance(layouts, stale, 0.0f, false, p));
        offline_lpv.push_back(offline.radiance(p));
    }
    return {relativeRms(twin_relit, offline_lpv), relativeRms(twin_stale, offline_lpv)};
}

// Points on a lattice inside the courtyard's open interior (x, z in -7..7, y in 0.5..4.5).
std::vector<glm::vec3> courtyardPoints() {
    std::vector<glm::vec3> p;
    for (int x = 0; x < 8; ++x) {
        for (int y = 0; y < 4; ++y) {
            for (int z = 0; z < 8; ++z) {
                p.emplace_back(-7.0f + 2.0f * float(x), 0.5f + 1.33f * float(y),
                               -7.0f + 2.0f * float(z));
            }
        }
    }
    return p;
}

} // namespace

// The twin's transport is the offline LPV's: from the same injected intensities, on the same
// 32^3 grid, 24 steps give the same radiance. In free space they differ only in summation
// order (measured 1.7e-7 of the largest coefficient; bound 1e-5). Through the thin-wall scene's
// geometry the blocking is rounded too: the twin sums it in fixed point at 2^-16 per area
// sample, the offline volume in float, which moves a face's blocking by up to about 1e-4 and
// the radiance by the 2.6e-4 of the largest coefficient measured (bound 1e-3).
struct PropagationCase {
    bool occlusion;
    float bound;
};
class GiTwinPropagation : public ::testing::TestWithParam<PropagationCase> {};

TEST_P(GiTwinPropagation, MatchesTheOfflineLpv) {
    const Scene scene = test::generatedScene("thin-wall");
    const Scene empty;
    const Triangles tris = trianglesOf(GetParam().occlusion ? scene : empty);
    const GiCascadeLayout layout = cubeAround(scene.bounds, 32);
    const LpvCascadeLayout offline = offlineLayout(layout);
    const std::vector<GiGeometryCell> geometry =
        buildGiGeometry(layout, tris.vertices, tris.indices);

    // Injected light: beams of assorted directions and colours in cells on both sides of the
    // wall.
    GiField twin_field(giCellCount(layout));
    LpvField offline_field(offline.cellCount());
    for (int i = 0; i < 24; ++i) {
        const glm::ivec3 c(3 + (i * 7) % 26, 2 + (i * 5) % 10, 4 + (i * 11) % 24);
        const Sh1Rgb beam = beamSh(sh::fibonacciDirection(i, 24),
                                   glm::vec3(1.0f + 0.1f * float(i % 3), 0.5f, 0.2f));
        offline_field.add(offline.index(c), beam);
        for (int k = 0; k < 4; ++k) {
            for (int ch = 0; ch < 3; ++ch) {
                twin_field.at(giCellIndex(layout, c), k, ch) += beam.c[size_t(k)][ch];
            }
        }
    }
    constexpr uint32_t kIterations = 24;
    LpvSettings settings;
    settings.occlusion = GetParam().occlusion;
    const LpvTransfer transfer = buildLpvTransfer(scene, offline, settings);
    const std::vector<Sh1Rgb> expected =
        propagateToRadiance(offline, transfer, offline_field, kIterations, 2);

    GiField current = twin_field;
    GiField next;
    std::vector<float> crossing(18 * giCellCount(layout), 0.0f);
    glm::vec3 scale(1.0f);
    for (uint32_t it = 0; it < kIterations; ++it) {
        scale = giPropagateStep(layout, geometry, 1.0f, current, scale, next, crossing);
        std::swap(current, next);
    }
    GiField radiance(giCellCount(layout));
    giResolve(layout, crossing, radiance);

    float largest = 0.0f;
    float worst = 0.0f;
    for (size_t i = 0; i < expected.size(); ++i) {
        for (int k = 0; k < 4; ++k) {
            for (int ch = 0; ch < 3; ++ch) {
                largest = std::max(largest, std::abs(expected[i].c[size_t(k)][ch]));
                worst =
                    std::max(worst, std::abs(expected[i].c[size_t(k)][ch] - radiance.at(i, k, ch)));
            }
        }
    }
    std::printf("twin vs offline propagation (occlusion %d): max |diff| / max |L| = %.3g\n",
                int(GetParam().occlusion), worst / largest);
    EXPECT_GT(largest, 0.0f);
    EXPECT_LT(worst, GetParam().bound * largest);
}

INSTANTIATE_TEST_SUITE_P(GiTwin, GiTwinPropagation,
                         ::testing::Values(PropagationCase{false, 1e-5f},
                                           PropagationCase{true, 1e-3f}));

// The accuracy check. The courtyard's sun moves from its own 50 degrees elevation,
// azimuth 30, to 35 degrees, azimuth -60; the twin relights its 32^3 cascade for the moved sun
// (geometry unchanged) and is compared, at 256 points of the open interior, with
//  (a) the offline LPV baked for the moved sun on the same grid (its cascade: VPLs of every
//      bounce, escape rays, the same transport), indirect light only;
//  (b) the path method's probes (4096 directions), with the runtime's direct sun (unshadowed
//      irradiance x the transmittance marched through the geometry volume) added to its
//      cascade, beside the offline LPV method's probes (traced direct + LPV) for scale.
// Each figure is the relative RMS difference of the irradiance at the six axis normals; the
// runtime does not reach the offline LPV's figures (numbers at the assertions).
TEST(GiTwinAccuracy, SunMoveAgreesWithTheOfflineLpvAndIsCloseToThePathReference) {
    Scene scene = test::generatedScene("courtyard");
    ASSERT_EQ(scene.lights.size(), 1u);
    const PunctualLight sun_before = scene.lights[0];
    PunctualLight sun_after = sun_before;
    {
        const float el = glm::radians(35.0f);
        const float az = glm::radians(-60.0f);
        sun_after.direction =
            -glm::vec3(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
    }
    scene.lights = {sun_after};

    const Triangles tris = trianglesOf(scene);
    const GiCascadeLayout layout = cubeAround(scene.bounds, 32);
    const std::vector<GiGeometryCell> geometry =
        buildGiGeometry(layout, tris.vertices, tris.indices);
    constexpr uint32_t kIterations = 32;
    GiCascadeInputs inputs;
    inputs.iterations = kIterations;
    inputs.bounces = 3;
    const std::array<PunctualLight, 1> before{sun_before};
    const std::array<PunctualLight, 1> after{sun_after};
    inputs.lights = before;
    const GiField stale = giUpdateCascade(layout, geometry, inputs);
    inputs.lights = after;
    const GiField relit = giUpdateCascade(layout, geometry, inputs);

    // (a) The offline LPV for the moved sun on the same grid: its cascade (indirect light).
    const LpvConfig lpv = offlineConfig(kIterations);
    const LpvCascades offline = offlineCascade(scene, lpv, layout);

    const std::vector<glm::vec3> points = courtyardPoints();
    const std::array<GiCascadeLayout, 1> layouts{layout};
    const std::array<GiField, 1> relit_fields{relit};
    const std::array<GiField, 1> stale_fields{stale};
    const auto [relit_vs_offline, stale_vs_offline] =
        twinVsOffline(layouts, relit_fields, stale_fields, offline, points);
    std::printf("indirect, twin vs offline LPV for the moved sun: relit %.3f, stale %.3f\n",
                relit_vs_offline, stale_vs_offline);

    // (b) Against the path reference: probes at the same points.
    BakeConfig config;
    VolumeConfig v;
    v.bounds.mode = BoundsMode::Custom;
    v.bounds.min = glm::vec3(-8.0f, -0.1667f, -8.0f);
    v.bounds.max = glm::vec3(8.0f, 5.1633f, 8.0f);
    v.resolution = glm::uvec3(8, 4, 8);
    v.storage = Storage::Float32;
    config.volumes = {v};
    config.path.samples = 4096;
    BakeOptions options;
    options.threads = 2;
    const Result<BakeResult> path = bake(scene, config, options);
    ASSERT_TRUE(path.ok()) << path.error().message;
    config.path.maxBounces = 0;
    const Result<BakeResult> direct = bake(scene, config, options);
    ASSERT_TRUE(direct.ok()) << direct.error().message;
    config.path.maxBounces = PathConfig{}.maxBounces;
    config.method = Method::Lpv;
    config.lpv = lpv;
    config.lpv.directSamples = 4096;
    const Result<BakeResult> lpv_bake = bake(scene, config, options);
    ASSERT_TRUE(lpv_bake.ok()) << lpv_bake.error().message;
    const Volume& path_volume = path.value().file.volumes[0];
    const Volume& lpv_volume = lpv_bake.value().file.volumes[0];
    const Volume& direct_volume = direct.value().file.volumes[0];
    std::vector<sh::ShRgb> reference, runtime_total, offline_total;
    std::vector<sh::ShRgb> path_indirect, runtime_indirect, offline_indirect, runtime_exact;
    for (size_t i = 0; i < path_volume.probeCount(); ++i) {
        const glm::vec3 p = path_volume.desc.grid.probeWorld(path_volume.desc.grid.probeCoords(i));
        sh::ShRgb path_l1 = path_volume.probe(i);
        sh::ShRgb lpv_l1 = lpv_volume.probe(i);
        sh::ShRgb direct_l1 = direct_volume.probe(i);
        for (int k = 4; k < 9; ++k) {
            path_l1.rgb[size_t(k)] = glm::vec3(0.0f);
            lpv_l1.rgb[size_t(k)] = glm::vec3(0.0f);
            direct_l1.rgb[size_t(k)] = glm::vec3(0.0f);
        }
        sh::ShRgb indirect = direct_l1;
        indirect *= -1.0f;
        indirect += path_l1;
        path_indirect.push_back(indirect);
        const sh::ShRgb cascade = giSampleRadiance(layouts, relit_fields, 0.0f, false, p);
        runtime_indirect.push_back(cascade);
        offline_indirect.push_back(offline.radiance(p));
        sh::ShRgb exact = cascade;
        exact += direct_l1;
        runtime_exact.push_back(exact);
        reference.push_back(path_l1);
        offline_total.push_back(lpv_l1);
        // The runtime's direct sun as radiance SH whose L1 irradiance is the shadowed sun's:
        // a beam of radiance from the sun's direction, E_facing x transmittance.
        const glm::vec3 to_sun = -glm::normalize(sun_after.direction);
        const float t = giTransmittance(layout, geometry, p, to_sun,
                                        std::numeric_limits<float>::infinity(), glm::ivec3(-1));
        sh::ShRgb total = giSampleRadiance(layouts, relit_fields, 0.0f, false, p);
        const sh::Coeffs y = sh::evalBasis(to_sun);
        for (int k = 0; k < 4; ++k) {
            total.rgb[size_t(k)] += (t * y[size_t(k)]) * sun_after.intensity;
        }
        runtime_total.push_back(total);
    }
    const double indirect_runtime = relativeRms(runtime_indirect, path_indirect);
    const double indirect_offline = relativeRms(offline_indirect, path_indirect);
    const double total_exact_direct = relativeRms(runtime_exact, reference);
    const double total_marched = relativeRms(runtime_total, reference);
    const double total_offline = relativeRms(offline_total, reference);
    std::printf("indirect against the path's: runtime cascade %.3f, offline LPV cascade %.3f\n"
                "total against the path: runtime with exact direct %.3f, with the marched sun "
                "%.3f; offline LPV method %.3f\n",
                indirect_runtime, indirect_offline, total_exact_direct, total_marched,
                total_offline);
    // Deterministic (fixed seeds); the bounds leave room for float differences between
    // platforms. Measured: relit 0.326 and stale 0.821 from the offline cascade; indirect 0.488
    // (offline cascade 0.362) and total 0.198 with exact direct (offline LPV method 0.139) from
    // the path. More bounces (5) or iterations (64) change these by less than 0.01: what is
    // left is the injection (the grid-marched sun and one element per geometry cell against
    // the offline VPLs of exact visibility) and the 0.55 m cells.
    EXPECT_LT(relit_vs_offline, 0.40);
    EXPECT_GT(stale_vs_offline, 2.0 * relit_vs_offline);
    EXPECT_LT(indirect_runtime, 0.60);
    EXPECT_LT(total_exact_direct, 0.25);
    EXPECT_LT(total_marched, 0.40);
}

// A point light moved in the thin-wall scene (from (-2, 1.8, -1) to (-3, 1.2, 0.5)): the twin
// relit for the moved light against the offline LPV cascade for it on the same 32^3 grid, at
// points of both rooms; and where the runtime fails, as the offline LPV's seeds warn: behind the
// 5 cm wall at 32^3 (cells of 0.27 m), the leak ratio (irradiance facing the wall, runtime or
// offline cascade over the path's indirect light) at points 0.3 m behind it, away from the
// doorway.
TEST(GiTwinAccuracy, PointLightMoveAndTheThinWall) {
    Scene scene = test::generatedScene("thin-wall");
    ASSERT_EQ(scene.lights.size(), 1u);
    const PunctualLight before = scene.lights[0];
    PunctualLight after = before;
    after.position = glm::vec3(-3.0f, 1.2f, 0.5f);
    scene.lights = {after};

    const Triangles tris = trianglesOf(scene);
    const GiCascadeLayout layout = cubeAround(scene.bounds, 32);
    const std::vector<GiGeometryCell> geometry =
        buildGiGeometry(layout, tris.vertices, tris.indices);
    GiCascadeInputs inputs;
    inputs.iterations = 32;
    inputs.bounces = 3;
    const std::array<PunctualLight, 1> lights_before{before};
    const std::array<PunctualLight, 1> lights_after{after};
    inputs.lights = lights_before;
    const std::array<GiField, 1> stale{giUpdateCascade(layout, geometry, inputs)};
    inputs.lights = lights_after;
    const std::array<GiField, 1> relit{giUpdateCascade(layout, geometry, inputs)};
    const std::array<GiCascadeLayout, 1> layouts{layout};

    const LpvConfig lpv = offlineConfig(32);
    const LpvCascades offline = offlineCascade(scene, lpv, layout);

    std::vector<glm::vec3> points;
    for (int x = 0; x < 8; ++x) {
        for (int y = 0; y < 3; ++y) {
            for (int z = 0; z < 4; ++z) {
                points.emplace_back(-3.5f + float(x), 0.5f + 0.75f * float(y), -1.5f + float(z));
            }
        }
    }
    const auto [relit_vs_offline, stale_vs_offline] =
        twinVsOffline(layouts, relit, stale, offline, points);
    std::printf("point light moved, twin vs offline LPV: relit %.3f, stale %.3f\n",
                relit_vs_offline, stale_vs_offline);

    // Behind the wall, at increasing distances.
    const std::array<float, 5> distances = {0.05f, 0.1f, 0.2f, 0.3f, 0.5f};
    std::vector<glm::vec3> behind;
    for (float d : distances) {
        for (int y = 0; y < 4; ++y) {
            for (int z = 0; z < 4; ++z) {
                behind.emplace_back(0.025f + d, 0.5f + 0.5f * float(y), -1.5f + 0.5f * float(z));
            }
        }
    }
    BakeConfig config = test::probesAt(behind, 0.01f);
    config.path.samples = 4096;
    BakeOptions options;
    options.threads = 2;
    const Result<BakeResult> path = bake(scene, config, options);
    ASSERT_TRUE(path.ok()) << path.error().message;
    const glm::vec3 facing(-1.0f, 0.0f, 0.0f);
    std::array<double, distances.size()> leak_runtime{}, leak_offline{};
    for (size_t k = 0; k < distances.size(); ++k) {
        double e_path = 0.0, e_twin = 0.0, e_offline = 0.0;
        for (size_t i = 16 * k; i < 16 * (k + 1); ++i) {
            // No direct light reaches behind the wall: the path's light there is all indirect.
            e_path +=
                sh::irradiance(path.value().file.volumes[i].probe(0), sh::Order::L1, facing).y;
            e_twin += sh::irradiance(giSampleRadiance(layouts, relit, 0.0f, false, behind[i]),
                                     sh::Order::L1, facing)
                          .y;
            e_offline += sh::irradiance(offline.radiance(behind[i]), sh::Order::L1, facing).y;
        }
        leak_runtime[k] = e_twin / e_path;
        leak_offline[k] = e_offline / e_path;
        std::printf("%.2f m behind the 5 cm wall at 32^3: leak ratio runtime %.2f, offline LPV "
                    "cascade %.2f\n",
                    double(distances[k]), leak_runtime[k], leak_offline[k]);
    }
    // Measured (deterministic seeds): relit 0.461, stale 0.637 from the offline cascade; leak
    // ratio 3.65 at 0.05 m, 1.42 at 0.1 m, 0.85-0.96 from 0.2 m on (offline cascade 6.20, 1.74,
    // 0.67-0.85): light leaks into the cell the wall shares, not beyond it.
    EXPECT_LT(relit_vs_offline, 0.55);
    EXPECT_GT(stale_vs_offline, relit_vs_offline + 0.1);
    EXPECT_LT(leak_runtime[0], 5.0);
    for (size_t k = 2; k < distances.size(); ++k) {
        EXPECT_GT(leak_runtime[k], 0.6) << distances[k];
        EXPECT_LT(leak_runtime[k], 1.3) << distances[k];
    }
}
