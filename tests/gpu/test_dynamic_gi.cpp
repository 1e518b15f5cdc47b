// DynamicGi (runtime/include/probekit/runtime/dynamic_gi.hpp): the compute stages against their
// CPU twin (runtime/src/gi_twin.hpp, gi_geometry.hpp), dirty tracking, cascade placement and
// timings, on whatever Vulkan device the machine has (lavapipe in CI).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "gi_geometry.hpp"
#include "gi_twin.hpp"
#include "gpu_test_support.hpp"
#include "probekit/runtime/dynamic_gi.hpp"

namespace probekit {
namespace {

using runtime::DynamicGi;
using runtime::DynamicGiSettings;
using runtime::GiCascadeLayout;
using runtime::GiGeometryCell;
using runtime::RenderVertex;

struct Mesh {
    std::vector<RenderVertex> vertices;
    std::vector<uint32_t> indices;

    void quad(glm::vec3 corner, glm::vec3 u, glm::vec3 v, glm::vec3 albedo) {
        const auto base = uint32_t(vertices.size());
        const glm::vec3 n = glm::normalize(glm::cross(u, v));
        for (const glm::vec3 p : {corner, corner + u, corner + u + v, corner + v}) {
            RenderVertex vertex;
            vertex.position = p;
            vertex.normal = n;
            vertex.albedo = albedo;
            vertices.push_back(vertex);
        }
        for (const uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) {
            indices.push_back(base + i);
        }
    }
};

// A 2 m room without a ceiling and with a window in its +x wall. The extents avoid multiples of
// the cell size (0.125 m) and of half of it, so that no wall lies on a geometry-cell boundary
// (where the GPU's and the CPU's last bit could pick different cells).
Mesh roomScene() {
    Mesh m;
    const glm::vec3 lo(-0.97f, 0.03f, -1.02f);
    const glm::vec3 hi(1.03f, 1.98f, 0.95f);
    const glm::vec3 size = hi - lo;
    const glm::vec3 grey(0.7f);
    m.quad(lo, glm::vec3(0, 0, size.z), glm::vec3(size.x, 0, 0), glm::vec3(0.6f, 0.5f, 0.4f));
    m.quad(lo, glm::vec3(0, size.y, 0), glm::vec3(0, 0, size.z), glm::vec3(0.8f, 0.2f, 0.2f));
    m.quad(lo, glm::vec3(size.x, 0, 0), glm::vec3(0, size.y, 0), grey);
    m.quad(glm::vec3(lo.x, lo.y, hi.z), glm::vec3(0, size.y, 0), glm::vec3(size.x, 0, 0), grey);
    // +x wall with a window between y 0.71..1.33 and z -0.41..0.37.
    const float x = hi.x;
    const float y0 = 0.71f, y1 = 1.33f, z0 = -0.41f, z1 = 0.37f;
    const glm::vec3 green(0.2f, 0.7f, 0.3f);
    m.quad(glm::vec3(x, lo.y, lo.z), glm::vec3(0, 0, size.z), glm::vec3(0, y0 - lo.y, 0), green);
    m.quad(glm::vec3(x, y1, lo.z), glm::vec3(0, 0, size.z), glm::vec3(0, hi.y - y1, 0), green);
    m.quad(glm::vec3(x, y0, lo.z), glm::vec3(0, 0, z0 - lo.z), glm::vec3(0, y1 - y0, 0), green);
    m.quad(glm::vec3(x, y0, z1), glm::vec3(0, 0, hi.z - z1), glm::vec3(0, y1 - y0, 0), green);
    return m;
}

std::vector<PunctualLight> sceneLights(float sun_turn = 0.0f) {
    PunctualLight sun;
    sun.type = LightType::Directional;
    const float a = 0.6f + sun_turn;
    sun.direction = glm::normalize(glm::vec3(-std::cos(a) * 0.5f, -1.0f, -std::sin(a) * 0.5f));
    sun.intensity = glm::vec3(3.0f, 2.8f, 2.4f);
    PunctualLight point;
    point.type = LightType::Point;
    point.position = glm::vec3(0.21f, 1.17f, 0.09f);
    point.intensity = glm::vec3(2.0f, 1.5f, 1.0f);
    point.range = 6.0f;
    return {sun, point};
}

// The sun turned by exactly `angle` radians from sceneLights() (about an axis perpendicular to
// its direction).
std::vector<PunctualLight> turnedSun(float angle) {
    std::vector<PunctualLight> lights = sceneLights();
    const glm::vec3 d = lights[0].direction;
    const glm::vec3 axis = glm::normalize(glm::cross(d, glm::vec3(1.0f, 0.0f, 0.0f)));
    lights[0].direction = d * std::cos(angle) + glm::cross(axis, d) * std::sin(angle);
    return lights;
}

sh::ShRgb sceneSky() {
    sh::ShRgb sky;
    sky.rgb[0] = glm::vec3(0.5f, 0.6f, 0.8f);
    sky.rgb[1] = glm::vec3(0.2f, 0.25f, 0.35f); // brighter from above (+y)
    sky.rgb[3] = glm::vec3(0.05f, 0.04f, 0.0f);
    sky.rgb[6] = glm::vec3(0.03f, 0.03f, 0.05f);
    return sky;
}

DynamicGiSettings roomSettings() {
    DynamicGiSettings s;
    s.cascades = 1;
    s.resolution = 32;
    s.cellSize = 0.125f;
    s.aheadFraction = 0.0f;
    return s;
}

GiCascadeLayout layoutOf(const runtime::GiCascadePlacement& p) {
    GiCascadeLayout l;
    l.origin = p.origin;
    l.cellSize = p.cellSize;
    l.cells = int(p.cells);
    return l;
}

std::vector<GiGeometryCell> toCells(const std::vector<int32_t>& ints) {
    std::vector<GiGeometryCell> cells(ints.size() / 17);
    std::memcpy(static_cast<void*>(cells.data()), ints.data(),
                cells.size() * sizeof(GiGeometryCell));
    return cells;
}

// roomScene(), built once: it outlives every DynamicGi that holds it.
const Mesh& roomMesh() {
    static const Mesh mesh = roomScene();
    return mesh;
}

// A DynamicGi over the room (roomMesh()), camera in the room's middle.
DynamicGi makeRoomGi(runtime::GpuContext& context, const DynamicGiSettings& settings) {
    const Mesh& mesh = roomMesh();
    Result<DynamicGi> gi = DynamicGi::create(context, settings);
    EXPECT_TRUE(gi) << (gi ? "" : gi.error().message);
    DynamicGi out = std::move(gi.value());
    EXPECT_TRUE(out.setGeometry(mesh.vertices, mesh.indices));
    const std::vector<PunctualLight> lights = sceneLights();
    EXPECT_TRUE(out.setLights(lights));
    out.setSky(sceneSky());
    out.setCamera(glm::vec3(0.05f, 1.0f, 0.0f), glm::vec3(0.0f, 0.0f, -1.0f));
    return out;
}

class DynamicGiTest : public gputest::GpuTest {};

TEST_F(DynamicGiTest, GeometryVolumeMatchesTwin) {
    const Mesh& mesh = roomMesh();
    DynamicGi gi = makeRoomGi(context(), roomSettings());
    Result<runtime::GiUpdateStats> stats = gi.update(0);
    ASSERT_TRUE(stats) << stats.error().message;
    EXPECT_TRUE(stats.value().geometryRebuilt);
    Result<std::vector<int32_t>> gpu = gi.readGeometry(0);
    ASSERT_TRUE(gpu) << gpu.error().message;
    const std::vector<GiGeometryCell> cpu =
        runtime::buildGiGeometry(layoutOf(gi.placements()[0]), mesh.vertices, mesh.indices);
    ASSERT_EQ(gpu.value().size(), 17 * cpu.size());
    std::vector<int32_t> cpu_ints(17 * cpu.size());
    std::memcpy(cpu_ints.data(), cpu.data(), cpu_ints.size() * sizeof(int32_t));
    size_t differing = 0;
    int64_t worst = 0;
    int64_t nonzero = 0;
    for (size_t i = 0; i < cpu_ints.size(); ++i) {
        const int64_t d = std::abs(int64_t(gpu.value()[i]) - int64_t(cpu_ints[i]));
        differing += d != 0 ? 1 : 0;
        worst = std::max(worst, d);
        nonzero += cpu_ints[i] != 0 ? 1 : 0;
    }
    std::printf("geometry: %zu of %lld non-zero ints differ, by at most %lld (fixed-point units "
                "of 2^-16)\n",
                differing, static_cast<long long>(nonzero), static_cast<long long>(worst));
    EXPECT_GT(nonzero, 1000);
    // A sample's float arithmetic may round one contribution differently on the GPU (the
    // division by the cell size, fused multiply-adds): a few ints off by one or two units.
    EXPECT_LE(worst, 2);
    EXPECT_LE(differing, size_t(nonzero / 100));
}

TEST_F(DynamicGiTest, RadianceMatchesTwinOnItsOwnGeometry) {
    DynamicGiSettings settings = roomSettings();
    settings.cascades = 2; // the second (0.25 m cells) holds the room in 8^3 of its cells
    settings.bounces = 2;
    settings.iterations = 8;
    DynamicGi gi = makeRoomGi(context(), settings);
    Result<runtime::GiUpdateStats> stats = gi.update(0);
    ASSERT_TRUE(stats) << stats.error().message;
    // Per cascade: the geometry volume and its keep factors, then per bounce surfaces, inject,
    // 8 propagate, 7 reduce and resolve.
    EXPECT_EQ(stats.value().dispatches, 2u * (2u + 2u * (2u + 8u + 7u + 1u)));
    const std::vector<PunctualLight> lights = sceneLights();
    const sh::ShRgb sky = sceneSky();
    for (uint32_t k = 0; k < settings.cascades; ++k) {
        Result<std::vector<int32_t>> geometry = gi.readGeometry(k);
        ASSERT_TRUE(geometry) << geometry.error().message;
        Result<std::vector<float>> gpu = gi.readRadiance(k);
        ASSERT_TRUE(gpu) << gpu.error().message;
        const std::vector<GiGeometryCell> cells = toCells(geometry.value());
        runtime::GiCascadeInputs inputs;
        inputs.lights = lights;
        inputs.sky = &sky;
        inputs.iterations = 8;
        inputs.bounces = 2;
        inputs.propagationWeight = settings.propagationWeight;
        const runtime::GiField twin =
            runtime::giUpdateCascade(layoutOf(gi.placements()[k]), cells, inputs);
        ASSERT_EQ(gpu.value().size(), twin.data.size());
        float peak = 0.0f;
        float worst = 0.0f;
        for (size_t i = 0; i < twin.data.size(); ++i) {
            ASSERT_TRUE(std::isfinite(gpu.value()[i])) << i;
            peak = std::max(peak, std::abs(twin.data[i]));
            worst = std::max(worst, std::abs(gpu.value()[i] - twin.data[i]));
        }
        std::printf("radiance, cascade %u: peak |L| %.6g, max |GPU - twin| %.3g (%.3g of the "
                    "peak)\n",
                    k, peak, worst, worst / peak);
        EXPECT_GT(peak, 0.01f);
        // Measured on lavapipe: 2.3e-7 (cascade 0); float sums in a different order (the
        // clamp's kept and dropped flux, summed in double by the twin) and fused multiply-adds
        // on other devices stay far below this.
        EXPECT_LE(worst, 1e-4f * peak) << "cascade " << k;
    }
}

TEST_F(DynamicGiTest, Resolution64UpdatesCleanly) {
    DynamicGiSettings settings = roomSettings();
    settings.resolution = 64;
    settings.cellSize = 0.0625f;
    settings.iterations = 2;
    DynamicGi gi = makeRoomGi(context(), settings);
    Result<runtime::GiUpdateStats> stats = gi.update(0);
    ASSERT_TRUE(stats) << stats.error().message;
    EXPECT_EQ(stats.value().cascadesUpdated, 1u);
    Result<std::vector<float>> radiance = gi.readRadiance(0);
    ASSERT_TRUE(radiance) << radiance.error().message;
    ASSERT_EQ(radiance.value().size(), size_t(12) * 64 * 64 * 64);
    // Its buffers (gpuBytes): 65^3 geometry cells x (68 + 64) B, two fields, the pass and the
    // radiance (12 floats per cell each), crossings (18), keep factors (30), and 2 vec4 per
    // 64-cell workgroup: 130.7 MiB.
    const uint64_t cells = 64ull * 64 * 64;
    const uint64_t geometry = 65ull * 65 * 65;
    EXPECT_EQ(gi.gpuBytes(),
              geometry * (68 + 64) + cells * 4 * (4 * 12 + 18 + 30) + 2 * (cells / 64) * 16 + 16);
    float peak = 0.0f;
    for (const float v : radiance.value()) {
        ASSERT_TRUE(std::isfinite(v));
        peak = std::max(peak, std::abs(v));
    }
    EXPECT_GT(peak, 0.01f);
}

TEST_F(DynamicGiTest, DirtyTrackingRecordsNothingWithoutChange) {
    DynamicGiSettings settings = roomSettings();
    settings.cascades = 2;
    settings.iterations = 2;
    DynamicGi gi = makeRoomGi(context(), settings);
    auto step = [&](uint64_t frame) {
        Result<runtime::GiUpdateStats> r = gi.update(frame);
        EXPECT_TRUE(r) << (r ? "" : r.error().message);
        return r ? r.value() : runtime::GiUpdateStats{};
    };
    runtime::GiUpdateStats s = step(0);
    EXPECT_GT(s.dispatches, 0u);
    EXPECT_EQ(s.cascadesUpdated, 2u);
    EXPECT_TRUE(s.geometryRebuilt);

    s = step(1);
    EXPECT_EQ(s.dispatches, 0u);
    EXPECT_EQ(s.cascadesUpdated, 0u);

    // Turned by half the threshold: below it.
    ASSERT_TRUE(gi.setLights(turnedSun(0.5f * settings.angleThreshold)));
    s = step(2);
    EXPECT_EQ(s.dispatches, 0u);

    // Turned by twice the threshold: every cascade is relit, its geometry kept.
    ASSERT_TRUE(gi.setLights(turnedSun(2.0f * settings.angleThreshold)));
    s = step(3);
    EXPECT_GT(s.dispatches, 0u);
    EXPECT_EQ(s.cascadesUpdated, 2u);
    EXPECT_FALSE(s.geometryRebuilt);
    EXPECT_EQ(step(4).dispatches, 0u);

    // The sky, by 5% of its largest coefficient.
    sh::ShRgb sky = sceneSky();
    sky.rgb[0] *= 1.05f;
    gi.setSky(sky);
    s = step(5);
    EXPECT_EQ(s.cascadesUpdated, 2u);
    EXPECT_FALSE(s.geometryRebuilt);

    // Tuning: the fade and the quality are the shading's (no relight); more steps relight
    // without rebuilding; another propagation weight rebuilds the keep factors too.
    DynamicGiSettings tuned = settings;
    tuned.fadeCells = 3.0f;
    tuned.quality = runtime::GiQuality::L1Zonal;
    ASSERT_TRUE(gi.setTuning(tuned));
    EXPECT_EQ(step(7).dispatches, 0u);
    tuned.iterations = 3;
    ASSERT_TRUE(gi.setTuning(tuned));
    s = step(8);
    EXPECT_EQ(s.cascadesUpdated, 2u);
    EXPECT_FALSE(s.geometryRebuilt);
    tuned.propagationWeight = 0.9f;
    ASSERT_TRUE(gi.setTuning(tuned));
    s = step(9);
    EXPECT_EQ(s.cascadesUpdated, 2u);
    EXPECT_TRUE(s.geometryRebuilt);
    EXPECT_EQ(step(10).dispatches, 0u);
    tuned.resolution = 64;
    EXPECT_FALSE(gi.setTuning(tuned));

    // The camera moved by several finest cells: the finest cascade's geometry is rebuilt.
    gi.setCamera(glm::vec3(0.05f + 3.0f * settings.cellSize, 1.0f, 0.0f),
                 glm::vec3(0.0f, 0.0f, -1.0f));
    s = step(11);
    EXPECT_GE(s.cascadesUpdated, 1u);
    EXPECT_TRUE(s.geometryRebuilt);
}

TEST_F(DynamicGiTest, UpdateIntervalDefersDirtyUpdates) {
    DynamicGiSettings settings = roomSettings();
    settings.iterations = 2;
    settings.updateInterval = 4;
    DynamicGi gi = makeRoomGi(context(), settings);
    Result<runtime::GiUpdateStats> s = gi.update(10);
    ASSERT_TRUE(s);
    EXPECT_GT(s.value().dispatches, 0u); // the first update is always due
    ASSERT_TRUE(gi.setLights(turnedSun(0.2f)));
    for (uint64_t frame = 11; frame < 14; ++frame) {
        s = gi.update(frame);
        ASSERT_TRUE(s);
        EXPECT_EQ(s.value().dispatches, 0u) << "frame " << frame;
    }
    s = gi.update(14);
    ASSERT_TRUE(s);
    EXPECT_GT(s.value().dispatches, 0u);
    EXPECT_EQ(s.value().cascadesUpdated, 1u);
    s = gi.update(15);
    ASSERT_TRUE(s);
    EXPECT_EQ(s.value().dispatches, 0u);
}

TEST(DynamicGiPlacement, SnapsToEachCascadeLatticeAndMovesByWholeCells) {
    DynamicGiSettings settings;
    settings.cascades = 4;
    settings.resolution = 32;
    settings.cellSize = 0.25f;
    settings.aheadFraction = 0.25f;
    const glm::vec3 forward = glm::normalize(glm::vec3(0.3f, -0.2f, -1.0f));
    glm::vec3 camera(3.37f, 1.61f, -7.93f);
    std::vector<runtime::GiCascadePlacement> previous;
    for (int move = 0; move < 20; ++move) {
        const std::vector<runtime::GiCascadePlacement> p =
            runtime::placeGiCascades(settings, camera, forward);
        ASSERT_EQ(p.size(), 4u);
        for (size_t k = 0; k < p.size(); ++k) {
            const float s = settings.cellSize * float(1u << k);
            EXPECT_FLOAT_EQ(p[k].cellSize, s);
            EXPECT_EQ(p[k].cells, 32u);
            const float width = 32.0f * s;
            const glm::vec3 centre = camera + settings.aheadFraction * width * forward;
            for (int axis = 0; axis < 3; ++axis) {
                const float cells = p[k].origin[axis] / s;
                // On the lattice (to float rounding of a number of at most a few hundred cells).
                EXPECT_NEAR(cells, std::round(cells), 1e-4f) << "cascade " << k;
                // Snapped down: the box's centre is within one cell below the wanted centre.
                const float offset = centre[axis] - (p[k].origin[axis] + 0.5f * width);
                EXPECT_GE(offset, -1e-4f * s);
                EXPECT_LT(offset, s * (1.0f + 1e-4f));
                if (!previous.empty()) {
                    const float moved = (p[k].origin[axis] - previous[k].origin[axis]) / s;
                    EXPECT_NEAR(moved, std::round(moved), 1e-4f);
                }
            }
        }
        previous = p;
        camera += glm::vec3(0.071f, -0.033f, 0.113f);
    }
}

TEST_F(DynamicGiTest, TimingsAreFilledAfterAnUpdate) {
    DynamicGiSettings settings = roomSettings(); // one 32^3 cascade
    settings.iterations = 16;
    settings.bounces = 1;
    DynamicGi gi = makeRoomGi(context(), settings);
    runtime::GiTimings t = gi.timings();
    EXPECT_TRUE(std::isnan(t.occupancyMs) && std::isnan(t.injectMs) && std::isnan(t.propagateMs) &&
                std::isnan(t.resolveMs));
    ASSERT_TRUE(gi.update(0));
    t = gi.timings();
    if (!(context().timestampPeriodNs() > 0.0)) {
        EXPECT_TRUE(std::isnan(t.propagateMs));
        GTEST_SKIP() << "the queue has no timestamps";
    }
    std::printf("gi timings, one 32^3 cascade, 16 iterations, 1 bounce: occupancy %.3f ms, "
                "inject %.3f ms, propagate %.3f ms, resolve %.3f ms\n",
                t.occupancyMs, t.injectMs, t.propagateMs, t.resolveMs);
    for (const double ms : {t.occupancyMs, t.injectMs, t.propagateMs, t.resolveMs}) {
        EXPECT_TRUE(std::isfinite(ms));
        EXPECT_GE(ms, 0.0);
    }
    // Lights alone changed: the geometry volume is not rebuilt, so its time is NaN.
    ASSERT_TRUE(gi.setLights(turnedSun(0.3f)));
    ASSERT_TRUE(gi.update(1));
    t = gi.timings();
    EXPECT_TRUE(std::isnan(t.occupancyMs));
    EXPECT_TRUE(std::isfinite(t.propagateMs));
}

TEST_F(DynamicGiTest, RejectsSettingsAndInputsOutsideTheirRanges) {
    DynamicGiSettings bad = roomSettings();
    bad.cascades = 5;
    EXPECT_FALSE(DynamicGi::create(context(), bad));
    bad = roomSettings();
    bad.resolution = 48;
    EXPECT_FALSE(DynamicGi::create(context(), bad));
    Result<DynamicGi> gi = DynamicGi::create(context(), roomSettings());
    ASSERT_TRUE(gi) << gi.error().message;
    const Mesh mesh = roomScene();
    const std::vector<uint32_t> past = {0, 1, uint32_t(mesh.vertices.size())};
    const Result<void> r = gi.value().setGeometry(mesh.vertices, past);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code, ErrorCode::OutOfRange);
    const std::vector<PunctualLight> many(runtime::kMaxGiLights + 1);
    EXPECT_FALSE(gi.value().setLights(many));
}

} // namespace
} // namespace probekit
