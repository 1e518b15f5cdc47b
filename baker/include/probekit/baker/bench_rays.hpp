// probekit::baker — raw ray throughput of the baker's tracer on a scene ("bench-rays").
//
// The yardstick for the integrators: the path tracer's rays per second are compared with what
// the same Embree scene and the same single-ray queries (rtcIntersect1 / rtcOccluded1 behind
// RayTracer::intersect / occluded) achieve on incoherent rays, so the ratio isolates the
// integrator's own overhead. Benchmarks report ratios measured in one run; nothing here is
// asserted against a wall-clock threshold.
#pragma once

#include <cstdint>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

struct RayThroughput {
    double closestHitMraysPerSec = 0; // closest-hit queries, millions of rays per second
    double occlusionMraysPerSec = 0;  // any-hit (occlusion) queries, millions of rays per second
    uint64_t rays = 0;                // rays traced per query kind
    uint32_t threads = 0;             // threads that traced them (fewer than asked for when
                                      // the system refused to start some)
};

// Builds the tracer for `scene` (not timed), then traces `rays` incoherent rays of each kind on
// `threads` threads (0: std::thread::hardware_concurrency()): origins uniform in the scene
// bounds shrunk by 1% per side, directions uniform on the sphere, unbounded length. Rays are
// generated per thread before the clock starts (each thread cycles over at most 2^20 of its
// own), from a fixed seed, so two runs trace the same rays. A thread the system refuses to
// start is left out with its share of the rays (`rays` and `threads` of the result say what was
// traced). Fails if `rays` is 0, the tracer cannot be built or no thread can be started.
Result<RayThroughput> measureRayThroughput(const Scene& scene, uint64_t rays, uint32_t threads);

} // namespace probekit::baker
