// The headless renderer: a flat plane under known lighting gives albedo / pi x E per pixel; the
// Cornell box in the irradiance view matches the CPU sampler (what `probekit sample` runs) at
// the G-buffer positions; probe spheres show their own SH; validity colours invalid probes.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

#include "bricked_test_volume.hpp"
#include "gpu_test_support.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/runtime/gpu_volumes.hpp"
#include "probekit/runtime/renderer.hpp"
#include "probekit/runtime/sampler.hpp"
#include "probekit/runtime/tonemap.hpp"

using namespace probekit;
using namespace probekit::gputest;
using runtime::Frame;
using runtime::FrameSettings;
using runtime::GpuVolumeSet;
using runtime::RenderVertex;
using runtime::RenderView;
using runtime::VolumeSet;

namespace {

// The irradiance view is pk_irradiance itself: within the sampler tolerance of
// test_gpu_sampler.cpp (measured there at ~1e-5), for float volumes.
constexpr float kIrradianceRelative = 1e-4f;
// Shaded pixels multiply by the albedo the G-buffer stored as RGBA16F. The albedos here are
// exact in binary16, but the rasteriser interpolates them (0.75 arrives as 0.74999994) and
// Vulkan lets float -> binary16 conversion round toward zero (lavapipe does), so the stored
// albedo can be one binary16 step low: at most 2^-10 relative (a value just above a power of
// two), on top of the irradiance error.
constexpr float kShadedRelative = 1.0f / 1024.0f + kIrradianceRelative;
// Half volumes, as in test_gpu_sampler.cpp: hardware may filter binary16 at half precision.
constexpr float kHalfRelative = 2e-3f;

// Albedos exactly representable in binary16.
const glm::vec3 kAlbedo(0.5f, 0.25f, 0.75f);

void writePfm(const std::string& path, const Frame& frame) {
    std::ofstream out(path, std::ios::binary);
    out << "PF\n" << frame.width << " " << frame.height << "\n-1\n";
    // PFM rows run bottom to top.
    for (uint32_t y = frame.height; y-- > 0;) {
        for (uint32_t x = 0; x < frame.width; ++x) {
            const glm::vec4& c = frame.color[x + size_t(frame.width) * y];
            out.write(reinterpret_cast<const char*>(&c), 3 * sizeof(float));
        }
    }
}

// A square in the plane y = 0, |x|, |z| <= 1, facing +y.
void planeMesh(std::vector<RenderVertex>& vertices, std::vector<uint32_t>& indices) {
    const glm::vec3 corners[4] = {{-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1}};
    for (const glm::vec3& c : corners) {
        vertices.push_back({c, glm::vec3(0, 1, 0), kAlbedo, glm::vec3(0.0f)});
    }
    indices = {0, 2, 1, 0, 3, 2};
}

FrameSettings planeView(uint32_t width, uint32_t height) {
    FrameSettings settings;
    settings.width = width;
    settings.height = height;
    settings.camera.eye = glm::vec3(0.3f, 2.5f, 1.5f);
    settings.camera.target = glm::vec3(0.0f);
    settings.readbackGBuffer = true;
    return settings;
}

float maxAbs(glm::vec3 v) {
    return std::max(std::abs(v.x), std::max(std::abs(v.y), std::abs(v.z)));
}

struct PixelCheck {
    size_t covered = 0;
    size_t failures = 0;
    float maxRelative = 0.0f;
};

// Every covered pixel against `expected(position, normal)`; the frame goes to disk on failure.
template <class Expected>
PixelCheck checkPixels(const Frame& frame, float relative, const std::string& name,
                       const Expected& expected) {
    PixelCheck out;
    for (size_t i = 0; i < frame.color.size(); ++i) {
        if (frame.position[i].w == 0.0f) {
            EXPECT_EQ(frame.color[i], glm::vec4(0.0f)) << name << ": background pixel " << i;
            continue;
        }
        ++out.covered;
        const glm::vec3 want =
            expected(glm::vec3(frame.position[i]), glm::normalize(glm::vec3(frame.normal[i])));
        const float scale = std::max(maxAbs(want), 1e-6f);
        const float error = maxAbs(glm::vec3(frame.color[i]) - want) / scale;
        out.maxRelative = std::max(out.maxRelative, error);
        if (!(error <= relative)) {
            if (out.failures++ == 0) {
                ADD_FAILURE() << name << ": pixel " << i << " (" << i % frame.width << ", "
                              << i / frame.width << ") is (" << frame.color[i].x << ", "
                              << frame.color[i].y << ", " << frame.color[i].z << "), expected ("
                              << want.x << ", " << want.y << ", " << want.z << ")";
            }
        }
    }
    if (out.failures > 0) {
        const std::string path = failureOutputPath(name + ".pfm");
        writePfm(path, frame);
        ADD_FAILURE() << name << ": " << out.failures << " of " << out.covered
                      << " pixels off; image in " << path;
    }
    std::printf("[ figures  ] %s: %zu pixels, max relative error %.3g (tolerance %.0e)\n",
                name.c_str(), out.covered, double(out.maxRelative), double(relative));
    return out;
}

class Renderer : public GpuTest {
protected:
    runtime::Renderer& renderer() {
        if (!m_renderer) {
            Result<runtime::Renderer> r = runtime::Renderer::create(context());
            EXPECT_TRUE(r.ok()) << r.error().message;
            m_renderer = std::make_unique<runtime::Renderer>(std::move(r).value());
        }
        return *m_renderer;
    }
    // Later frames draw the plane (planeMesh); false when the upload fails.
    bool drawPlane() {
        std::vector<RenderVertex> vertices;
        std::vector<uint32_t> indices;
        planeMesh(vertices, indices);
        return renderer().setMeshes(vertices, indices).ok();
    }
    // The GPU set of `volumes`, the renderer holding no meshes (frames show the probes alone);
    // the error of the step that failed.
    Result<GpuVolumeSet> probesOnly(const std::vector<Volume>& volumes) {
        Result<void> meshes = renderer().setMeshes({}, {});
        if (!meshes.ok()) {
            return meshes.error();
        }
        return GpuVolumeSet::create(context(), volumes);
    }
    void TearDown() override {
        m_renderer.reset();
        GpuTest::TearDown();
    }

private:
    std::unique_ptr<runtime::Renderer> m_renderer;
};

VolumeSpec planeVolumeSpec() {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(-2.0f, -1.0f, -2.0f), glm::vec3(2.0f, 1.0f, 2.0f)};
    spec.resolution = glm::uvec3(8, 4, 8);
    return spec;
}

TEST_F(Renderer, UniformlyLitPlaneIsAlbedoTimesRadiance) {
    // White-furnace-like: a uniform environment of radiance L gives E = pi L for any normal, so
    // a Lambertian plane reflects albedo x L (formats/CONVENTIONS.md).
    const glm::vec3 radiance(0.4f, 0.3f, 0.2f);
    const std::vector<Volume> volumes{makeTestVolume(planeVolumeSpec(), [&](glm::vec3) {
        sh::ShRgb s;
        s.rgb[0] = radiance * (2.0f * std::sqrt(sh::kPi));
        return s;
    })};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    ASSERT_TRUE(drawPlane());
    Result<Frame> frame = renderer().render(gpu.value(), planeView(96, 64));
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    // kY00 is 1 / (2 sqrt(pi)) to 6 decimals: E = pi L within ~1e-6.
    const PixelCheck check = checkPixels(frame.value(), kShadedRelative, "furnace_plane",
                                         [&](glm::vec3, glm::vec3) { return kAlbedo * radiance; });
    EXPECT_GT(check.covered, size_t(96 * 64 / 4));
}

