// VPL method on the shared Cornell box: accuracy against the Cycles reference and wall time
// against the path method, measured in one run.
//
//   ./build/tests/probekit_bench_bake --benchmark_filter='Vpl'
//
// Accuracy is the band-limited relative RMSE of the baker test (BakeCornell): E from each
// probe's L2 SH at the 64 reference normals against E_L2 at the 8 reference points, with a
// 1x1x1 volume (one probe) at each point. The method's targets: with default settings, rel RMSE
// <= 5%, and a 16x16x16 volume over the box baked in <= 10% of the path method's time at 4096
// samples. Each benchmark prints its table; the counters carry the same figures.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_bake_common.hpp"
#include "probekit/baker/bake.hpp"

using namespace probekit;
using namespace probekit::baker;
using bench::bakeCornell;
using bench::cornellReference;
using bench::probeIrradiance;
using bench::referenceProbes;
using bench::relRmse;

namespace {

// Mean over points, normals and channels of (a - b), relative to the mean of `reference`.
double relMeanDifference(const std::vector<std::vector<glm::dvec3>>& a,
                         const std::vector<std::vector<glm::dvec3>>& b,
                         const std::vector<std::vector<glm::dvec3>>& reference) {
    double diff = 0.0, mean = 0.0;
    for (size_t p = 0; p < a.size(); ++p) {
        for (size_t k = 0; k < a[p].size(); ++k) {
            for (int c = 0; c < 3; ++c) {
                diff += a[p][k][c] - b[p][k][c];
                mean += reference[p][k][c];
            }
        }
    }
    return diff / mean;
}

// (1) Default settings at the reference points.
void BM_VplCornellDefault(benchmark::State& state) {
    BakeConfig config = referenceProbes();
    config.method = Method::Vpl;
    for (auto _ : state) {
        Result<BakeResult> r = bakeCornell(config);
        if (!r) {
            state.SkipWithError(r.error().message.c_str());
            return;
        }
        const double error = relRmse(probeIrradiance(r.value()), cornellReference().irradianceL2);
        state.counters["rel_rmse"] = error;
        state.counters["bake_s"] = r.value().stats.seconds;
        state.counters["vpls"] = double(r.value().stats.vpls);
        std::printf("[vpl cornell] default settings: %llu VPLs, rel RMSE vs E_L2 %.4f "
                    "(target <= 0.05), %.3f s\n",
                    static_cast<unsigned long long>(r.value().stats.vpls), error,
                    r.value().stats.seconds);
    }
}
BENCHMARK(BM_VplCornellDefault)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// (3) VPL count against error and time; the error averaged over seeds 1..4 (a single seed's
// error is itself noisy), the time of seed 1.
void BM_VplCornellCountSweep(benchmark::State& state) {
    constexpr int kSeeds = 4;
    for (auto _ : state) {
        std::printf("[vpl cornell] count sweep, default settings otherwise (%d seeds)\n"
                    "  %8s %8s %12s %12s %10s %10s\n",
                    kSeeds, "count", "vpls", "rel RMSE", "(min..max)", "seconds", "cut/probe");
        for (uint32_t count = 256; count <= 65536; count *= 4) {
            BakeConfig config = referenceProbes();
            config.method = Method::Vpl;
            config.vpl.count = count;
            double sum = 0.0, lo = INFINITY, hi = 0.0, seconds = 0.0, cut = 0.0;
            uint64_t vpls = 0;
            for (int seed = 1; seed <= kSeeds; ++seed) {
                config.seed = uint64_t(seed);
                Result<BakeResult> r = bakeCornell(config);
                if (!r) {
                    state.SkipWithError(r.error().message.c_str());
                    return;
                }
                const double e =
                    relRmse(probeIrradiance(r.value()), cornellReference().irradianceL2);
                sum += e;
                lo = std::min(lo, e);
                hi = std::max(hi, e);
                if (seed == 1) {
                    seconds = r.value().stats.seconds;
                    vpls = r.value().stats.vpls;
                    cut = r.value().stats.vplMeanCut;
                }
            }
            std::printf("  %8u %8llu %12.4f %5.3f..%5.3f %10.3f %10.1f\n", count,
                        static_cast<unsigned long long>(vpls), sum / kSeeds, lo, hi, seconds, cut);
            state.counters["rel_rmse_" + std::to_string(count)] = sum / kSeeds;
        }
    }
}
BENCHMARK(BM_VplCornellCountSweep)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// Clamping bias: for one VPL set (same seed) the clamped gathers differ from the unclamped
// one (unbiased over sets) only by the clamp, so mean(E_clamp - E_none) over seeds is the
// clamping bias. At 65536 VPLs, relative to the mean reference irradiance.
void BM_VplCornellClampBias(benchmark::State& state) {
    constexpr int kSeeds = 4;
    const VplClamp modes[] = {VplClamp::None, VplClamp::Distance, VplClamp::Spherical};
    for (auto _ : state) {
        std::printf("[vpl cornell] clamping at 65536 VPLs (%d seeds): rel RMSE vs E_L2, and bias "
                    "= mean(E_clamp - E_none) / mean E_L2\n",
                    kSeeds);
        std::vector<std::vector<std::vector<glm::dvec3>>> unclamped;
        for (const VplClamp mode : modes) {
            double error = 0.0, bias = 0.0;
            for (int seed = 1; seed <= kSeeds; ++seed) {
                BakeConfig config = referenceProbes();
                config.method = Method::Vpl;
                config.vpl.count = 65536;
                config.vpl.clamp = mode;
                config.seed = uint64_t(seed);
                Result<BakeResult> r = bakeCornell(config);
                if (!r) {
                    state.SkipWithError(r.error().message.c_str());
                    return;
                }
                const auto e = probeIrradiance(r.value());
                error += relRmse(e, cornellReference().irradianceL2) / kSeeds;
                if (mode == VplClamp::None) {
                    unclamped.push_back(e);
                } else {
                    bias += relMeanDifference(e, unclamped[size_t(seed - 1)],
                                              cornellReference().irradianceL2) /
                            kSeeds;
                }
            }
            std::printf("  %-10s rel RMSE %.4f  bias %+.5f\n", std::string(toString(mode)).c_str(),
                        error, bias);
            state.counters["rel_rmse_" + std::string(toString(mode))] = error;
            state.counters["bias_" + std::string(toString(mode))] = bias;
        }
    }
}
BENCHMARK(BM_VplCornellClampBias)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// (2) A 16x16x16 volume over the box: VPL at default settings against the path method at 4096
// samples, wall time. The machine is shared and its load drifts over seconds, so the two bakes
// alternate (vpl, path, vpl, path) and the ratio is of the summed times: both see the same
// load on average.
void BM_VplVsPath16Cubed(benchmark::State& state) {
    constexpr int kRounds = 2;
    for (auto _ : state) {
        BakeConfig vpl_config;
        VolumeConfig v;
        v.resolution = glm::uvec3(16);
        vpl_config.volumes = {v};
        vpl_config.method = Method::Vpl;
        BakeConfig path_config = vpl_config;
        path_config.method = Method::Path;
        path_config.path.samples = 4096;
        double cut = 0.0;
        uint64_t vpls = 0;
        const std::optional<bench::VersusPath> timed =
            bench::timeAgainstPath(state, "vpl", 2, "vpl16_ratio", vpl_config, path_config, kRounds,
                                   [&](const BakeResult& vpl) {
                                       vpls = vpl.stats.vpls;
                                       cut = vpl.stats.vplMeanCut;
                                   });
        if (!timed) {
            return;
        }
        std::printf("[vpl cornell] 16^3: vpl (default, %llu VPLs, %.1f clusters/probe) %.2f s, "
                    "path at 4096 samples %.2f s (means of %d): ratio %.4f (target <= 0.10), %u "
                    "threads\n",
                    static_cast<unsigned long long>(vpls), cut, timed->seconds / kRounds,
                    timed->pathSeconds / kRounds, kRounds, timed->ratio, bench::benchThreads());
    }
}
BENCHMARK(BM_VplVsPath16Cubed)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

} // namespace
