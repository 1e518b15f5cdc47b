// Leak-proof interpolation on the GPU: real thin-wall bakes (the offsets of the CPU sweep in
// tests/bake/test_leak.cpp where trilinear interpolation leaks most), sampled by pk_irradiance
// (GpuPointSampler) at the dark-side points. The GPU must keep the leak bound and agree with the
// CPU sampler point by point, dense and bricked, with visibility on; without visibility both
// leak alike.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "gpu_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/target.hpp"
#include "probekit/runtime/gpu_volumes.hpp"
#include "probekit/runtime/point_sampler.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit {
namespace {

constexpr double kLeakBound = 1.5;
// GPU against CPU per point and channel: the relative tolerance the other gpu tests use for
// float volumes (lavapipe filters and sums in float like the CPU; 8 taps, a division).
constexpr float kGpuRelative = 1e-4f;
constexpr float kGpuAbsolute = 1e-5f;

baker::Scene thinWall() {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("probekit_gpu_leak_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    EXPECT_TRUE(baker::writeGeneratedScene("thin-wall", dir / "thin-wall.gltf").ok());
    Result<baker::Scene> s = baker::loadGltf(dir / "thin-wall.gltf");
    EXPECT_TRUE(s.ok());
    return s.ok() ? std::move(s).value() : baker::Scene{};
}

struct Points {
    std::vector<glm::vec3> positions, normals;
};

// 0.25-0.35 m behind the wall's dark face, away from the doorway, six normals each.
Points darkPoints() {
    const glm::vec3 normals[6] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                  {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
    Points p;
    for (float dx : {0.25f, 0.30f, 0.35f}) {
        for (float y : {0.6f, 1.2f, 1.8f}) {
            for (float z : {-1.5f, -0.9f, -0.3f, 0.3f}) {
                for (const glm::vec3& n : normals) {
                    p.positions.emplace_back(0.025f + dx, y, z);
                    p.normals.push_back(n);
                }
            }
        }
    }
    return p;
}

double sum(const std::vector<glm::vec3>& e) {
    double s = 0.0;
    for (const glm::vec3& v : e) {
        s += double(v.x) + v.y + v.z;
    }
    return s;
}

class GpuLeak : public gputest::GpuTest {};

TEST_F(GpuLeak, GpuKeepsTheLeakBoundAndMatchesTheCpu) {
    const baker::Scene scene = thinWall();
    const Points points = darkPoints();
    baker::BakeConfig ref_config;
    std::vector<glm::vec3> unique;
    for (size_t i = 0; i < points.positions.size(); i += 6) {
        unique.push_back(points.positions[i]);
    }
    Result<baker::PointBake> ref = baker::bakePoints(scene, ref_config, unique, 4096, 0);
    ASSERT_TRUE(ref.ok());
    double ref_sum = 0.0;
    for (size_t i = 0; i < points.positions.size(); ++i) {
        const glm::vec3 e = sh::irradiance(ref.value().sh[i / 6], sh::Order::L2, points.normals[i]);
        ref_sum += double(e.x) + e.y + e.z;
    }
    Result<runtime::GpuPointSampler> sampler = runtime::GpuPointSampler::create(context());
    ASSERT_TRUE(sampler.ok()) << sampler.error().message;

    // Wall offsets 6.25 and 12.5 cm above the last lit-side probe plane (the worst two of the
    // CPU sweep), dense centre, dense corner and bricked, half storage (the default).
    struct Case {
        const char* name;
        baker::VolumeConfig volume;
    };
    std::vector<Case> cases;
    for (int k : {1, 2}) {
        const float o = 0.0625f * float(k);
        baker::VolumeConfig dense;
        dense.bounds.mode = baker::BoundsMode::Custom;
        dense.bounds.min = glm::vec3(-o - 1.75f, 0.0f, -2.0f);
        dense.bounds.max = glm::vec3(-o + 2.25f, 2.5f, 2.0f);
        dense.resolution = glm::uvec3(8, 8, 8);
        cases.push_back({k == 1 ? "dense 6.25 cm" : "dense 12.5 cm", dense});
        baker::VolumeConfig corner = dense;
        corner.position = grid::PositionMode::Corner;
        corner.bounds.min = glm::vec3(-o - 1.5f, 0.0f, -2.0f);
        corner.bounds.max = glm::vec3(-o + 2.0f, 2.5f, 2.0f);
        cases.push_back({k == 1 ? "corner 6.25 cm" : "corner 12.5 cm", corner});
        baker::VolumeConfig bricked = dense;
        bricked.layout = VolumeLayout::Bricked;
        bricked.bounds.min = glm::vec3(-o - 3.0f, 0.0f, -2.0f);
        bricked.bounds.max = glm::vec3(-o + 3.0f, 2.5f, 1.0f);
        bricked.resolution = glm::uvec3(4, 2, 2);
        bricked.maxLevel = 0;
        cases.push_back({k == 1 ? "bricked 6.25 cm" : "bricked 12.5 cm", bricked});
    }
    for (const Case& c : cases) {
        for (const bool visibility : {true, false}) {
            baker::BakeConfig config;
            config.path.samples = 256;
            config.visibility = visibility;
            config.volumes = {c.volume};
            Result<baker::BakeResult> baked = baker::bake(scene, config);
            ASSERT_TRUE(baked.ok()) << baked.error().message;
            const std::vector<Volume>& volumes = baked.value().file.volumes;
            Result<runtime::GpuVolumeSet> set = runtime::GpuVolumeSet::create(context(), volumes);
            ASSERT_TRUE(set.ok()) << set.error().message;
            Result<std::vector<glm::vec3>> gpu =
                sampler.value().irradiance(set.value(), points.positions, points.normals);
            ASSERT_TRUE(gpu.ok()) << gpu.error().message;
            const runtime::VolumeSet cpu(volumes);
            std::vector<glm::vec3> cpu_e;
            double worst = 0.0;
            for (size_t i = 0; i < points.positions.size(); ++i) {
                cpu_e.push_back(cpu.irradiance(points.positions[i], points.normals[i]));
                for (int ch = 0; ch < 3; ++ch) {
                    const float a = gpu.value()[i][ch], b = cpu_e.back()[ch];
                    worst = std::max(worst,
                                     double(std::abs(a - b)) / std::max(1e-3, double(std::abs(b))));
                    EXPECT_NEAR(a, b, kGpuRelative * std::abs(b) + kGpuAbsolute)
                        << c.name << " point " << i;
                }
            }
            const double gpu_ratio = sum(gpu.value()) / ref_sum;
            const double cpu_ratio = sum(cpu_e) / ref_sum;
            std::printf("[gpu leak] %-16s visibility %-3s: leak GPU %.3f, CPU %.3f; worst GPU/CPU "
                        "relative difference %.2g\n",
                        c.name, visibility ? "on" : "off", gpu_ratio, cpu_ratio, worst);
            if (visibility) {
                EXPECT_LE(gpu_ratio, kLeakBound) << c.name;
            } else {
                EXPECT_GT(gpu_ratio, 2.0 * kLeakBound) << c.name << ": the case must leak";
            }
        }
    }
}

} // namespace
} // namespace probekit