TEST_F(Renderer, FlatPlaneIsAlbedoOverPiTimesE) {
    const std::vector<Volume> volumes{makeTestVolume(
        planeVolumeSpec(), skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.5f, -0.4f}, 4.0f))};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    const VolumeSet cpu(volumes);
    ASSERT_TRUE(drawPlane());

    FrameSettings settings = planeView(96, 64);
    Result<Frame> shaded = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(shaded.ok()) << shaded.error().message;
    for (const glm::vec4& n : shaded.value().normal) {
        if (n != glm::vec4(0.0f)) {
            EXPECT_NEAR(n.y, 1.0f, 1e-6f); // the plane's normal, facing the camera above it
        }
    }
    checkPixels(shaded.value(), kShadedRelative, "plane_shaded",
                [&](glm::vec3 p, glm::vec3 n) { return kAlbedo / sh::kPi * cpu.irradiance(p, n); });

    settings.view = RenderView::Irradiance;
    Result<Frame> irradiance = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(irradiance.ok());
    checkPixels(irradiance.value(), kIrradianceRelative, "plane_irradiance",
                [&](glm::vec3 p, glm::vec3 n) { return cpu.irradiance(p, n); });

    // Unshadowed direct light on top: a point light, a spot light and a directional light.
    settings.view = RenderView::Shaded;
    settings.directLight = true;
    PunctualLight point;
    point.position = glm::vec3(0.2f, 0.8f, -0.1f);
    point.intensity = glm::vec3(2.0f, 1.0f, 0.5f);
    point.range = 3.0f;
    PunctualLight spot;
    spot.type = LightType::Spot;
    spot.position = glm::vec3(-0.5f, 1.0f, 0.5f);
    spot.direction = glm::normalize(glm::vec3(0.2f, -1.0f, -0.1f));
    spot.intensity = glm::vec3(3.0f);
    spot.innerConeCos = 0.95f;
    spot.outerConeCos = 0.8f;
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
    sun.intensity = glm::vec3(0.5f, 0.6f, 0.7f);
    settings.lights = {point, spot, sun};
    Result<Frame> lit = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(lit.ok()) << lit.error().message;
    // The CPU twin of shade.comp's direct light (formats/light.hpp).
    auto direct = [&](glm::vec3 p, glm::vec3 n) {
        glm::vec3 e(0.0f);
        for (const PunctualLight& light : settings.lights) {
            e += irradianceAt(light, p, n);
        }
        return e;
    };
    checkPixels(lit.value(), kShadedRelative, "plane_direct", [&](glm::vec3 p, glm::vec3 n) {
        return kAlbedo / sh::kPi * (cpu.irradiance(p, n) + direct(p, n));
    });

    // Shadows (FrameSettings::lightVisibility): a pixel's mask switches each light off where its
    // bit is clear. Here stripes from the pixel's position, a different phase per light, so that
    // every combination occurs; the twin applies the same function to the same positions.
    auto maskAt = [](glm::vec3 p) {
        uint32_t m = 0u;
        for (uint32_t i = 0; i < 3; ++i) {
            if (glm::fract(4.0f * p.x + 3.0f * p.z + 0.37f * float(i)) < 0.5f) {
                m |= 1u << i;
            }
        }
        return m;
    };
    settings.lightVisibility.assign(lit.value().position.size(), 0u);
    size_t partly_shadowed = 0;
    for (size_t i = 0; i < lit.value().position.size(); ++i) {
        if (lit.value().position[i].w > 0.0f) {
            settings.lightVisibility[i] = maskAt(glm::vec3(lit.value().position[i]));
            partly_shadowed += settings.lightVisibility[i] != 7u ? 1 : 0;
        }
    }
    EXPECT_GT(partly_shadowed, size_t(96 * 64 / 8));
    auto masked = [&](glm::vec3 p, glm::vec3 n) {
        glm::vec3 e(0.0f);
        for (size_t i = 0; i < settings.lights.size(); ++i) {
            if ((maskAt(p) >> i) & 1u) {
                e += irradianceAt(settings.lights[i], p, n);
            }
        }
        return e;
    };
    Result<Frame> shadowed = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(shadowed.ok()) << shadowed.error().message;
    checkPixels(shadowed.value(), kShadedRelative, "plane_direct_shadowed",
                [&](glm::vec3 p, glm::vec3 n) {
                    return kAlbedo / sh::kPi * (cpu.irradiance(p, n) + masked(p, n));
                });
    // The irradiance view adds the same direct light: E itself.
    settings.view = RenderView::Irradiance;
    Result<Frame> shadowed_e = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(shadowed_e.ok()) << shadowed_e.error().message;
    checkPixels(shadowed_e.value(), kIrradianceRelative, "plane_direct_shadowed_irradiance",
                [&](glm::vec3 p, glm::vec3 n) { return cpu.irradiance(p, n) + masked(p, n); });
    // A mask count that is not one per pixel is refused.
    settings.lightVisibility.pop_back();
    EXPECT_FALSE(renderer().render(gpu.value(), settings).ok());
}

// Direct light alone: a black volume makes pk_irradiance exactly 0, so each pixel of the shaded
// view is albedo / pi x shade.comp's pk_direct_irradiance, compared with its CPU twin, the sum of
// irradianceAt over the lights (formats/light.hpp), for each light type alone and all together.
//
// Tolerance per pixel: kShadedRelative's albedo term (2^-10, the G-buffer's binary16 albedo) plus
// 1e-5 for the light terms themselves (about 15 float operations on each side; Vulkan allows
// 2.5-3 ulp for division and inversesqrt, so a few 1e-7 each), relative to the expected value;
// plus, for spot lights, the cone ramp's amplification of rounding in its cosine: t = (cos -
// cos_outer) s turns an error e in cos into at most 2 s e in t^2, with e = 16 ulp of 1 (the
// normalisation and the dot product on either side), relative to the spot's unramped
// irradiance (the same light as a point light). Near the cone's outer edge, where t^2 is tiny,
// only that absolute term can hold, which is why a purely relative check would not do.
TEST_F(Renderer, DirectLightMatchesItsCpuTwin) {
    constexpr float kDirectRelative = 1.0f / 1024.0f + 1e-5f;
    constexpr float kConeCosError = 16.0f * 0x1p-24f;
    const std::vector<Volume> volumes{
        makeTestVolume(planeVolumeSpec(), [](glm::vec3) { return sh::ShRgb{}; })};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    ASSERT_TRUE(drawPlane());

    PunctualLight point;
    point.position = glm::vec3(0.3f, 0.7f, 0.2f);
    point.intensity = glm::vec3(1.5f, 0.75f, 3.0f);
    point.range = 2.5f;
    // Its cone (outer half-angle ~37 degrees at 1.1 m) ends on the plane, so the ramp is seen.
    PunctualLight spot;
    spot.type = LightType::Spot;
    spot.position = glm::vec3(-0.2f, 1.1f, -0.1f);
    spot.direction = glm::normalize(glm::vec3(0.1f, -1.0f, 0.15f));
    spot.intensity = glm::vec3(4.0f, 2.0f, 1.0f);
    spot.innerConeCos = 0.95f;
    spot.outerConeCos = 0.8f;
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.4f, -1.0f, 0.3f));
    sun.intensity = glm::vec3(0.7f, 0.5f, 0.3f);

    const struct {
        const char* name;
        std::vector<PunctualLight> lights;
    } cases[] = {{"direct_point", {point}},
                 {"direct_spot", {spot}},
                 {"direct_sun", {sun}},
                 {"direct_all", {point, spot, sun}}};
    for (const auto& c : cases) {
        FrameSettings settings = planeView(96, 64);
        settings.directLight = true;
        settings.lights = c.lights;
        Result<Frame> frame = renderer().render(gpu.value(), settings);
        ASSERT_TRUE(frame.ok()) << frame.error().message;
        const Frame& f = frame.value();
        size_t covered = 0;
        size_t lit = 0;
        size_t failures = 0;
        float worst = 0.0f; // largest error / allowed error
        for (size_t i = 0; i < f.color.size(); ++i) {
            if (f.position[i].w == 0.0f) {
                continue; // the background: checkPixels covers it in the other tests
            }
            ++covered;
            const glm::vec3 p(f.position[i]);
            const glm::vec3 n = glm::normalize(glm::vec3(f.normal[i]));
            glm::vec3 want(0.0f);
            float allowed = 0.0f;
            for (const PunctualLight& light : c.lights) {
                want += kAlbedo / sh::kPi * irradianceAt(light, p, n);
                if (light.type == LightType::Spot) {
                    PunctualLight unramped = light;
                    unramped.type = LightType::Point;
                    const float slope = 1.0f / (light.innerConeCos - light.outerConeCos);
                    allowed += 2.0f * slope * kConeCosError *
                               maxAbs(kAlbedo / sh::kPi * irradianceAt(unramped, p, n));
                }
            }
            allowed += kDirectRelative * maxAbs(want);
            lit += maxAbs(want) > 0.0f ? 1 : 0;
            const float error = maxAbs(glm::vec3(f.color[i]) - want);
            worst =
                std::max(worst, allowed > 0.0f ? error / allowed : (error > 0.0f ? 1e9f : 0.0f));
            if (!(error <= allowed) && failures++ == 0) {
                ADD_FAILURE() << c.name << ": pixel " << i << " at (" << p.x << ", " << p.y << ", "
                              << p.z << ") is (" << f.color[i].x << ", " << f.color[i].y << ", "
                              << f.color[i].z << "), expected (" << want.x << ", " << want.y << ", "
                              << want.z << ") within " << allowed;
            }
        }
        EXPECT_EQ(failures, 0u) << c.name << ": of " << covered << " pixels";
        EXPECT_GT(lit, covered / 4) << c.name << ": the light should reach much of the plane";
        std::printf("[ figures  ] %s: %zu pixels (%zu lit), max error / tolerance %.3g\n", c.name,
                    covered, lit, double(worst));
    }
}

