// The runtime's dynamic GI in an application (installed probekit package): a baked .pvol for
// the static light plus DynamicGi relighting a sun that moves, on a small courtyard of
// triangles (a floor and two walls around the first volume's box).
//
//   probekit_example_dynamic_gi VOLUMES.pvol OUT.pfm
//
// Per frame: move the sun, hand DynamicGi the new light, record its update (nothing when
// nothing changed beyond the thresholds), render with the baked volumes plus the GI. Writes the
// last frame's shaded image to OUT.pfm. Exit codes: 0 success, 1 failure, 77 no Vulkan device.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

#include <probekit/formats/pvol.hpp>
#include <probekit/runtime/dynamic_gi.hpp>
#include <probekit/runtime/gpu_context.hpp>
#include <probekit/runtime/gpu_volumes.hpp>
#include <probekit/runtime/renderer.hpp>

#include "example_start.hpp"

using namespace probekit;

namespace {

// Two triangles; the renderer and DynamicGi take the same arrays.
void quad(std::vector<runtime::RenderVertex>& v, std::vector<uint32_t>& idx, glm::vec3 a,
          glm::vec3 b, glm::vec3 c, glm::vec3 d, glm::vec3 albedo) {
    const auto base = uint32_t(v.size());
    const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
    for (const glm::vec3& p : {a, b, c, d}) {
        v.push_back({p, n, albedo, glm::vec3(0.0f), glm::vec2(0.0f)});
    }
    idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

} // namespace

int main(int argc, char** argv) {
    PvolFile file;
    if (const int code = startExample(argc, argv, file); code != 0) {
        return code;
    }
    Result<std::unique_ptr<runtime::GpuContext>> context = runtime::GpuContext::create();
    if (!context) {
        std::fprintf(stderr, "%s\n", context.error().message.c_str());
        return 1;
    }
    runtime::GpuContext& gpu = *context.value();
    Result<runtime::GpuVolumeSet> volumes = runtime::GpuVolumeSet::create(gpu, file.volumes);
    Result<runtime::Renderer> renderer = runtime::Renderer::create(gpu);
    if (!volumes || !renderer) {
        std::fprintf(stderr, "%s\n",
                     (!volumes ? volumes.error() : renderer.error()).message.c_str());
        return 1;
    }

    // The scene: a floor over the first volume's box and two walls along two of its sides.
    const grid::Aabb box = file.volumes[0].desc.grid.worldBounds();
    const glm::vec3 lo = box.min;
    const glm::vec3 hi = box.max;
    std::vector<runtime::RenderVertex> vertices;
    std::vector<uint32_t> indices;
    quad(vertices, indices, {lo.x, lo.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
         {hi.x, lo.y, lo.z}, glm::vec3(0.6f));
    quad(vertices, indices, {lo.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {lo.x, hi.y, hi.z},
         {lo.x, lo.y, hi.z}, glm::vec3(0.8f, 0.3f, 0.2f));
    quad(vertices, indices, {lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
         {lo.x, hi.y, lo.z}, glm::vec3(0.3f, 0.7f, 0.3f));
    if (auto r = renderer.value().setMeshes(vertices, indices); !r) {
        std::fprintf(stderr, "%s\n", r.error().message.c_str());
        return 1;
    }

    // One 32^3 cascade holding the box: cell = the longest side / 30.
    runtime::DynamicGiSettings settings;
    const glm::vec3 size = hi - lo;
    settings.cellSize = std::max({size.x, size.y, size.z}) / 30.0f;
    settings.aheadFraction = 0.0f; // centred on the camera position given below
    Result<runtime::DynamicGi> gi = runtime::DynamicGi::create(gpu, settings);
    if (!gi) {
        std::fprintf(stderr, "%s\n", gi.error().message.c_str());
        return 1;
    }
    if (auto r = gi.value().setGeometry(vertices, indices); !r) {
        std::fprintf(stderr, "%s\n", r.error().message.c_str());
        return 1;
    }
    gi.value().setCamera(box.center(), glm::vec3(0.0f, 0.0f, -1.0f));

    runtime::FrameSettings frame;
    frame.width = frame.height = 64;
    frame.camera.eye = box.center() + glm::vec3(0.6f, 0.8f, 1.2f) * glm::length(size);
    frame.camera.target = box.center();
    frame.directLight = true; // the sun's direct light, shadowed through the GI's geometry
    frame.readbackGBuffer = true;

    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.intensity = glm::vec3(3.0f, 2.9f, 2.7f);
    runtime::Frame last;
    uint32_t idle_dispatches = 0;
    for (uint64_t f = 0; f < 6; ++f) {
        // The sun sweeps 60 degrees over frames 0..4 and stands still at frame 5.
        const float azimuth = glm::radians(30.0f + 15.0f * float(std::min<uint64_t>(f, 4)));
        const float elevation = glm::radians(40.0f);
        sun.direction = -glm::vec3(std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                                   std::cos(azimuth) * std::cos(elevation));
        const std::vector<PunctualLight> lights{sun};
        if (auto r = gi.value().setLights(lights); !r) {
            std::fprintf(stderr, "%s\n", r.error().message.c_str());
            return 1;
        }
        Result<runtime::GiUpdateStats> stats = gi.value().update(f);
        if (!stats) {
            std::fprintf(stderr, "%s\n", stats.error().message.c_str());
            return 1;
        }
        const runtime::GiShadingInputs inputs = gi.value().shadingInputs();
        frame.dynamicGi = &inputs;
        frame.lights = lights;
        Result<runtime::Frame> rendered = renderer.value().render(volumes.value(), frame);
        if (!rendered) {
            std::fprintf(stderr, "%s\n", rendered.error().message.c_str());
            return 1;
        }
        const runtime::GiTimings t = gi.value().timings();
        std::printf("frame %llu: %u GI dispatches; inject %.2f ms, propagate %.2f ms; shading "
                    "%.2f ms\n",
                    static_cast<unsigned long long>(f), stats.value().dispatches, t.injectMs,
                    t.propagateMs, rendered.value().timings.shadeMs);
        if (f == 5) {
            idle_dispatches = stats.value().dispatches;
        }
        last = std::move(rendered.value());
    }

    std::ofstream out(argv[2], std::ios::binary);
    out << "PF\n" << last.width << " " << last.height << "\n-1\n";
    for (uint32_t row = last.height; row-- > 0;) { // PFM stores the bottom row first
        for (uint32_t x = 0; x < last.width; ++x) {
            out.write(reinterpret_cast<const char*>(&last.color[x + size_t(last.width) * row]), 12);
        }
    }
    // The frame where nothing moved relit nothing.
    return out && idle_dispatches == 0 ? 0 : 1;
}
