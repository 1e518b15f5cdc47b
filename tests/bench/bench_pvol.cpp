// .pvol load throughput against the raw read that bounds it.
//
// One 64x64x64 L2 float volume (about 29 MiB) is written to a temporary file once; then
//   BM_PlainRead   reads the file's bytes into a std::vector exactly as readPvol does
//                  (open, fstat, read loop, close) and nothing else;
//   BM_ReadPvol    readPvol on the same file: the same read, the checksum pass, the copies;
//   BM_DecodePvol  decodePvol on bytes already in memory (checksum + copies, no I/O);
//   BM_Xxhash64    the checksum pass alone.
// All report bytes/s of file size. The machine is shared and noisy, so the figure that matters
// is the ratio readPvol / plain read measured in the same run, printed at the end (target: at
// least 0.5). Run a Release build: ./probekit_bench_formats [--benchmark_repetitions=5]
#include <benchmark/benchmark.h>

#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "probekit/formats/pvol.hpp"

namespace {

using namespace probekit;

std::filesystem::path g_path;
std::vector<uint8_t> g_bytes; // the file's bytes, for the in-memory benchmarks

// The same read readPvol performs, so the two benchmarks differ only by decoding.
std::vector<uint8_t> readWholeFile(const std::filesystem::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        return {};
    }
    struct stat info {};
    std::vector<uint8_t> bytes;
    if (::fstat(fd, &info) == 0) {
        bytes.resize(size_t(info.st_size));
        size_t done = 0;
        while (done < bytes.size()) {
            const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
            if (n < 0 && errno == EINTR) {
                continue;
            }
            if (n <= 0) {
                bytes.resize(done);
                break;
            }
            done += size_t(n);
        }
    }
    ::close(fd);
    return bytes;
}

void BM_PlainRead(benchmark::State& state) {
    for (auto _ : state) {
        std::vector<uint8_t> bytes = readWholeFile(g_path);
        if (bytes.size() != g_bytes.size()) {
            state.SkipWithError("short read");
            break;
        }
        benchmark::DoNotOptimize(bytes.data());
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(g_bytes.size()));
}

void BM_ReadPvol(benchmark::State& state) {
    for (auto _ : state) {
        Result<PvolFile> file = readPvol(g_path);
        if (!file) {
            state.SkipWithError(file.error().message.c_str());
            break;
        }
        benchmark::DoNotOptimize(file.value().volumes.data());
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(g_bytes.size()));
}

void BM_DecodePvol(benchmark::State& state) {
    for (auto _ : state) {
        Result<PvolFile> file = decodePvol(g_bytes, "bench.pvol");
        if (!file) {
            state.SkipWithError(file.error().message.c_str());
            break;
        }
        benchmark::DoNotOptimize(file.value().volumes.data());
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(g_bytes.size()));
}

void BM_Xxhash64(benchmark::State& state) {
    for (auto _ : state) {
        benchmark::DoNotOptimize(xxhash64(g_bytes));
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(g_bytes.size()));
}

// Console output as usual, plus each benchmark's throughput kept for the closing ratio. With
// --benchmark_repetitions the median is used.
class RatioReporter : public benchmark::ConsoleReporter {
public:
    void ReportRuns(const std::vector<Run>& runs) override {
        ConsoleReporter::ReportRuns(runs);
        for (const Run& run : runs) {
            const auto rate = run.counters.find("bytes_per_second");
            if (rate == run.counters.end() || run.error_occurred) {
                continue;
            }
            const std::string& name = run.run_name.function_name;
            if (run.run_type == Run::RT_Aggregate && run.aggregate_name == "median") {
                m_bytesPerSecond[name] = rate->second.value;
                m_haveMedian[name] = true;
            } else if (run.run_type == Run::RT_Iteration && !m_haveMedian[name]) {
                m_bytesPerSecond[name] = rate->second.value;
            }
        }
    }

    // bytes/s of a benchmark, 0 when it did not run.
    double throughput(const std::string& name) const {
        const auto it = m_bytesPerSecond.find(name);
        return it == m_bytesPerSecond.end() ? 0.0 : it->second;
    }

private:
    std::map<std::string, double> m_bytesPerSecond;
    std::map<std::string, bool> m_haveMedian;
};

PvolFile makeBenchFile() {
    VolumeDesc desc;
    desc.name = "bench_64x64x64_L2_float";
    desc.grid = grid::GridLayout(grid::Aabb{glm::vec3(-8.0f), glm::vec3(8.0f)}, glm::uvec3(64),
                                 grid::PositionMode::Center);
    desc.shOrder = sh::Order::L2;
    desc.storage = Storage::Float32;
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        for (int k = 0; k < sh::kMaxCoefficients; ++k) {
            // Varied, non-zero data: all-zero pages could be special-cased below us.
            probes[i].rgb[k] = glm::vec3(float(i % 977) * 0.01f + float(k), float(k) - 0.5f,
                                         float(i % 31) * -0.25f);
        }
    }
    PvolFile file;
    file.metadata.toolVersion = "probekit bench";
    file.metadata.method = "synthetic";
    file.metadata.parametersJson = "{}";
    file.volumes.push_back(makeVolume(desc, probes).value());
    return file;
}

} // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
        return 1;
    }

    g_path = std::filesystem::temp_directory_path() /
             ("probekit_bench_" + std::to_string(::getpid()) + ".pvol");
    if (auto written = writePvol(g_path, makeBenchFile()); !written) {
        std::fprintf(stderr, "cannot write the benchmark file: %s\n",
                     written.error().message.c_str());
        return 1;
    }
    g_bytes = readWholeFile(g_path);

    benchmark::RegisterBenchmark("BM_PlainRead", BM_PlainRead)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("BM_ReadPvol", BM_ReadPvol)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("BM_DecodePvol", BM_DecodePvol)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("BM_Xxhash64", BM_Xxhash64)->Unit(benchmark::kMillisecond);

    RatioReporter reporter;
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();

    std::error_code ignored;
    std::filesystem::remove(g_path, ignored);

    const double plain = reporter.throughput("BM_PlainRead");
    const double load = reporter.throughput("BM_ReadPvol");
    if (plain > 0.0 && load > 0.0) {
        std::printf("\nfile %.1f MiB: plain read %.2f GB/s, readPvol %.2f GB/s\n",
                    double(g_bytes.size()) / (1024.0 * 1024.0), plain * 1e-9, load * 1e-9);
        std::printf("readPvol / plain read throughput = %.3f (target >= 0.5)\n", load / plain);
    }
    return 0;
}