// The Cornell box as `probekit render` draws it: flat triangles with their material albedo and
// emission (the test repeats the tool's few lines of flattening).
void cornellMesh(std::vector<RenderVertex>& vertices, std::vector<uint32_t>& indices,
                 grid::Aabb& bounds) {
    const std::filesystem::path dir =
        std::filesystem::path(PROBEKIT_TEST_OUTPUT_DIR).parent_path() / "gpu_scenes";
    std::filesystem::create_directories(dir);
    const std::filesystem::path gltf = dir / "cornell.gltf";
    ASSERT_TRUE(baker::writeGeneratedScene("cornell", gltf).ok());
    Result<baker::Scene> scene = baker::loadGltf(gltf);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    const baker::Scene& s = scene.value();
    for (uint32_t t = 0; t < s.triangles.size(); ++t) {
        const glm::uvec3 tri = s.triangles[t];
        const glm::vec3 a = s.positions[tri.x];
        const glm::vec3 b = s.positions[tri.y];
        const glm::vec3 c = s.positions[tri.z];
        const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
        const glm::vec2 bary[3] = {{0, 0}, {1, 0}, {0, 1}};
        const glm::vec3 corner[3] = {a, b, c};
        for (int k = 0; k < 3; ++k) {
            indices.push_back(uint32_t(vertices.size()));
            vertices.push_back({corner[k], n, s.albedoAt(t, bary[k]), s.emissionAt(t, bary[k])});
        }
    }
    bounds = s.bounds;
}

TEST_F(Renderer, CornellIrradianceMatchesTheCpuSampler) {
    std::vector<RenderVertex> vertices;
    std::vector<uint32_t> indices;
    grid::Aabb bounds;
    cornellMesh(vertices, indices, bounds);
    ASSERT_FALSE(vertices.empty());
    // Two volumes as the bundled example once had them: the whole box in half
    // precision, and a higher-priority corner volume with a fade band. Their data is analytic:
    // this test is about the GPU path reproducing the CPU sampler, whatever the data.
    VolumeSpec box;
    box.bounds = bounds;
    box.resolution = glm::uvec3(8, 8, 8);
    box.storage = Storage::Float16;
    box.name = "box";
    VolumeSpec corner;
    corner.bounds = {glm::vec3(0.2f, 0.34f, 0.15f), glm::vec3(0.4f, 0.54f, 0.35f)};
    corner.resolution = glm::uvec3(4, 4, 4);
    corner.mode = grid::PositionMode::Corner;
    corner.priority = 1;
    corner.fade = 0.05f;
    corner.name = "light-corner";
    const std::vector<Volume> volumes{
        makeTestVolume(box, skyAndLight({0.2f, 0.2f, 0.2f}, {0.28f, 0.54f, 0.28f}, 0.5f)),
        makeTestVolume(corner, skyAndLight({0.1f, 0.15f, 0.1f}, {0.3f, 0.5f, 0.2f}, 0.2f))};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    const VolumeSet cpu(volumes);
    ASSERT_TRUE(renderer().setMeshes(vertices, indices).ok());

    FrameSettings settings;
    settings.width = 160;
    settings.height = 120;
    // The default camera now frames a scene from +Z (glTF assets face +Z); the Cornell box opens
    // towards -Z, so the test asks for that side, the classic front view it always used.
    settings.camera =
        runtime::frameBounds(bounds, 40.0f, 160.0f / 120.0f, glm::vec3(0.0f, 0.0f, -1.0f));
    settings.view = RenderView::Irradiance;
    settings.readbackGBuffer = true;
    Result<Frame> frame = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    // Irradiance can approach zero in corners the light barely reaches: measure against at
    // least 5% of the median pixel.
    std::vector<float> magnitudes;
    for (size_t i = 0; i < frame.value().color.size(); ++i) {
        if (frame.value().position[i].w != 0.0f) {
            magnitudes.push_back(maxAbs(glm::vec3(frame.value().color[i])));
        }
    }
    ASSERT_GT(magnitudes.size(), size_t(160 * 120 / 2)) << "the default camera frames the box";
    std::nth_element(magnitudes.begin(), magnitudes.begin() + long(magnitudes.size() / 2),
                     magnitudes.end());
    const float floor = 0.05f * magnitudes[magnitudes.size() / 2];
    size_t failures = 0;
    float worst = 0.0f;
    for (size_t i = 0; i < frame.value().color.size(); ++i) {
        if (frame.value().position[i].w == 0.0f) {
            continue;
        }
        const glm::vec3 p(frame.value().position[i]);
        const glm::vec3 n = glm::normalize(glm::vec3(frame.value().normal[i]));
        const glm::vec3 want = cpu.irradiance(p, n);
        const float error =
            maxAbs(glm::vec3(frame.value().color[i]) - want) / std::max(maxAbs(want), floor);
        worst = std::max(worst, error);
        failures += error <= kHalfRelative ? 0 : 1;
    }
    std::printf("[ figures  ] cornell irradiance view: %zu pixels vs VolumeSet::irradiance, max "
                "relative error %.3g (tolerance %.0e)\n",
                magnitudes.size(), double(worst), double(kHalfRelative));
    if (failures > 0) {
        const std::string path = failureOutputPath("cornell_irradiance.pfm");
        writePfm(path, frame.value());
        ADD_FAILURE() << failures << " pixels differ from the CPU sampler (worst " << worst
                      << "); image in " << path;
    }

    // The shaded view shows the emitter (radiance 17, 12, 4, plus whatever it reflects): no
    // reflecting surface comes near that under this lighting (E < 5 W/m^2 almost everywhere).
    settings.view = RenderView::Shaded;
    Result<Frame> shaded = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(shaded.ok());
    float brightest = 0.0f;
    for (const glm::vec4& c : shaded.value().color) {
        brightest = std::max(brightest, c.x);
    }
    EXPECT_GT(brightest, 15.0f) << "the Cornell emitter is in view of the default camera";
}

