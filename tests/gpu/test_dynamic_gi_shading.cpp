// The dynamic GI in the shading pass (shade.comp with PK_DYNAMIC_GI) against its CPU twins
// (runtime/src/gi_twin.hpp): per pixel, at the G-buffer's position and normal, the cascades'
// irradiance (giSampleRadiance, both quality levels, two cascades with their fade), the sun's
// marched shadow (giSunVisibility) and the debug views (giGeometryColour, giOcclusion), read
// from the DynamicGi's own buffers so that only the shading is under test.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include <glm/geometric.hpp>

#include "gi_twin.hpp"
#include "gpu_test_support.hpp"
#include "probekit/runtime/dynamic_gi.hpp"
#include "probekit/runtime/gpu_volumes.hpp"
#include "probekit/runtime/renderer.hpp"

using namespace probekit;
using namespace probekit::gputest;
using namespace probekit::runtime;

namespace {

// A corner of a room: a 4 x 4 m floor, two 2 m walls along its -x and -z sides and a 1 m box
// in the middle, white (so the shaded view is E / pi).
void roomCorner(std::vector<RenderVertex>& v, std::vector<uint32_t>& idx) {
    auto quad = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
        const auto base = uint32_t(v.size());
        const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
        for (const glm::vec3& p : {a, b, c, d}) {
            RenderVertex r;
            r.position = p;
            r.normal = n;
            r.albedo = glm::vec3(1.0f);
            v.push_back(r);
        }
        idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    };
    quad({-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2});
    quad({-2, 0, -2}, {-2, 2, -2}, {-2, 2, 2}, {-2, 0, 2});
    quad({-2, 0, -2}, {2, 0, -2}, {2, 2, -2}, {-2, 2, -2});
    // The box: its five visible faces.
    const glm::vec3 lo(-0.5f, 0.0f, -0.5f), hi(0.5f, 1.0f, 0.5f);
    quad({lo.x, hi.y, lo.z}, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}, {hi.x, hi.y, lo.z});
    quad({hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z}, {hi.x, lo.y, hi.z});
    quad({lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z});
    quad({lo.x, lo.y, lo.z}, {lo.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {lo.x, hi.y, lo.z});
    quad({lo.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, lo.y, lo.z});
}

class DynamicGiShading : public GpuTest {};

struct Twin {
    std::vector<GiCascadeLayout> layouts;
    std::vector<GiField> fields;
    std::vector<GiGeometryCell> geometry; // the finest cascade's
};

Twin readTwin(const DynamicGi& gi) {
    Twin t;
    const std::vector<GiCascadePlacement> placements = gi.placements();
    for (uint32_t j = 0; j < placements.size(); ++j) {
        GiCascadeLayout l;
        l.origin = placements[j].origin;
        l.cellSize = placements[j].cellSize;
        l.cells = int(placements[j].cells);
        t.layouts.push_back(l);
        Result<std::vector<float>> radiance = gi.readRadiance(j);
        EXPECT_TRUE(radiance.ok());
        GiField f(giCellCount(l));
        f.data = radiance.value();
        t.fields.push_back(std::move(f));
    }
    Result<std::vector<int32_t>> geometry = gi.readGeometry(0);
    EXPECT_TRUE(geometry.ok());
    t.geometry.resize(geometry.value().size() / (sizeof(GiGeometryCell) / sizeof(int32_t)));
    std::memcpy(static_cast<void*>(t.geometry.data()), geometry.value().data(),
                t.geometry.size() * sizeof(GiGeometryCell));
    return t;
}

