// Path-method baker throughput against raw Embree throughput on the Cornell box, one run.
//
//   ./build/tests/probekit_bench_bake --benchmark_filter='Path|Rays'
//
// Prints, after the benchmarks, the ratio the baker issue asks for: baker Mrays/s divided by
// bench-rays' incoherent closest-hit Mrays/s, both measured in this process on the same scene
// with the same thread count.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include <benchmark/benchmark.h>

#include "bench_bake_common.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/bench_rays.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace probekit::bench {

std::map<std::string, double>& results() {
    static std::map<std::string, double> r;
    return r;
}

const Scene& cornellScene() {
    static const Scene scene = [] {
        const auto path = std::filesystem::path(PROBEKIT_SHARED_DIR) / "scenes" / "cornell-box" /
                          "cornell_from_obj.gltf";
        Result<Scene> s = loadGltf(path);
        if (!s) {
            std::fprintf(stderr, "bench: %s\n", s.error().message.c_str());
            std::exit(1);
        }
        return std::move(s).value();
    }();
    return scene;
}

uint32_t benchThreads() {
    return std::max(1u, std::thread::hardware_concurrency());
}

} // namespace probekit::bench

namespace {

void BM_RaysIncoherent(benchmark::State& state) {
    const Scene& scene = bench::cornellScene();
    for (auto _ : state) {
        Result<RayThroughput> r = measureRayThroughput(scene, 4'000'000, bench::benchThreads());
        if (!r) {
            state.SkipWithError(r.error().message.c_str());
            return;
        }
        state.counters["closest_Mrays_s"] = r.value().closestHitMraysPerSec;
        state.counters["occlusion_Mrays_s"] = r.value().occlusionMraysPerSec;
        bench::results()["rays_closest"] = r.value().closestHitMraysPerSec;
        bench::results()["rays_occlusion"] = r.value().occlusionMraysPerSec;
    }
}
BENCHMARK(BM_RaysIncoherent)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The speed figure: a 32x32x32 volume over the box at 256 samples.
void BM_BakePath32Cubed256(benchmark::State& state) {
    const Scene& scene = bench::cornellScene();
    BakeConfig config;
    config.path.samples = 256;
    VolumeConfig v;
    v.resolution = glm::uvec3(32);
    config.volumes = {v};
    BakeOptions options;
    options.threads = bench::benchThreads();
    for (auto _ : state) {
        Result<BakeResult> r = bake(scene, config, options);
        if (!r) {
            state.SkipWithError(r.error().message.c_str());
            return;
        }
        state.counters["bake_s"] = r.value().stats.seconds;
        state.counters["Mrays_s"] = r.value().stats.mraysPerSecond;
        state.counters["rays"] = double(r.value().stats.rays);
        bench::results()["path32_seconds"] = r.value().stats.seconds;
        bench::results()["path32_mrays"] = r.value().stats.mraysPerSecond;
    }
}
BENCHMARK(BM_BakePath32Cubed256)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

} // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    const auto& r = probekit::bench::results();
    std::printf("\nthreads: %u\n", probekit::bench::benchThreads());
    if (r.count("rays_closest") && r.count("path32_mrays")) {
        std::printf("baker Mrays/s / bench-rays incoherent closest-hit Mrays/s = %.2f / %.2f = "
                    "%.2f (target >= 0.7)\n",
                    r.at("path32_mrays"), r.at("rays_closest"),
                    r.at("path32_mrays") / r.at("rays_closest"));
    }
    return 0;
}