// Pixel under a world point, as the renderer projects it.
glm::ivec2 project(const FrameSettings& s, glm::vec3 world) {
    const runtime::Camera& cam = s.camera;
    glm::mat4 projection =
        glm::perspectiveRH_ZO(glm::radians(cam.verticalFovDeg), float(s.width) / float(s.height),
                              cam.nearPlane, cam.farPlane);
    projection[1][1] *= -1.0f;
    const glm::vec4 clip =
        projection * glm::lookAtRH(cam.eye, cam.target, cam.up) * glm::vec4(world, 1.0f);
    const glm::vec2 ndc = glm::vec2(clip) / clip.w;
    return glm::ivec2((ndc * 0.5f + 0.5f) * glm::vec2(s.width, s.height));
}

TEST_F(Renderer, ProbeSpheresShowTheirOwnShAndValidity) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(-1.0f), glm::vec3(1.0f)};
    spec.resolution = glm::uvec3(4, 4, 4);
    const Volume volume =
        makeTestVolume(spec, skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.6f, -0.4f}, 3.0f), 5);
    const std::vector<Volume> volumes{volume};
    Result<GpuVolumeSet> gpu = probesOnly(volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;

    FrameSettings settings;
    settings.width = 200;
    settings.height = 200;
    settings.camera.eye = glm::vec3(0.4f, 0.7f, 4.0f);
    settings.camera.target = glm::vec3(0.0f);
    settings.view = RenderView::Probes;
    settings.readbackGBuffer = true;
    Result<Frame> probes = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(probes.ok()) << probes.error().message;
    settings.view = RenderView::Validity;
    Result<Frame> validity = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(validity.ok()) << validity.error().message;

    const grid::GridLayout& layout = volume.desc.grid;
    const float radius = 0.15f * layout.spacing().x;
    size_t checked = 0;
    size_t invalid_seen = 0;
    for (size_t i = 0; i < layout.probeCount(); ++i) {
        const glm::vec3 center = layout.probeWorld(layout.probeCoords(i));
        const glm::ivec2 px = project(settings, center);
        const size_t at = size_t(px.x) + size_t(settings.width) * size_t(px.y);
        const glm::vec4 position = probes.value().position[at];
        // Only probes whose own sphere is visible at their centre pixel.
        if (position.w == 0.0f || glm::length(glm::vec3(position) - center) > 1.01f * radius) {
            continue;
        }
        ++checked;
        const glm::vec3 n = glm::normalize(glm::vec3(probes.value().normal[at]));
        // A white Lambertian sphere lit by the probe's coefficients: E / pi.
        const glm::vec3 want = sh::irradiance(volume.probe(i), volume.desc.shOrder, n) / sh::kPi;
        const glm::vec3 got(probes.value().color[at]);
        EXPECT_LE(maxAbs(got - want), kIrradianceRelative * maxAbs(want)) << "probe " << i;
        const glm::vec3 v(validity.value().color[at]);
        if (volume.validity[i] == kProbeInvalid) {
            ++invalid_seen;
            EXPECT_GT(v.x, 0.2f) << "invalid probe " << i << " is red";
            EXPECT_LT(v.y, 0.1f * v.x);
            EXPECT_LT(v.z, 0.1f * v.x);
        } else {
            EXPECT_EQ(v, got) << "valid probe " << i << " looks as in the probes view";
        }
    }
    EXPECT_GT(checked, size_t(20));
    EXPECT_GT(invalid_seen, size_t(2));
}

TEST_F(Renderer, BrickedProbeSpheresShowTheirLevelAndOwnSh) {
    // Mixed levels 0..2: the probes view colours each sphere by its brick's level (renderer.hpp
    // legend), the validity view lights valid ones by their own SH, read from the brick atlas.
    VolumeDesc desc;
    desc.name = "bricked";
    desc.grid = grid::GridLayout({glm::vec3(-1.0f), glm::vec3(1.0f)}, glm::uvec3(2, 1, 2),
                                 grid::PositionMode::Center, {});
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = bricktest::mixedLayout(glm::uvec3(2, 1, 2));
    const Volume volume = bricktest::makeBrickedVolume(
        desc, skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.6f, -0.4f}, 3.0f), true);
    Result<GpuVolumeSet> gpu = probesOnly(std::vector<Volume>{volume});
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;

    FrameSettings settings;
    // Large enough that the probes view's budget (probeBudget: one probe per 64 pixels, 3,600
    // here) takes every probe of this layout; at the 320 x 320 this test used before the budget
    // existed it would draw a sub-grid.
    settings.width = 480;
    settings.height = 480;
    settings.camera.eye = glm::vec3(-2.5f, 2.0f, -3.5f);
    settings.camera.target = glm::vec3(0.0f);
    settings.view = RenderView::Probes;
    settings.readbackGBuffer = true;
    Result<Frame> probes = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(probes.ok()) << probes.error().message;
    EXPECT_EQ(probes.value().probes.stride, 1u) << probes.value().probes.inView << " in view";
    settings.view = RenderView::Validity;
    Result<Frame> lit = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(lit.ok()) << lit.error().message;

    // The dominant channels of each level's colour: 0 blue, 1 green, 2 red and green (yellow).
    size_t seen[3] = {0, 0, 0};
    for (size_t b = 0; b < desc.bricks.bricks.size(); ++b) {
        const brick::Brick& br = desc.bricks.bricks[b];
        const float spacing = 2.0f / 6.0f / float(1u << br.level);
        for (uint32_t k = 0; k < brick::kBrickProbeCount; ++k) {
            const glm::vec3 center = bricktest::probeLocal(desc, br, k);
            const glm::ivec2 px = project(settings, center);
            const size_t at = size_t(px.x) + size_t(settings.width) * size_t(px.y);
            const glm::vec4 position = probes.value().position[at];
            // Only probes whose own sphere is visible at their centre pixel.
            if (position.w == 0.0f || glm::length(glm::vec3(position) - center) > 0.16f * spacing) {
                continue;
            }
            const glm::vec3 c(probes.value().color[at]);
            const std::string where = "brick " + std::to_string(b) + " probe " + std::to_string(k);
            if (br.level == 0) {
                EXPECT_TRUE(c.z > 2.0f * c.x && c.z > 2.0f * c.y) << where;
            } else if (br.level == 1) {
                EXPECT_TRUE(c.y > 2.0f * c.x && c.y > 2.0f * c.z) << where;
            } else {
                EXPECT_TRUE(c.x > 2.0f * c.z && c.y > 2.0f * c.z) << where;
            }
            ++seen[br.level];
            const glm::vec3 n = glm::normalize(glm::vec3(lit.value().normal[at]));
            const size_t probe = b * brick::kBrickProbeCount + k;
            const glm::vec3 want = sh::irradiance(volume.probe(probe), desc.shOrder, n) / sh::kPi;
            EXPECT_LE(maxAbs(glm::vec3(lit.value().color[at]) - want),
                      kIrradianceRelative * maxAbs(want))
                << where;
        }
    }
    EXPECT_GT(seen[0], size_t(10));
    EXPECT_GT(seen[1], size_t(10));
    EXPECT_GT(seen[2], size_t(10));
}

TEST_F(Renderer, DynamicUpdatesShowInTheNextFrameOnly) {
    const std::vector<Volume> volumes{makeTestVolume(
        planeVolumeSpec(), skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.5f, -0.4f}, 4.0f))};
    const Volume other = makeTestVolume(planeVolumeSpec(),
                                        skyAndLight({0.6f, 0.2f, 0.1f}, {-0.5f, 1.2f, 0.4f}, 2.0f));
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok());
    ASSERT_TRUE(drawPlane());
    FrameSettings settings = planeView(64, 48);
    settings.view = RenderView::Irradiance;

    Result<Frame> before = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(gpu.value().replaceVolume(0, other, runtime::VolumeState::Secondary).ok());
    ASSERT_TRUE(gpu.value().setStateBlend(0, 1.0f).ok());
    Result<Frame> after = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(gpu.value().setStateBlend(0, 0.0f).ok());
    Result<Frame> back = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(before.ok() && after.ok() && back.ok());
    const VolumeSet cpu_after({other});
    checkPixels(after.value(), kIrradianceRelative, "after_blend",
                [&](glm::vec3 p, glm::vec3 n) { return cpu_after.irradiance(p, n); });
    EXPECT_EQ(before.value().color, back.value().color) << "blend 0 restores the first state";
}

