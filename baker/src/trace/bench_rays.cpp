#include "probekit/baker/bench_rays.hpp"

#include <algorithm>
#include <barrier>
#include <chrono>
#include <cmath>
#include <numbers>
#include <thread>
#include <vector>

#include "trace/parallel.hpp"
#include "trace/ray_tracer.hpp"
#include "trace/rng.hpp"

namespace probekit::baker {

namespace {

// Fixed so that two runs trace the same rays.
constexpr uint64_t kBenchSeed = 0xbe0c4a75ull;
// Rays generated per thread before timing; threads asked for more cycle over them (bounded
// memory: 24 MiB per thread).
constexpr uint64_t kMaxPregeneratedRays = uint64_t(1) << 20;
// Origins stay 1% of the extent inside each face of the bounds.
constexpr float kBoundsShrink = 0.01f;

struct Ray {
    glm::vec3 origin;
    glm::vec3 dir;
};

std::vector<Ray> generateRays(const grid::Aabb& bounds, uint64_t count, uint32_t thread) {
    const glm::vec3 margin = kBoundsShrink * bounds.size();
    const glm::vec3 low = bounds.min + margin;
    const glm::vec3 extent = bounds.size() - 2.0f * margin;
    Rng rng(hashKeys(kBenchSeed, thread));
    std::vector<Ray> rays(count);
    for (Ray& ray : rays) {
        ray.origin = low + extent * glm::vec3(rng.uniform(), rng.uniform(), rng.uniform());
        const float z = 1.0f - 2.0f * rng.uniform();
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const float phi = 2.0f * std::numbers::pi_v<float> * rng.uniform();
        ray.dir = glm::vec3(r * std::cos(phi), r * std::sin(phi), z);
    }
    return rays;
}

} // namespace

Result<RayThroughput> measureRayThroughput(const Scene& scene, uint64_t rays, uint32_t threads) {
    if (rays == 0) {
        return makeError(ErrorCode::InvalidArgument, "bench-rays: the ray count must be positive");
    }
    threads = uint32_t(std::min<uint64_t>(resolveThreads(threads), rays));
    Result<std::unique_ptr<RayTracer>> built = RayTracer::create(scene);
    if (!built) {
        return built.error();
    }
    const RayTracer& tracer = *built.value();

    // Phases, separated by barriers that the timing thread also joins: generate | closest hit |
    // occlusion. The clock runs between the barriers around a phase, so generation and thread
    // start-up stay outside it.
    // This is not the baker's parallel loop (parallel.hpp) on purpose: that loop starts its
    // threads inside the call and hands out ranges to whichever thread is free, which is right
    // for a bake's results (ARCHITECTURE.md, "Output is deterministic") but wrong for a rate.
    // Timed around it, thread start-up would count as tracing (a large share of a short run
    // such as the 20000 rays of the bench-rays test), and nothing would make every thread trace
    // its own pregenerated rays for the whole interval. The barrier starts the clock only once
    // every thread holds its rays and stops it when the last one is done.
    // A thread the system refuses to start (a process or address-space limit) is left out:
    // its share of the rays is dropped from the barrier and from the count reported.
    std::barrier sync(std::ptrdiff_t(threads) + 1);
    const auto share = [&](size_t t) { return rays / threads + (t < rays % threads ? 1 : 0); };
    std::vector<std::thread> workers;
    const size_t started = detail::startThreads(threads, workers, [&](size_t t) {
        const ScopedFloatMode float_mode;
        const uint64_t count = share(t);
        const std::vector<Ray> pool =
            generateRays(scene.bounds, std::min(count, kMaxPregeneratedRays), uint32_t(t));
        sync.arrive_and_wait();
        for (uint64_t i = 0; i < count; ++i) {
            const Ray& ray = pool[i % pool.size()];
            // The query is an opaque library call: its result can be dropped.
            (void)tracer.intersect(ray.origin, ray.dir);
        }
        sync.arrive_and_wait();
        sync.arrive_and_wait();
        for (uint64_t i = 0; i < count; ++i) {
            const Ray& ray = pool[i % pool.size()];
            (void)tracer.occluded(ray.origin, ray.dir, kInfinity);
        }
        sync.arrive_and_wait();
    });
    if (started == 0) {
        return makeError(ErrorCode::Io, "bench-rays: the system refused to start a thread");
    }
    uint64_t traced = 0;
    for (size_t t = 0; t < threads; ++t) {
        if (t < started) {
            traced += share(t);
        } else {
            sync.arrive_and_drop();
        }
    }
    using Clock = std::chrono::steady_clock;
    sync.arrive_and_wait();
    const Clock::time_point closest_start = Clock::now();
    sync.arrive_and_wait();
    const Clock::time_point closest_end = Clock::now();
    sync.arrive_and_wait();
    const Clock::time_point occlusion_start = Clock::now();
    sync.arrive_and_wait();
    const Clock::time_point occlusion_end = Clock::now();
    for (std::thread& worker : workers) {
        worker.join();
    }

    const auto seconds = [](Clock::time_point a, Clock::time_point b) {
        return std::max(1e-9, std::chrono::duration<double>(b - a).count());
    };
    RayThroughput result;
    result.rays = traced;
    result.threads = uint32_t(started);
    result.closestHitMraysPerSec = double(traced) / seconds(closest_start, closest_end) * 1e-6;
    result.occlusionMraysPerSec = double(traced) / seconds(occlusion_start, occlusion_end) * 1e-6;
    return result;
}

} // namespace probekit::baker
