// The baker's one parallel loop. Bakes promise bit-identical output for any thread count
// (ARCHITECTURE.md, "Output is deterministic"), so a body may write only results that depend
// on its own indices; the loop then decides nothing but who computes what.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace probekit::baker {

// Threads a loop uses for `threads` = 0: every hardware thread (at least one).
inline uint32_t resolveThreads(uint32_t threads) {
    return threads ? threads : std::max(1u, std::thread::hardware_concurrency());
}

namespace detail {

// Threads that have work for `count` indices in ranges of `chunk`: at most one per range.
inline size_t loopThreads(size_t count, uint32_t threads, size_t chunk) {
    return std::min<size_t>(resolveThreads(threads),
                            std::max<size_t>(1, (count + chunk - 1) / chunk));
}

// Starts `started` threads that call body(begin, end) on ranges of at most `chunk` indices
// covering [0, count), handed out in order as threads become free, then runs
// caller(work, done) on the calling thread: work() takes ranges like the started threads,
// done(wait) waits up to `wait` for every started thread to run out of ranges and says whether
// they have. Returns after joining them.
template <class Body, class Caller>
void runRanges(size_t count, size_t chunk, size_t started, const Body& body, const Caller& caller) {
    std::atomic<size_t> next{0};
    const auto work = [&] {
        for (size_t begin = next.fetch_add(chunk); begin < count; begin = next.fetch_add(chunk)) {
            body(begin, std::min(count, begin + chunk));
        }
    };
    std::mutex mutex;
    std::condition_variable finished;
    size_t running = started;
    std::vector<std::thread> pool;
    for (size_t t = 0; t < started; ++t) {
        pool.emplace_back([&] {
            work();
            const std::lock_guard lock(mutex);
            --running;
            finished.notify_all();
        });
    }
    const auto done = [&](std::chrono::milliseconds wait) {
        std::unique_lock lock(mutex);
        return finished.wait_for(lock, wait, [&] { return running == 0; });
    };
    caller(work, done);
    for (std::thread& t : pool) {
        t.join();
    }
}

} // namespace detail

// Calls body(begin, end) on ranges of at most `chunk` indices covering [0, count), handed out
// in order as threads become free (probes cost very different amounts: inside walls, near
// lights), on resolveThreads(threads) threads of which the calling thread is one. Returns when
// every range is done.
template <class Body>
void parallelFor(size_t count, uint32_t threads, size_t chunk, const Body& body) {
    chunk = std::max<size_t>(chunk, 1);
    detail::runRanges(count, chunk, detail::loopThreads(count, threads, chunk) - 1, body,
                      [](const auto& work, const auto&) { work(); });
}

// parallelFor for a caller that reports while the loop runs (the bake's progress: called from
// the calling thread only, about every `interval`): the ranges go to resolveThreads(threads)
// started threads while the calling thread calls watch() every `interval` until they are
// done, returning as soon as they are. The body's results are those of parallelFor.
template <class Body, class Watch>
void parallelForWatched(size_t count, uint32_t threads, size_t chunk, const Body& body,
                        std::chrono::milliseconds interval, const Watch& watch) {
    chunk = std::max<size_t>(chunk, 1);
    detail::runRanges(count, chunk, detail::loopThreads(count, threads, chunk), body,
                      [&](const auto&, const auto& done) {
                          do {
                              watch();
                          } while (!done(interval));
                      });
}

} // namespace probekit::baker