// A bricked volume (identity frame, mixed levels) over `bounds`, by default the plane volume's.
Volume brickedPlaneVolume(const ProbeFunction& field,
                          grid::Aabb bounds = {glm::vec3(-2.0f, -1.0f, -2.0f),
                                               glm::vec3(2.0f, 1.0f, 2.0f)}) {
    VolumeDesc desc;
    desc.name = "bricked";
    desc.grid = grid::GridLayout(bounds, glm::uvec3(2, 1, 2), grid::PositionMode::Center, {});
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = bricktest::mixedLayout(glm::uvec3(2, 1, 2));
    return bricktest::makeBrickedVolume(desc, field, true);
}

TEST_F(Renderer, LeakViewIsTheVisibleShare) {
    // The leak view is (1, v, v) with v = runtime::visibleWeight at the pixel's position (one
    // volume covering the plane, so the blend is that volume's share). The share is a sum of
    // eight products of weights in [0, 1]: float rounding and the ~1e-6 cell coordinate
    // difference on a 1/32-cell ramp keep GPU and CPU within 1e-3 absolute (the float
    // tolerance of the sampler tests at scale 1).
    constexpr float kShareAbsolute = 1e-3f;
    ASSERT_TRUE(drawPlane());
    FrameSettings settings = planeView(96, 64);
    settings.view = RenderView::Leak;
    const ProbeFunction field = skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.5f, -0.4f}, 4.0f);
    for (bool bricked : {false, true}) {
        const std::string name = bricked ? "leak_view_bricked" : "leak_view_dense";
        Volume volume =
            bricked ? brickedPlaneVolume(field) : makeTestVolume(planeVolumeSpec(), field);
        addVisibility(volume, bricked ? 7 : 5);
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), std::vector<Volume>{volume});
        ASSERT_TRUE(gpu.ok()) << gpu.error().message;
        Result<Frame> frame = renderer().render(gpu.value(), settings);
        ASSERT_TRUE(frame.ok()) << frame.error().message;
        size_t covered = 0;
        size_t hidden = 0;
        size_t partial = 0;
        size_t failures = 0;
        float worst = 0.0f;
        for (size_t i = 0; i < frame.value().color.size(); ++i) {
            if (frame.value().position[i].w == 0.0f) {
                continue;
            }
            ++covered;
            const float v = runtime::visibleWeight(volume, glm::vec3(frame.value().position[i]));
            const glm::vec4 c = frame.value().color[i];
            const float error =
                std::max({std::abs(c.x - 1.0f), std::abs(c.y - v), std::abs(c.z - v)});
            worst = std::max(worst, error);
            failures += error <= kShareAbsolute ? 0 : 1;
            hidden += v < 0.5f ? 1 : 0;
            partial += v > 0.05f && v < 0.95f ? 1 : 0;
        }
        std::printf("[ figures  ] %s: %zu pixels, %zu with share < 0.5, %zu in (0.05, 0.95), "
                    "max |GPU - CPU| %.3g (tolerance %.0e)\n",
                    name.c_str(), covered, hidden, partial, double(worst), double(kShareAbsolute));
        EXPECT_GT(covered, size_t(96 * 64 / 4));
        // Not vacuous: hidden taps, and shares between the extremes.
        EXPECT_GT(hidden, covered / 50) << name << ": the bytes hide too little to test";
        EXPECT_GT(partial, covered / 50) << name << ": too few partial shares to test";
        if (failures > 0) {
            const std::string path = failureOutputPath(name + ".pfm");
            writePfm(path, frame.value());
            ADD_FAILURE() << name << ": " << failures << " pixels off (worst " << worst
                          << "); image in " << path;
        }
        // Without visibility the share is 1: white.
        Result<GpuVolumeSet> plain = GpuVolumeSet::create(context(), std::vector<Volume>{[&] {
                                                              Volume v = volume;
                                                              v.visibility.clear();
                                                              return v;
                                                          }()});
        ASSERT_TRUE(plain.ok());
        Result<Frame> white = renderer().render(plain.value(), settings);
        ASSERT_TRUE(white.ok());
        for (size_t i = 0; i < white.value().color.size(); ++i) {
            if (white.value().position[i].w != 0.0f) {
                ASSERT_EQ(white.value().color[i], glm::vec4(1.0f)) << name << " pixel " << i;
            }
        }
    }
}

TEST_F(Renderer, IrradianceWithVisibilityMatchesTheCpuSampler) {
    // Sets with visibility are shaded by the renderer's visibility pipelines (every volume tap
    // by tap on CPU devices): a dense volume with visibility under a bricked one with visibility
    // of higher priority and a fade, and a small dense one without (its taps weigh 1).
    ASSERT_TRUE(drawPlane());
    Volume dense = makeTestVolume(planeVolumeSpec(),
                                  skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.5f, -0.4f}, 4.0f));
    addVisibility(dense, 11);
    // Over part of the plane, its fade band across it.
    Volume bricked =
        brickedPlaneVolume(skyAndLight({0.5f, 0.3f, 0.2f}, {-0.4f, 1.2f, 0.5f}, 3.0f),
                           {glm::vec3(-1.2f, -1.0f, -1.2f), glm::vec3(0.8f, 1.0f, 0.8f)});
    bricked.desc.blendPriority = 1;
    bricked.desc.fadeDistance = 0.4f;
    addVisibility(bricked, 12);
    VolumeSpec small = planeVolumeSpec();
    small.bounds = {glm::vec3(0.2f, -0.5f, -0.8f), glm::vec3(1.0f, 0.5f, 0.4f)};
    small.resolution = glm::uvec3(4, 4, 4);
    small.priority = 2;
    small.fade = 0.2f;
    const Volume plain =
        makeTestVolume(small, skyAndLight({0.1f, 0.2f, 0.1f}, {0.5f, 1.0f, 0.0f}, 2.0f));
    const std::vector<Volume> volumes{dense, bricked, plain};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    const VolumeSet cpu(volumes);
    FrameSettings settings = planeView(96, 64);
    settings.view = RenderView::Irradiance;
    Result<Frame> frame = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    checkPixels(frame.value(), kIrradianceRelative, "plane_irradiance_visibility",
                [&](glm::vec3 p, glm::vec3 n) { return cpu.irradiance(p, n); });
    // Not vacuous: visibility moves the result.
    std::vector<Volume> without = volumes;
    for (Volume& v : without) {
        v.visibility.clear();
    }
    const VolumeSet cpu_without(without);
    size_t changed = 0;
    size_t covered = 0;
    for (size_t i = 0; i < frame.value().color.size(); ++i) {
        if (frame.value().position[i].w == 0.0f) {
            continue;
        }
        ++covered;
        const glm::vec3 p(frame.value().position[i]);
        const glm::vec3 n = glm::normalize(glm::vec3(frame.value().normal[i]));
        const glm::vec3 e = cpu.irradiance(p, n);
        changed += maxAbs(e - cpu_without.irradiance(p, n)) > 0.05f * maxAbs(e) ? 1 : 0;
    }
    EXPECT_GT(changed, covered / 20) << "visibility changes too few pixels to test";
}