// Every geometry pixel of a frame with its G-buffer, against expected(position, normal); the
// share of pixels beyond `tolerance` x (the largest expected value) must stay below
// `outlier_share` (nearest-cell lookups at exact cell borders may round either way).
template <class Expected>
void expectPixels(const Frame& frame, const Expected& expected, float tolerance,
                  double outlier_share, const char* what) {
    std::vector<std::pair<glm::vec3, glm::vec3>> want;
    float largest = 0.0f;
    for (size_t i = 0; i < frame.color.size(); ++i) {
        const glm::vec3 e = frame.position[i].w > 0.0f
                                ? expected(glm::vec3(frame.position[i]), glm::vec3(frame.normal[i]))
                                : glm::vec3(0.0f);
        largest = std::max({largest, e.x, e.y, e.z});
        want.emplace_back(e, glm::vec3(frame.color[i]));
    }
    size_t pixels = 0;
    size_t outliers = 0;
    float worst = 0.0f;
    for (size_t i = 0; i < want.size(); ++i) {
        if (frame.position[i].w <= 0.0f) {
            continue;
        }
        ++pixels;
        const glm::vec3 d = glm::abs(want[i].first - want[i].second);
        const float diff = std::max({d.x, d.y, d.z});
        if (diff > tolerance * largest) {
            ++outliers;
        } else {
            worst = std::max(worst, diff);
        }
    }
    std::printf("%s: %zu pixels, largest %.4g, worst inside the tolerance %.3g of it, %zu "
                "beyond\n",
                what, pixels, double(largest), double(worst / largest), outliers);
    EXPECT_GT(pixels, 1000u) << what;
    EXPECT_GT(largest, 0.0f) << what;
    EXPECT_LE(double(outliers), outlier_share * double(pixels)) << what;
}

