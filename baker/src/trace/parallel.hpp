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
#include <functional>
#include <mutex>
#include <new>
#include <system_error>
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

// Starts a thread running `entry`. The system may refuse (a process or address-space limit):
// std::thread's constructor then throws std::system_error (or std::bad_alloc for its state),
// and no thread exists.
inline std::thread startThread(std::function<void()> entry) {
    return std::thread(std::move(entry));
}

// What the loops start their threads with. Tests replace it with one that refuses after some
// threads, the one way to make thread creation fail deterministically (RLIMIT_NPROC does not
// bind root, which the tests run as).
inline std::atomic<std::thread (*)(std::function<void()>)> threadStarter{&startThread};

// Starts up to `wanted` threads running a copy of `entry` with the thread's index into `pool`,
// stopping at the first the system refuses: the caller runs with those that started. Returns
// how many did.
template <class Entry>
size_t startThreads(size_t wanted, std::vector<std::thread>& pool, const Entry& entry) {
    pool.reserve(wanted);
    for (size_t t = 0; t < wanted; ++t) {
        try {
            pool.push_back(threadStarter.load()([entry, t] { entry(t); }));
        } catch (const std::system_error&) {
            break;
        } catch (const std::bad_alloc&) {
            break;
        }
    }
    return pool.size();
}

// Starts up to `started` threads that call body(begin, end) on ranges of at most `chunk`
// indices covering [0, count), handed out in order as threads become free, then runs
// caller(work, done) on the calling thread: work() takes ranges like the started threads,
// done(wait) waits up to `wait` for every started thread to run out of ranges and says whether
// they have. The calling thread then takes whatever ranges are left, which is all of them when
// no thread could be started, and returns after joining the threads. Which thread runs a range
// never changes its result, so fewer threads than asked for give the same output.
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
    // Joins every started thread however this function is left (a body that throws on the
    // calling thread included): a joinable std::thread must never be destroyed.
    struct JoinAll {
        std::vector<std::thread>& threads;
        ~JoinAll() {
            for (std::thread& t : threads) {
                if (t.joinable()) {
                    t.join();
                }
            }
        }
    } join_all{pool};
    const size_t refused = started - startThreads(started, pool, [&](size_t) {
                               work();
                               const std::lock_guard lock(mutex);
                               --running;
                               finished.notify_all();
                           });
    if (refused > 0) {
        const std::lock_guard lock(mutex);
        running -= refused;
    }
    const auto done = [&](std::chrono::milliseconds wait) {
        std::unique_lock lock(mutex);
        return finished.wait_for(lock, wait, [&] { return running == 0; });
    };
    caller(work, done);
    work();
}

} // namespace detail

// Calls body(begin, end) on ranges of at most `chunk` indices covering [0, count), handed out
// in order as threads become free (probes cost very different amounts: inside walls, near
// lights), on resolveThreads(threads) threads of which the calling thread is one (fewer when
// the system refuses to start some: the calling thread always runs). Returns when every range
// is done.
template <class Body>
void parallelFor(size_t count, uint32_t threads, size_t chunk, const Body& body) {
    chunk = std::max<size_t>(chunk, 1);
    detail::runRanges(count, chunk, detail::loopThreads(count, threads, chunk) - 1, body,
                      [](const auto& work, const auto&) { work(); });
}

// parallelFor for a caller that reports while the loop runs (the bake's progress: called from
// the calling thread only, about every `interval`): the ranges go to resolveThreads(threads)
// started threads while the calling thread calls watch() every `interval` until they are
// done, returning as soon as they are. The body's results are those of parallelFor. When no
// thread can be started, watch() is called once and the calling thread runs every range.
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
