// Tests of the baker's parallel loop (baker/src/trace/parallel.hpp) and of the bake's progress
// reports, which run on the calling thread while the loop's threads bake (BakeOptions::progress).
#include <atomic>
#include <chrono>
#include <functional>
#include <system_error>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/bench_rays.hpp"
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

// One 4 x 4 x 2 volume (32 probes, 8 of the bake's ranges of 4) at 16 samples.
BakeConfig smallConfig() {
    BakeConfig c;
    c.path.samples = 16;
    VolumeConfig v;
    v.resolution = glm::uvec3(4, 4, 2);
    c.volumes = {v};
    return c;
}

std::atomic<size_t> g_threads_allowed{0};
std::atomic<size_t> g_thread_starts{0};

// Starts the first g_threads_allowed threads asked for, then refuses as std::thread does when
// the system is at its process limit (EAGAIN).
std::thread refusingStarter(std::function<void()> entry) {
    if (g_thread_starts.fetch_add(1) >= g_threads_allowed) {
        throw std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again),
                                "test: thread refused");
    }
    return std::thread(std::move(entry));
}

// For its lifetime, the loops' threads come from refusingStarter with `allowed` threads.
struct RefuseThreadsAfter {
    explicit RefuseThreadsAfter(size_t allowed) {
        g_threads_allowed = allowed;
        g_thread_starts = 0;
        detail::threadStarter = &refusingStarter;
    }
    ~RefuseThreadsAfter() { detail::threadStarter = &detail::startThread; }
    RefuseThreadsAfter(const RefuseThreadsAfter&) = delete;
    RefuseThreadsAfter& operator=(const RefuseThreadsAfter&) = delete;
};

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
    const BakeConfig c = smallConfig();
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

namespace {

// Bakes on 2 threads, keeping every progress report.
Result<BakeResult> bakeReporting(const Scene& scene, const BakeConfig& c,
                                 std::vector<BakeProgress>& reports) {
    BakeOptions options;
    options.threads = 2;
    options.progress = [&](const BakeProgress& p) { reports.push_back(p); };
    return bake(scene, c, options);
}

} // namespace

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
    Result<BakeResult> r = bakeReporting(scene, c, reports);
    ASSERT_TRUE(r.ok()) << r.error().message;
    ASSERT_FALSE(reports.empty());
    EXPECT_EQ(reports.front().probesTotal, 40u);
    for (size_t i = 1; i < reports.size(); ++i) {
        EXPECT_GE(reports[i].probesTotal, reports[i - 1].probesTotal) << i;
    }
    EXPECT_EQ(reports.back().probesTotal, r.value().stats.probes);
}

// A bricked volume's refinement is expected from its first report: level 0's lattice and as
// many again per level to be tested (BakeProgress), replaced by the batches as they come, so
// the last report's total is the bake's probes.
TEST(BakeProgressReports, ABrickedVolumeExpectsItsRefinementFromTheFirstReport) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c;
    c.path.samples = 16;
    VolumeConfig v;
    v.layout = VolumeLayout::Bricked;
    v.resolution = glm::uvec3(2, 2, 2); // 7^3 = 343 level-0 lattice probes
    v.maxLevel = 2;
    v.refineError = 0.01f;
    c.volumes = {v};
    std::vector<BakeProgress> reports;
    Result<BakeResult> r = bakeReporting(scene, c, reports);
    ASSERT_TRUE(r.ok()) << r.error().message;
    ASSERT_FALSE(reports.empty());
    EXPECT_EQ(reports.front().probesTotal, 343u * 3u);
    EXPECT_GT(r.value().stats.probes, 343u); // it refined: the expectation was needed
    EXPECT_EQ(reports.back().probesTotal, r.value().stats.probes);
}

// When the system refuses threads (a process or address-space limit), both loops run on the
// threads that did start and the calling thread: every index still exactly once, no abort.
TEST(ParallelLoop, EveryIndexExactlyOnceWhenThreadsCannotBeStarted) {
    for (const size_t allowed : {size_t(0), size_t(1)}) {
        const RefuseThreadsAfter refuse(allowed);
        std::vector<std::atomic<int>> plain(1000), watched(1000);
        parallelFor(plain.size(), 4, 7, [&](size_t begin, size_t end) {
            for (size_t i = begin; i < end; ++i) {
                plain[i].fetch_add(1);
            }
        });
        // 3 threads asked for beyond the caller: `allowed` started, one refused.
        EXPECT_EQ(g_thread_starts.load(), allowed + 1) << allowed;
        g_thread_starts = 0;
        int watches = 0;
        parallelForWatched(
            watched.size(), 4, 7,
            [&](size_t begin, size_t end) {
                for (size_t i = begin; i < end; ++i) {
                    watched[i].fetch_add(1);
                }
            },
            std::chrono::milliseconds(1), [&] { ++watches; });
        EXPECT_EQ(g_thread_starts.load(), allowed + 1) << allowed;
        EXPECT_GE(watches, 1);
        const std::vector<int> once(1000, 1);
        EXPECT_EQ(hits(plain), once) << allowed;
        EXPECT_EQ(hits(watched), once) << allowed;
    }
}

// A bake whose threads the system refuses gives the file a normal bake gives, with and
// without progress reports (the watched loop).
TEST(ParallelLoop, BakeIsIdenticalWhenThreadsCannotBeStarted) {
    const Scene scene = test::generatedScene("cornell");
    const BakeConfig c = smallConfig();
    BakeOptions options;
    options.threads = 4;
    Result<BakeResult> normal = bake(scene, c, options);
    ASSERT_TRUE(normal.ok()) << normal.error().message;
    for (const size_t allowed : {size_t(0), size_t(1)}) {
        const RefuseThreadsAfter refuse(allowed);
        Result<BakeResult> plain = bake(scene, c, options);
        BakeOptions watched = options;
        size_t reports = 0;
        watched.progress = [&](const BakeProgress&) { ++reports; };
        Result<BakeResult> with_progress = bake(scene, c, watched);
        ASSERT_TRUE(plain.ok() && with_progress.ok()) << allowed;
        EXPECT_GT(g_thread_starts.load(), allowed) << "the refusing starter was not used";
        EXPECT_GE(reports, 1u);
        test::expectSameFileButTiming(normal.value(), plain.value());
        test::expectSameFileButTiming(normal.value(), with_progress.value());
    }
}

// bench-rays traces on the threads that started, reporting how many and their rays; with none
// it fails with a message instead of aborting.
TEST(ParallelLoop, BenchRaysRunsOnTheThreadsThatStarted) {
    const Scene scene = test::generatedScene("cornell");
    {
        const RefuseThreadsAfter refuse(2);
        Result<RayThroughput> r = measureRayThroughput(scene, 3001, 3);
        ASSERT_TRUE(r.ok()) << r.error().message;
        EXPECT_EQ(r.value().threads, 2u);
        EXPECT_EQ(r.value().rays, 2001u); // 1001 + 1000: the refused third thread's 1000 left out
        EXPECT_GT(r.value().closestHitMraysPerSec, 0.0);
    }
    const RefuseThreadsAfter refuse(0);
    Result<RayThroughput> none = measureRayThroughput(scene, 3001, 3);
    ASSERT_FALSE(none.ok());
    EXPECT_NE(none.error().message.find("refused to start a thread"), std::string::npos)
        << none.error().message;
}
