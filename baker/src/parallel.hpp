// The baker's one parallel loop. Bakes promise bit-identical output for any thread count
// (ARCHITECTURE.md, "Output is deterministic"), so a body may write only results that depend
// on its own indices; the loop then decides nothing but who computes what.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <thread>
#include <vector>

namespace probekit::baker {

// Threads a loop uses for `threads` = 0: every hardware thread (at least one).
inline uint32_t resolveThreads(uint32_t threads) {
    return threads ? threads : std::max(1u, std::thread::hardware_concurrency());
}

// Calls body(begin, end) on ranges of at most `chunk` indices covering [0, count), handed out
// in order as threads become free (probes cost very different amounts: inside walls, near
// lights), on resolveThreads(threads) threads of which the calling thread is one. Returns when
// every range is done.
template <class Body>
void parallelFor(size_t count, uint32_t threads, size_t chunk, const Body& body) {
    chunk = std::max<size_t>(chunk, 1);
    const size_t workers =
        std::min<size_t>(resolveThreads(threads), std::max<size_t>(1, (count + chunk - 1) / chunk));
    std::atomic<size_t> next{0};
    const auto work = [&] {
        for (size_t begin = next.fetch_add(chunk); begin < count; begin = next.fetch_add(chunk)) {
            body(begin, std::min(count, begin + chunk));
        }
    };
    std::vector<std::thread> pool;
    for (size_t t = 1; t < workers; ++t) {
        pool.emplace_back(work);
    }
    work();
    for (std::thread& t : pool) {
        t.join();
    }
}

} // namespace probekit::baker
