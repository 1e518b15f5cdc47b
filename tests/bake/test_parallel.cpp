// Tests of the baker's parallel loop (baker/src/trace/parallel.hpp) and of the bake's progress
// reports, which run on the calling thread while the loop's threads bake (BakeOptions::progress).
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/formats/pvol.hpp"
#include "trace/parallel.hpp"

using namespace probekit;
using namespace probekit::baker;

namespace {

// Index hits after a loop over `count` indices: each must be exactly 1.
std::vector<int> hits(const std::vector<std::atomic<int>>& counters) {
    std::vector<int> out;
    for (const std::atomic<int>& c : counters) {
        out.push_back(c.load());
    }
    return out;
}

} // namespace

TEST(ParallelLoop, EveryIndexExactlyOnceForAnyThreadCountAndChunk) {
    for (const size_t count : {size_t(0), size_t(1), size_t(10), size_t(1000)}) {
        for (const uint32_t threads : {1u, 2u, 3u, 8u}) {
            for (const size_t chunk : {size_t(0), size_t(1), size_t(4), size_t(7)}) {
                std::vector<std::atomic<int>> plain(count), watched(count);
                const auto body = [](std::vector<std::atomic<int>>& c) {
                    return [&c](size_t begin, size_t end) {
                        for (size_t i = begin; i < end; ++i) {
                            c[i].fetch_add(1);
                        }
                    };
                };
                parallelFor(count, threads, chunk, body(plain));
                parallelForWatched(count, threads, chunk, body(watched),
                                   std::chrono::milliseconds(1), [] {});
                const std::vector<int> once(count, 1);
                EXPECT_EQ(hits(plain), once) << count << " " << threads << " " << chunk;
                EXPECT_EQ(hits(watched), once) << count << " " << threads << " " << chunk;
            }
        }
    }
}

// The watched loop leaves the calling thread to watch(): the body runs only on the loop's
// threads, watch() only on the caller, at least once.
TEST(ParallelLoop, WatchedLoopWatchesOnTheCallingThreadOnly) {
    const std::thread::id caller = std::this_thread::get_id();
    std::atomic<int> body_on_caller{0};
    int watches = 0;
    bool watched_elsewhere = false;
    parallelForWatched(
        64, 2, 1,
        [&](size_t, size_t) {
            body_on_caller += std::this_thread::get_id() == caller;
            std::this_thread::sleep_for(std::chrono::microseconds(200));
        },
        std::chrono::milliseconds(1),
        [&] {
            ++watches;
            watched_elsewhere |= std::this_thread::get_id() != caller;
        });
    EXPECT_EQ(body_on_caller.load(), 0);
    EXPECT_GE(watches, 1);
    EXPECT_FALSE(watched_elsewhere);
}

// Progress is reported from the calling thread, the last report counts every probe, and
// asking for it changes nothing in the bake's output.
TEST(BakeProgressReports, FromTheCallingThreadEndingAtTheTotalWithTheSameOutput) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c;
    c.path.samples = 16;
    VolumeConfig v;
    v.resolution = glm::uvec3(4, 4, 2);
    c.volumes = {v};
    const std::thread::id caller = std::this_thread::get_id();
    std::vector<BakeProgress> reports;
    bool reported_elsewhere = false;
    BakeOptions with_progress;
    with_progress.threads = 2;
    with_progress.progress = [&](const BakeProgress& p) {
        reports.push_back(p);
        reported_elsewhere |= std::this_thread::get_id() != caller;
    };
    BakeOptions without_progress;
    without_progress.threads = 2;
    Result<BakeResult> a = bake(scene, c, with_progress);
    Result<BakeResult> b = bake(scene, c, without_progress);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_FALSE(reported_elsewhere);
    ASSERT_FALSE(reports.empty());
    EXPECT_EQ(reports.back().probesDone, a.value().stats.probes);
    EXPECT_EQ(reports.back().probesTotal, a.value().stats.probes);
    test::expectSameFileButTiming(a.value(), b.value());
}

// The total covers the whole bake from its first report: the second volume's planned probes
// are counted while the first bakes, so the ETA is the bake's, not the first volume's.
TEST(BakeProgressReports, TheTotalCoversEveryVolumeFromTheFirstReport) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c;
    c.path.samples = 16;
    VolumeConfig first;
    first.name = "first";
    first.resolution = glm::uvec3(4, 4, 2); // 32 probes
    VolumeConfig second;
    second.name = "second";
    second.resolution = glm::uvec3(2, 2, 2); // 8 probes
    c.volumes = {first, second};
    std::vector<BakeProgress> reports;
    BakeOptions options;
    options.threads = 2;
    options.progress = [&](const BakeProgress& p) { reports.push_back(p); };
    Result<BakeResult> r = bake(scene, c, options);
    ASSERT_TRUE(r.ok()) << r.error().message;
    ASSERT_FALSE(reports.empty());
    EXPECT_EQ(reports.front().probesTotal, 40u);
    for (size_t i = 1; i < reports.size(); ++i) {
        EXPECT_GE(reports[i].probesTotal, reports[i - 1].probesTotal) << i;
    }
    EXPECT_EQ(reports.back().probesTotal, r.value().stats.probes);
}