TEST_F(Renderer, TimesEachPass) {
    if (context().timestampPeriodNs() == 0.0) {
        GTEST_SKIP() << "the queue writes no timestamps on " << context().deviceInfo().name;
    }
    const std::vector<Volume> volumes{makeTestVolume(
        planeVolumeSpec(), skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.5f, -0.4f}, 4.0f))};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok());
    ASSERT_TRUE(drawPlane());
    FrameSettings settings = planeView(64, 48);
    settings.readbackColor = false;
    settings.readbackGBuffer = false;
    for (bool fetch_only : {false, true}) {
        settings.fetchOnly = fetch_only;
        Result<Frame> frame = renderer().render(gpu.value(), settings);
        ASSERT_TRUE(frame.ok());
        EXPECT_GT(frame.value().timings.gbufferMs, 0.0);
        EXPECT_GT(frame.value().timings.shadeMs, 0.0);
        EXPECT_TRUE(frame.value().color.empty());
    }
}

TEST_F(Renderer, RejectsBadInput) {
    std::vector<RenderVertex> vertices(3);
    EXPECT_EQ(renderer().setMeshes(vertices, std::vector<uint32_t>{0, 1}).error().code,
              ErrorCode::OutOfRange);
    EXPECT_EQ(renderer().setMeshes(vertices, std::vector<uint32_t>{0, 1, 3}).error().code,
              ErrorCode::OutOfRange);
    const std::vector<Volume> volumes{makeTestVolume(
        planeVolumeSpec(), skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 1.5f, -0.4f}, 4.0f))};
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok());
    FrameSettings settings = planeView(0, 10);
    EXPECT_EQ(renderer().render(gpu.value(), settings).error().code, ErrorCode::OutOfRange);
    settings = planeView(8, 8);
    settings.lights.resize(runtime::kMaxRenderLights + 1);
    EXPECT_EQ(renderer().render(gpu.value(), settings).error().code, ErrorCode::OutOfRange);
    settings = planeView(8, 8);
    settings.camera.target = settings.camera.eye;
    EXPECT_EQ(renderer().render(gpu.value(), settings).error().code, ErrorCode::InvalidArgument);
}

// A volume whose every probe sees a uniform radiance L: E = pi L for any normal, so a shaded
// Lambertian pixel is albedo x L (formats/CONVENTIONS.md); L = 0 gives a black volume.
std::vector<Volume> furnaceVolumes(glm::vec3 radiance) {
    return {makeTestVolume(planeVolumeSpec(), [&](glm::vec3) {
        sh::ShRgb s;
        s.rgb[0] = radiance * (2.0f * std::sqrt(sh::kPi));
        return s;
    })};
}

// A UV sphere of radius 1 at the origin, `segments` around and segments / 2 from pole to pole;
// its vertex normals the analytic ones, or (flat) each triangle's face normal.
void sphereMesh(uint32_t segments, bool flat, std::vector<RenderVertex>& vertices,
                std::vector<uint32_t>& indices) {
    auto at = [&](uint32_t i, uint32_t j) {
        const float phi = 2.0f * sh::kPi * float(i) / float(segments);
        const float theta = sh::kPi * float(j) / float(segments / 2);
        return glm::vec3(std::sin(theta) * std::cos(phi), std::cos(theta),
                         std::sin(theta) * std::sin(phi));
    };
    for (uint32_t j = 0; j < segments / 2; ++j) {
        for (uint32_t i = 0; i < segments; ++i) {
            const glm::vec3 q[4] = {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)};
            for (const glm::uvec3 t : {glm::uvec3(0, 1, 2), glm::uvec3(0, 2, 3)}) {
                const glm::vec3 face = glm::cross(q[t.y] - q[t.x], q[t.z] - q[t.x]);
                if (glm::length(face) < 1e-9f) {
                    continue; // the poles' degenerate halves
                }
                for (int k = 0; k < 3; ++k) {
                    indices.push_back(uint32_t(vertices.size()));
                    const glm::vec3 p = q[t[k]];
                    vertices.push_back({p, flat ? glm::normalize(face) : p, kAlbedo});
                }
            }
        }
    }
}

// Smooth shading: the G-buffer normal is the vertex normals interpolated per pixel, so on a
// tessellated sphere it follows the analytic normal (the direction from the centre to the shaded
// point) everywhere, where face normals jump by a facet's angle (7.5 degrees here) at every edge.
//
// Tolerance: on a facet the interpolated normal and the direction to the point differ by a
// second-order term, at most about (7.5 degrees)^2 / 8 in radians = 0.12 degrees at a facet's
// far corner for these facets; 0.25 degrees leaves room for the rasteriser's interpolation. Face
// normals are off by up to half a facet's diagonal (~5 degrees): the test requires > 2.
TEST_F(Renderer, SmoothNormalsFollowTheSphere) {
    const std::vector<Volume> volumes = furnaceVolumes(glm::vec3(0.5f));
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    FrameSettings settings;
    settings.width = 128;
    settings.height = 128;
    settings.camera.eye = glm::vec3(0.5f, 0.8f, 3.0f);
    settings.readbackGBuffer = true;
    float worst[2] = {0.0f, 0.0f};
    for (bool flat : {false, true}) {
        std::vector<RenderVertex> vertices;
        std::vector<uint32_t> indices;
        sphereMesh(48, flat, vertices, indices);
        ASSERT_TRUE(renderer().setMeshes(vertices, indices).ok());
        Result<Frame> frame = renderer().render(gpu.value(), settings);
        ASSERT_TRUE(frame.ok()) << frame.error().message;
        size_t covered = 0;
        for (size_t i = 0; i < frame.value().normal.size(); ++i) {
            if (frame.value().position[i].w == 0.0f) {
                continue;
            }
            ++covered;
            const glm::vec3 want = glm::normalize(glm::vec3(frame.value().position[i]));
            const glm::vec3 got = glm::normalize(glm::vec3(frame.value().normal[i]));
            const float angle = std::acos(std::clamp(glm::dot(want, got), -1.0f, 1.0f));
            worst[flat] = std::max(worst[flat], glm::degrees(angle));
        }
        EXPECT_GT(covered, size_t(128 * 128 / 4));
    }
    std::printf("[ figures  ] sphere normals against the analytic normal: smooth %.3f degrees, "
                "flat %.3f degrees at worst (tolerance 0.25)\n",
                double(worst[0]), double(worst[1]));
    EXPECT_LE(worst[0], 0.25f);
    EXPECT_GT(worst[1], 2.0f) << "face normals would pass too: the test cannot tell them apart";
}

// A quad in the plane z = 0 facing +Z, |x|, |y| <= 1, with uv (0, 0) at its top-left corner
// (x, y) = (-1, 1) and uv (1, 1) at (1, -1), as a glTF texture maps it; texture index per triangle.
void texturedQuad(glm::vec3 albedo, std::vector<RenderVertex>& vertices,
                  std::vector<uint32_t>& indices) {
    const glm::vec2 corners[4] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (const glm::vec2& c : corners) {
        const glm::vec2 uv((c.x + 1.0f) * 0.5f, (1.0f - c.y) * 0.5f);
        vertices.push_back({glm::vec3(c, 0.0f), glm::vec3(0, 0, 1), albedo, glm::vec3(0.0f), uv});
    }
    indices = {0, 1, 2, 0, 2, 3};
}

