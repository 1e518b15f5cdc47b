// LPV method on the shared Cornell box: accuracy against the Cycles reference and wall time
// against the path method, measured in one run.
//
//   ./build/tests/probekit_bench_bake --benchmark_filter='Lpv'
//
// Accuracy is the band-limited relative RMSE of the baker test (BakeCornell): E from each
// probe's L2 SH at the 64 reference normals against E_L2 at the 8 reference points, with a
// 1x1x1 volume (one probe) at each point. The method's targets: with default settings, rel RMSE
// <= 20%, and a 16x16x16 volume over the box baked in <= 3% of the path method's time at 4096
// samples. Each benchmark prints its table; the counters carry the same figures.
#include <cstdio>
#include <optional>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_bake_common.hpp"
#include "probekit/baker/bake.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace {

// A 16x16x16 volume over the box with the given method.
BakeConfig volume16(Method method) {
    BakeConfig c;
    VolumeConfig v;
    v.resolution = glm::uvec3(16);
    c.volumes = {v};
    c.method = method;
    return c;
}

// (1) Default settings at the reference points.
void BM_LpvCornellDefault(benchmark::State& state) {
    for (auto _ : state) {
        BakeConfig config = bench::referenceProbes();
        config.method = Method::Lpv;
        Result<BakeResult> r = bench::bakeCornell(config);
        if (!r) {
            state.SkipWithError(r.error().message.c_str());
            return;
        }
        const double error = bench::relRmse(bench::probeIrradiance(r.value()),
                                            bench::cornellReference().irradianceL2);
        state.counters["rel_rmse"] = error;
        state.counters["bake_s"] = r.value().stats.seconds;
        bench::results()["lpv_default_rmse"] = error;
        std::printf("[lpv cornell] defaults (grid 32, 32 iterations, 1 cascade, occlusion on, "
                    "%llu VPLs): rel RMSE %.4f (target <= 0.20), %.2f s for the 8 reference "
                    "probes\n",
                    static_cast<unsigned long long>(r.value().stats.vpls), error,
                    r.value().stats.seconds);
    }
}
BENCHMARK(BM_LpvCornellDefault)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// (2) Grid x iterations: error at the reference points, and the wall time of the 16^3 volume
// (one propagation; the reference bake propagates once per point volume).
void BM_LpvCornellGridSweep(benchmark::State& state) {
    for (auto _ : state) {
        std::printf("[lpv cornell] grid x iterations (occlusion on, 1 cascade):\n"
                    "   grid  iterations  rel RMSE  16^3 bake s\n");
        for (uint32_t grid : {16u, 32u, 64u}) {
            for (uint32_t iterations : {grid / 2, grid, 2 * grid}) {
                BakeConfig points = bench::referenceProbes();
                points.method = Method::Lpv;
                points.lpv.grid = grid;
                points.lpv.iterations = iterations;
                BakeConfig volume = volume16(Method::Lpv);
                volume.lpv = points.lpv;
                Result<BakeResult> r = bench::bakeCornell(points);
                Result<BakeResult> v = bench::bakeCornell(volume);
                if (!r || !v) {
                    state.SkipWithError((r ? v : r).error().message.c_str());
                    return;
                }
                const double error = bench::relRmse(bench::probeIrradiance(r.value()),
                                                    bench::cornellReference().irradianceL2);
                std::printf("   %4u  %10u  %8.4f  %11.3f\n", grid, iterations, error,
                            v.value().stats.seconds);
            }
        }
    }
}
BENCHMARK(BM_LpvCornellGridSweep)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// (3) A 16x16x16 volume over the box: LPV at default settings against the path method at 4096
// samples, wall time. The machine is shared and its load drifts, so the bakes alternate and
// the ratio is of the summed times (both see the same load on average).
void BM_LpvVsPath16Cubed(benchmark::State& state) {
    constexpr int kRounds = 2;
    for (auto _ : state) {
        const BakeConfig lpv_config = volume16(Method::Lpv);
        BakeConfig path_config = volume16(Method::Path);
        path_config.path.samples = 4096;
        const std::optional<bench::VersusPath> timed = bench::timeAgainstPath(
            state, "lpv", 3, "lpv16_ratio", lpv_config, path_config, kRounds);
        if (!timed) {
            return;
        }
        std::printf("[lpv cornell] 16^3: lpv (defaults) %.3f s, path at 4096 samples %.2f s "
                    "(means of %d): ratio %.4f (target <= 0.03), %u threads\n",
                    timed->seconds / kRounds, timed->pathSeconds / kRounds, kRounds, timed->ratio,
                    bench::benchThreads());
    }
}
BENCHMARK(BM_LpvVsPath16Cubed)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

} // namespace
