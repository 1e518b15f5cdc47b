// CPU reference sampler throughput: VolumeSet::irradiance per sample on one dense 32^3 L2
// volume (float, half, float with visibility), 4096 fixed random points per iteration.
// This is the path that calls Volume::texel for every plane of every tap, so it is where an
// always-on check on a per-probe accessor would show (ARCHITECTURE.md, "Preconditions"):
// compare two builds by running them alternately in one session, never against a figure from
// another day. Run a Release build: ./probekit_bench_sampler [--benchmark_repetitions=5]
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "probekit/runtime/sampler.hpp"

namespace {

using namespace probekit;

constexpr size_t kPoints = 4096;

Volume benchVolume(Storage storage, bool with_visibility) {
    VolumeDesc desc;
    desc.name = "bench";
    desc.grid = grid::GridLayout({glm::vec3(-2.0f), glm::vec3(2.0f)}, glm::uvec3(32),
                                 grid::PositionMode::Center);
    desc.storage = storage;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (sh::ShRgb& p : probes) {
        for (glm::vec3& c : p.rgb) {
            c = glm::vec3(unit(rng), unit(rng), unit(rng));
        }
    }
    std::vector<uint8_t> bytes(with_visibility ? probes.size() * visibility::kBytesPerProbe : 0);
    for (uint8_t& q : bytes) {
        q = uint8_t(rng() & 255u);
    }
    return makeVolume(desc, probes, {}, bytes).value();
}

template <Storage kStorage, bool kVisibility>
void BM_Irradiance(benchmark::State& state) {
    const runtime::VolumeSet set({benchVolume(kStorage, kVisibility)});
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> coord(-2.0f, 2.0f);
    std::vector<glm::vec3> points(kPoints);
    for (glm::vec3& p : points) {
        p = glm::vec3(coord(rng), coord(rng), coord(rng));
    }
    const glm::vec3 normal(0.0f, 1.0f, 0.0f);
    glm::vec3 sum(0.0f);
    for (auto _ : state) {
        for (const glm::vec3& p : points) {
            sum += set.irradiance(p, normal);
        }
    }
    benchmark::DoNotOptimize(sum);
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(kPoints));
}

BENCHMARK(BM_Irradiance<Storage::Float32, false>)->Name("BM_Irradiance/float");
BENCHMARK(BM_Irradiance<Storage::Float16, false>)->Name("BM_Irradiance/half");
BENCHMARK(BM_Irradiance<Storage::Float32, true>)->Name("BM_Irradiance/float_visibility");

} // namespace

BENCHMARK_MAIN();