// Base colour per pixel: a quad with an 8 x 8 checker (texels exact in binary16) lit by a
// uniform radiance L shows albedo factor x texture(uv) x L at every pixel, the texture sampled
// bilinearly at the interpolated uv. CPU twin: RgbaImage::sampleBilinear at the uv of the pixel's
// G-buffer position (the quad maps position to uv linearly).
//
// Tolerance: the G-buffer stores albedo as binary16, which Vulkan lets round toward zero: 2^-10
// relative (kShadedRelative, with the furnace's 1e-4). On top, the bilinear weights: the position
// read back and the uv the rasteriser interpolated differ by float rounding (~1e-6 of the quad),
// which the checker's steepest slope (0.6 per texel, 8 texels across) turns into < 1e-4; 2e-3
// absolute covers it with room. Without per-pixel sampling (per-vertex albedo), a checker would
// be a single flat colour: the test also requires both checker colours to appear.
TEST_F(Renderer, TexturedQuadFollowsItsCheckerPerPixel) {
    const glm::vec3 radiance(0.5f);
    const std::vector<Volume> volumes = furnaceVolumes(radiance);
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    RgbaImage checker{8, 8, {}};
    for (uint32_t y = 0; y < 8; ++y) {
        for (uint32_t x = 0; x < 8; ++x) {
            checker.texels.push_back((x + y) % 2 == 0 ? glm::vec4(0.875f, 0.25f, 0.125f, 1.0f)
                                                      : glm::vec4(0.25f, 0.75f, 0.5f, 1.0f));
        }
    }
    const glm::vec3 factor(1.0f, 0.5f, 1.0f);
    ASSERT_TRUE(renderer().setTextures(std::vector<RgbaImage>{checker}).ok());
    std::vector<RenderVertex> vertices;
    std::vector<uint32_t> indices;
    texturedQuad(factor, vertices, indices);
    ASSERT_TRUE(renderer().setMeshes(vertices, indices, std::vector<int32_t>{0, 0}).ok());
    FrameSettings settings;
    settings.width = 96;
    settings.height = 96;
    settings.camera.eye = glm::vec3(0.3f, -0.2f, 2.6f);
    settings.readbackGBuffer = true;
    Result<Frame> frame = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    size_t covered = 0, failures = 0, reddish = 0, greenish = 0;
    float worst = 0.0f;
    for (size_t i = 0; i < frame.value().color.size(); ++i) {
        const glm::vec4 p = frame.value().position[i];
        if (p.w == 0.0f) {
            continue;
        }
        ++covered;
        const glm::vec2 uv((p.x + 1.0f) * 0.5f, (1.0f - p.y) * 0.5f);
        const glm::vec3 want = factor * glm::vec3(checker.sampleBilinear(uv)) * radiance;
        const glm::vec3 got(frame.value().color[i]);
        const float error = maxAbs(got - want) - kShadedRelative * maxAbs(want);
        worst = std::max(worst, maxAbs(got - want));
        failures += error <= 2e-3f ? 0 : 1;
        // Red texels give x = 0.4375, green ones 0.125: split at the midpoint.
        reddish += got.x > 0.28f ? 1 : 0;
        greenish += got.x < 0.28f ? 1 : 0;
    }
    std::printf("[ figures  ] textured quad: %zu pixels vs the CPU bilinear sample, max abs "
                "error %.3g (tolerance 2^-10 relative + 2e-3)\n",
                covered, double(worst));
    EXPECT_GT(covered, size_t(96 * 96 / 4));
    EXPECT_EQ(failures, size_t(0));
    EXPECT_GT(reddish, covered / 5);
    EXPECT_GT(greenish, covered / 5);
}

// The environment behind the geometry: a constant one shows its radiance exactly at every empty
// pixel (alpha 0) in the shaded view, nothing in the irradiance view; a lat-long one shows
// Environment::radiance along runtime::pixelDirection, its CPU twin.
//
// Lat-long tolerance: the texels are stored as binary16 (2^-11 relative), the GPU's acos/atan
// and the interpolation of the bilinear weights differ from the CPU's by ~1e-6 in uv, which this
// smooth map (at most 0.5 per 2 pi of longitude and per pi of latitude across a 64 x 32 image)
// turns into < 1e-4; 2e-3 relative holds both.
TEST_F(Renderer, EnvironmentIsTheBackground) {
    const std::vector<Volume> volumes = furnaceVolumes(glm::vec3(0.5f));
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    ASSERT_TRUE(drawPlane());
    Environment sky;
    sky.constant = glm::vec3(0.25f, 0.5f, 1.0f);
    sky.intensity = 2.0f;
    ASSERT_TRUE(renderer().setEnvironment(sky).ok());
    FrameSettings settings = planeView(64, 48);
    settings.camera.eye = glm::vec3(0.3f, 0.6f, 3.0f); // the horizon in view: sky above the plane
    Result<Frame> frame = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    size_t empty = 0;
    for (size_t i = 0; i < frame.value().color.size(); ++i) {
        if (frame.value().position[i].w == 0.0f) {
            ++empty;
            ASSERT_EQ(frame.value().color[i], glm::vec4(0.5f, 1.0f, 2.0f, 0.0f)) << "pixel " << i;
        }
    }
    EXPECT_GT(empty, size_t(64 * 48 / 10));
    settings.view = RenderView::Irradiance;
    Result<Frame> irradiance = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(irradiance.ok());
    for (size_t i = 0; i < irradiance.value().color.size(); ++i) {
        if (irradiance.value().position[i].w == 0.0f) {
            ASSERT_EQ(irradiance.value().color[i], glm::vec4(0.0f)) << "E has no background";
        }
    }

    Environment map;
    map.type = Environment::Type::LatLong;
    map.image = {64, 32, {}};
    for (uint32_t y = 0; y < 32; ++y) {
        for (uint32_t x = 0; x < 64; ++x) {
            const float u = (float(x) + 0.5f) / 64.0f;
            const float v = (float(y) + 0.5f) / 32.0f;
            map.image.texels.push_back(glm::vec4(1.0f + 0.5f * std::sin(2.0f * sh::kPi * u),
                                                 1.0f - 0.5f * v, 0.5f + 0.5f * v, 1.0f));
        }
    }
    map.intensity = 3.0f;
    map.rotationDeg = 30.0f;
    ASSERT_TRUE(renderer().setEnvironment(map).ok());
    settings.view = RenderView::Shaded;
    Result<Frame> mapped = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(mapped.ok()) << mapped.error().message;
    float worst = 0.0f;
    for (uint32_t y = 0; y < settings.height; ++y) {
        for (uint32_t x = 0; x < settings.width; ++x) {
            const size_t i = x + size_t(settings.width) * y;
            if (mapped.value().position[i].w != 0.0f) {
                continue;
            }
            const glm::vec3 dir = runtime::pixelDirection(settings.camera, settings.width,
                                                          settings.height, glm::vec2(x, y) + 0.5f);
            const glm::vec3 want = map.radiance(dir);
            worst =
                std::max(worst, maxAbs(glm::vec3(mapped.value().color[i]) - want) / maxAbs(want));
        }
    }
    std::printf("[ figures  ] lat-long background vs Environment::radiance: max relative error "
                "%.3g (tolerance 2e-3)\n",
                double(worst));
    EXPECT_LE(worst, 2e-3f);
    ASSERT_TRUE(renderer().setEnvironment(Environment{}).ok()); // black again: no background
}