TEST_F(DynamicGiShading, EveryViewMatchesItsCpuTwin) {
    std::vector<RenderVertex> vertices;
    std::vector<uint32_t> indices;
    roomCorner(vertices, indices);

    DynamicGiSettings settings;
    settings.cascades = 2;
    settings.resolution = 32;
    settings.cellSize = 0.125f; // the finest holds most of the room, the coarser all of it
    settings.iterations = 8;
    settings.bounces = 2;
    settings.aheadFraction = 0.0f;
    settings.quality = GiQuality::L1Zonal;
    Result<DynamicGi> created = DynamicGi::create(context(), settings);
    ASSERT_TRUE(created.ok()) << created.error().message;
    DynamicGi& gi = created.value();
    ASSERT_TRUE(gi.setGeometry(vertices, indices).ok());
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.4f, -1.0f, -0.7f));
    sun.intensity = glm::vec3(3.0f, 2.8f, 2.5f);
    const std::vector<PunctualLight> lights{sun};
    ASSERT_TRUE(gi.setLights(lights).ok());
    sh::ShRgb sky;
    sky.rgb[0] = glm::vec3(0.3f, 0.4f, 0.6f) * std::sqrt(4.0f * sh::kPi);
    sky.rgb[1] = glm::vec3(0.1f, 0.1f, 0.2f); // brighter above
    gi.setSky(sky);
    gi.setCamera(glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(0.0f, 0.0f, -1.0f));
    ASSERT_TRUE(gi.update(0).ok());
    const Twin twin = readTwin(gi);
    const GiShadingInputs inputs = gi.shadingInputs();

    Result<Renderer> renderer = Renderer::create(context());
    ASSERT_TRUE(renderer.ok()) << renderer.error().message;
    ASSERT_TRUE(renderer.value().setMeshes(vertices, indices).ok());
    // No baked light: a volume of zeros, left out (bakedLight false).
    VolumeSpec spec;
    spec.bounds = grid::Aabb{glm::vec3(-2.0f), glm::vec3(2.0f)};
    spec.resolution = glm::uvec3(2);
    const Volume zero = makeTestVolume(spec, [](glm::vec3) { return sh::ShRgb{}; });
    Result<GpuVolumeSet> set = GpuVolumeSet::create(context(), {&zero, 1});
    ASSERT_TRUE(set.ok()) << set.error().message;

    FrameSettings frame;
    frame.width = 160;
    frame.height = 120;
    frame.camera.eye = glm::vec3(2.6f, 3.0f, 3.2f);
    frame.camera.target = glm::vec3(-0.5f, 0.4f, -0.5f);
    frame.readbackGBuffer = true;
    frame.dynamicGi = &inputs;
    frame.bakedLight = false;

    for (bool zonal : {true, false}) {
        // The quality level is the shading's: the same cascades serve both.
        GiShadingInputs in = inputs;
        in.quality = zonal ? GiQuality::L1Zonal : GiQuality::L1;
        frame.dynamicGi = &in;
        frame.view = RenderView::GiIrradiance;
        Result<Frame> f = renderer.value().render(set.value(), frame);
        ASSERT_TRUE(f.ok()) << f.error().message;
        expectPixels(
            f.value(),
            [&](glm::vec3 p, glm::vec3 n) {
                const sh::ShRgb r =
                    giSampleRadiance(twin.layouts, twin.fields, settings.fadeCells, zonal, p);
                return glm::max(sh::irradiance(r, sh::Order::L2, n), glm::vec3(0.0f));
            },
            1e-4f, 0.0, zonal ? "gi irradiance, zonal" : "gi irradiance, L1");
    }
    frame.dynamicGi = &inputs;

    // Shaded, white albedo: (E_gi + the sun's irradiance x its marched visibility) / pi.
    frame.view = RenderView::Shaded;
    frame.directLight = true;
    frame.lights = lights;
    frame.showEnvironment = false;
    Result<Frame> shaded = renderer.value().render(set.value(), frame);
    ASSERT_TRUE(shaded.ok()) << shaded.error().message;
    expectPixels(
        shaded.value(),
        [&](glm::vec3 p, glm::vec3 n) {
            const sh::ShRgb r =
                giSampleRadiance(twin.layouts, twin.fields, settings.fadeCells, true, p);
            const glm::vec3 e_gi = glm::max(sh::irradiance(r, sh::Order::L2, n), glm::vec3(0.0f));
            const float v = giSunVisibility(twin.layouts[0], twin.geometry, p, n, -sun.direction);
            return (e_gi + irradianceAt(sun, p, n) * v) / sh::kPi;
        },
        1e-3f, 0.01, "shaded with the marched sun");

    frame.directLight = false;
    frame.view = RenderView::GiGeometry;
    Result<Frame> geometry = renderer.value().render(set.value(), frame);
    ASSERT_TRUE(geometry.ok()) << geometry.error().message;
    expectPixels(
        geometry.value(),
        [&](glm::vec3 p, glm::vec3) { return giGeometryColour(twin.layouts[0], twin.geometry, p); },
        1e-4f, 0.01, "gi-geometry");

    frame.view = RenderView::GiAo;
    Result<Frame> ao = renderer.value().render(set.value(), frame);
    ASSERT_TRUE(ao.ok()) << ao.error().message;
    expectPixels(
        ao.value(),
        [&](glm::vec3 p, glm::vec3 n) {
            return glm::vec3(giOcclusion(twin.layouts[0], twin.geometry, p, n));
        },
        1e-4f, 0.01, "gi-ao");
}

// The views that read the dynamic GI refuse a frame without it.
TEST_F(DynamicGiShading, GiViewsNeedTheDynamicGi) {
    Result<Renderer> renderer = Renderer::create(context());
    ASSERT_TRUE(renderer.ok());
    VolumeSpec spec;
    const Volume zero = makeTestVolume(spec, [](glm::vec3) { return sh::ShRgb{}; });
    Result<GpuVolumeSet> set = GpuVolumeSet::create(context(), {&zero, 1});
    ASSERT_TRUE(set.ok());
    FrameSettings frame;
    frame.width = 8;
    frame.height = 8;
    frame.view = RenderView::GiAo;
    Result<Frame> f = renderer.value().render(set.value(), frame);
    ASSERT_FALSE(f.ok());
    EXPECT_NE(f.error().message.find("dynamicGi"), std::string::npos) << f.error().message;
}

} // namespace
