// A minimal application of the installed probekit package: load a .pvol, upload it to the GPU,
// shade one frame of a floor through the volumes, and check the GPU against the CPU sampler.
//
//   probekit_example_app VOLUMES.pvol OUT.pfm
//
// Writes only OUT.pfm (the irradiance image, W/m^2). Exit codes: 0 success, 1 failure,
// 77 no Vulkan device on this machine (tests count that as skipped).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

#include <probekit/formats/pvol.hpp>
#include <probekit/runtime/gpu_context.hpp>
#include <probekit/runtime/gpu_volumes.hpp>
#include <probekit/runtime/renderer.hpp>
#include <probekit/runtime/sampler.hpp>

#include "example_start.hpp"

using namespace probekit;

int main(int argc, char** argv) {
    PvolFile file;
    if (const int code = startExample(argc, argv, file); code != 0) {
        return code;
    }
    const std::vector<Volume>& volumes = file.volumes;

    Result<std::unique_ptr<runtime::GpuContext>> context = runtime::GpuContext::create();
    if (!context) {
        std::fprintf(stderr, "%s\n", context.error().message.c_str());
        return 1;
    }
    Result<runtime::GpuVolumeSet> gpu = runtime::GpuVolumeSet::create(*context.value(), volumes);
    Result<runtime::Renderer> renderer = runtime::Renderer::create(*context.value());
    if (!gpu || !renderer) {
        std::fprintf(stderr, "%s\n", (!gpu ? gpu.error() : renderer.error()).message.c_str());
        return 1;
    }

    // A floor across the first volume's box, half-way up, seen from above.
    const grid::Aabb box = volumes[0].desc.grid.bounds();
    const float y = volumes[0].desc.grid.frame().toWorld(box.center()).y;
    const glm::vec3 c = volumes[0].desc.grid.frame().toWorld(box.center());
    const float r = 0.5f * std::max(box.size().x, box.size().z);
    const std::vector<runtime::RenderVertex> vertices = {{{c.x - r, y, c.z - r}},
                                                         {{c.x + r, y, c.z - r}},
                                                         {{c.x + r, y, c.z + r}},
                                                         {{c.x - r, y, c.z + r}}};
    const std::vector<uint32_t> indices = {0, 1, 2, 0, 2, 3};
    if (auto m = renderer.value().setMeshes(vertices, indices); !m) {
        std::fprintf(stderr, "%s\n", m.error().message.c_str());
        return 1;
    }
    runtime::FrameSettings settings;
    settings.width = settings.height = 64;
    settings.camera.eye = c + glm::vec3(0.0f, 2.5f * r, 0.01f);
    settings.camera.target = c;
    settings.view = runtime::RenderView::Irradiance;
    settings.readbackGBuffer = true;
    Result<runtime::Frame> frame = renderer.value().render(gpu.value(), settings);
    if (!frame) {
        std::fprintf(stderr, "%s\n", frame.error().message.c_str());
        return 1;
    }

    // The centre pixel against the CPU reference at the same G-buffer point.
    const runtime::Frame& f = frame.value();
    const size_t centre = f.width / 2 + f.width * size_t(f.height / 2);
    const glm::vec3 p(f.position[centre]);
    const glm::vec3 gpu_e(f.color[centre]);
    const glm::vec3 cpu_e = runtime::VolumeSet(volumes).irradiance(p, glm::vec3(f.normal[centre]));
    const float error = glm::length(gpu_e - cpu_e) / std::max(glm::length(cpu_e), 1e-6f);
    std::printf("%s on %s: E(%.3f, %.3f, %.3f) GPU (%.5g, %.5g, %.5g) CPU (%.5g, %.5g, %.5g), "
                "relative difference %.2g; G-buffer %.2f ms, shading %.2f ms\n",
                argv[1], context.value()->deviceInfo().name.c_str(), p.x, p.y, p.z, gpu_e.x,
                gpu_e.y, gpu_e.z, cpu_e.x, cpu_e.y, cpu_e.z, double(error), f.timings.gbufferMs,
                f.timings.shadeMs);

    std::ofstream out(argv[2], std::ios::binary);
    out << "PF\n" << f.width << " " << f.height << "\n-1\n";
    for (uint32_t row = f.height; row-- > 0;) { // PFM stores the bottom row first
        for (uint32_t x = 0; x < f.width; ++x) {
            out.write(reinterpret_cast<const char*>(&f.color[x + size_t(f.width) * row]), 12);
        }
    }
    // Half volumes may be filtered at half precision on some GPUs: 2e-3, as the gpu tests.
    return out && f.position[centre].w == 1.0f && error < 2e-3f ? 0 : 1;
}