// Automatic exposure (runtime/tonemap.hpp) on real frames: a plane lit by a 2,049 W/m^2 sun (the
// exporters' common value) and by a 1 W/m^2 one, the same direction, tone-mapped with each
// frame's own automatic EV, give the same mean display value; linear scaling makes this exact up
// to float rounding and the G-buffer's binary16 albedo, well inside 1%.
TEST_F(Renderer, AutoExposureMakesASunAndADimRoomAlike) {
    const std::vector<Volume> volumes = furnaceVolumes(glm::vec3(0.0f));
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    ASSERT_TRUE(drawPlane());
    FrameSettings settings = planeView(64, 48);
    settings.directLight = true;
    double means[2] = {0.0, 0.0};
    double clipped_fixed = 0.0;
    const float levels[2] = {2049.0f, 1.0f};
    for (int k = 0; k < 2; ++k) {
        PunctualLight sun;
        sun.type = LightType::Directional;
        sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
        sun.intensity = glm::vec3(levels[k]);
        settings.lights = {sun};
        Result<Frame> frame = renderer().render(gpu.value(), settings);
        ASSERT_TRUE(frame.ok()) << frame.error().message;
        const float ev = runtime::autoExposureEv(frame.value().color);
        size_t covered = 0;
        for (const glm::vec4& c : frame.value().color) {
            if (c.w == 0.0f) {
                continue;
            }
            ++covered;
            const glm::vec3 shown = runtime::toneMap(glm::vec3(c), ev);
            means[k] += (shown.x + shown.y + shown.z) / 3.0;
            if (k == 0) {
                clipped_fixed += runtime::toneMap(glm::vec3(c), 0.0f).x == 1.0f ? 1.0 : 0.0;
            }
        }
        means[k] /= double(covered);
        if (k == 0) {
            clipped_fixed /= double(covered);
        }
    }
    std::printf("[ figures  ] auto exposure: mean display value %.4f (2,049 W/m^2 sun), %.4f "
                "(1 W/m^2); %.0f%% of the sunlit pixels clip at EV 0\n",
                means[0], means[1], 100.0 * clipped_fixed);
    EXPECT_NEAR(means[0] / means[1], 1.0, 0.01);
    EXPECT_GT(means[0], 0.1) << "mid-grey, not black";
    EXPECT_GT(clipped_fixed, 0.9) << "without auto exposure the sun blows the picture out";
}

// The default camera (frameBounds) frames a scene from +Z: a quad facing +Z with its left half
// red and its right half green (as a glTF asset's front, text or logo, would be seen) shows red
// on the image's left and green on its right, not mirrored, and its +Z face (normal +Z).
TEST_F(Renderer, DefaultCameraSeesThePlusZFaceUnmirrored) {
    const std::vector<Volume> volumes = furnaceVolumes(glm::vec3(1.0f));
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    std::vector<RenderVertex> vertices;
    std::vector<uint32_t> indices;
    for (const float side : {-1.0f, 1.0f}) {
        const glm::vec3 albedo =
            side < 0.0f ? glm::vec3(0.8f, 0.0f, 0.0f) : glm::vec3(0.0f, 0.8f, 0.0f);
        const uint32_t base = uint32_t(vertices.size());
        const float x0 = side < 0.0f ? -1.0f : 0.0f;
        for (const glm::vec2 c : {glm::vec2(x0, -0.5f), glm::vec2(x0 + 1.0f, -0.5f),
                                  glm::vec2(x0 + 1.0f, 0.5f), glm::vec2(x0, 0.5f)}) {
            vertices.push_back({glm::vec3(c, 0.0f), glm::vec3(0, 0, 1), albedo});
        }
        for (const uint32_t k : {0u, 1u, 2u, 0u, 2u, 3u}) {
            indices.push_back(base + k);
        }
    }
    ASSERT_TRUE(renderer().setMeshes(vertices, indices).ok());
    FrameSettings settings;
    settings.width = 80;
    settings.height = 60;
    const grid::Aabb bounds{glm::vec3(-1.0f, -0.5f, 0.0f), glm::vec3(1.0f, 0.5f, 0.0f)};
    settings.camera = runtime::frameBounds(bounds, 40.0f, 80.0f / 60.0f);
    EXPECT_GT(settings.camera.eye.z, 0.0f) << "on the +Z side";
    settings.readbackGBuffer = true;
    Result<Frame> frame = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    const Frame& f = frame.value();
    const size_t row = size_t(settings.width) * (settings.height / 2);
    const glm::vec4 left = f.color[row + settings.width / 4];
    const glm::vec4 right = f.color[row + 3 * settings.width / 4];
    EXPECT_GT(left.x, 0.5f) << "red on the left";
    EXPECT_EQ(left.y, 0.0f);
    EXPECT_GT(right.y, 0.5f) << "green on the right";
    EXPECT_EQ(right.x, 0.0f);
    EXPECT_NEAR(f.normal[row + settings.width / 4].z, 1.0f, 1e-6f) << "the +Z face";
}

// The probes view draws at most probeBudget spheres, however many probes the volume has: a dense
// 128 x 64 x 64 volume (524,288 probes) at 160 x 120 pixels (budget 300) draws every 16th probe
// along each axis (8 x 4 x 4 = 128 <= 300, while every 8th would be 16 x 8 x 8 = 1,024), not all; a
// 4 x 4 x 4 one at the same size is drawn whole (stride 1).
TEST_F(Renderer, ProbesViewDrawsWithinItsBudget) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(-2.0f, -1.0f, -1.0f), glm::vec3(2.0f, 1.0f, 1.0f)};
    spec.resolution = glm::uvec3(128, 64, 64);
    spec.order = sh::Order::L1;
    spec.storage = Storage::Float16;
    const std::vector<Volume> big{makeTestVolume(spec, [](glm::vec3) {
        sh::ShRgb s;
        s.rgb[0] = glm::vec3(1.0f);
        return s;
    })};
    Result<GpuVolumeSet> gpu = probesOnly(big);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    FrameSettings settings;
    settings.width = 160;
    settings.height = 120;
    settings.camera = runtime::frameBounds(spec.bounds, 40.0f, 160.0f / 120.0f);
    settings.view = RenderView::Probes;
    Result<Frame> frame = renderer().render(gpu.value(), settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    const runtime::ProbeStats& stats = frame.value().probes;
    std::printf("[ figures  ] probes view, 128x64x64 at 160x120: drew %llu of %llu (%llu in "
                "view, budget %u, stride %u)\n",
                static_cast<unsigned long long>(stats.drawn),
                static_cast<unsigned long long>(stats.total),
                static_cast<unsigned long long>(stats.inView), stats.budget, stats.stride);
    EXPECT_EQ(stats.total, uint64_t(128 * 64 * 64));
    EXPECT_EQ(stats.budget, runtime::probeBudget(160, 120));
    EXPECT_EQ(stats.budget, 300u);
    EXPECT_LE(stats.drawn, stats.budget);
    EXPECT_EQ(stats.drawn, 128u);
    EXPECT_EQ(stats.stride, 16u);
    size_t sphere_pixels = 0;
    for (const glm::vec4& c : frame.value().color) {
        sphere_pixels += c.w != 0.0f ? 1 : 0;
    }
    EXPECT_GT(sphere_pixels, size_t(128)) << "the drawn spheres are visible";

    spec.resolution = glm::uvec3(4);
    Result<GpuVolumeSet> small = GpuVolumeSet::create(
        context(),
        std::vector<Volume>{makeTestVolume(spec, [](glm::vec3) { return sh::ShRgb{}; })});
    ASSERT_TRUE(small.ok());
    Result<Frame> whole = renderer().render(small.value(), settings);
    ASSERT_TRUE(whole.ok());
    EXPECT_EQ(whole.value().probes.drawn, 64u);
    EXPECT_EQ(whole.value().probes.stride, 1u);
}

TEST_F(Renderer, RejectsBadTexturesAndTextureIndices) {
    EXPECT_EQ(renderer().setTextures(std::vector<RgbaImage>{RgbaImage{}}).error().code,
              ErrorCode::OutOfRange);
    ASSERT_TRUE(
        renderer().setTextures(std::vector<RgbaImage>{RgbaImage{1, 1, {glm::vec4(1)}}}).ok());
    std::vector<RenderVertex> vertices(3);
    const std::vector<uint32_t> indices{0, 1, 2};
    EXPECT_TRUE(renderer().setMeshes(vertices, indices, std::vector<int32_t>{0}).ok());
    EXPECT_EQ(renderer().setMeshes(vertices, indices, std::vector<int32_t>{1}).error().code,
              ErrorCode::OutOfRange);
    EXPECT_EQ(renderer().setMeshes(vertices, indices, std::vector<int32_t>{0, 0}).error().code,
              ErrorCode::OutOfRange);
}

} // namespace
