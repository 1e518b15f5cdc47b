// probekit::baker::VplProbeIntegrator — one probe of the VPL method: the light arriving
// straight from the lights, the near field by paths, everything else from the VPLs.
//
//  * The path integrator (path_integrator.hpp) with VplConfig::directSamples directions and
//    nearDistance = VplConfig::nearField: emitters and sky seen from the probe (next-event
//    estimation and MIS at the probe, punctual lights as deltas), and full paths (up to
//    VplConfig::bounces vertices, Russian roulette) for directions whose first hit is nearer
//    than the near field. Directions hitting farther stop at that surface.
//  * The VPL gather (vpl_gather.hpp) for the light the farther surfaces reflect: VPLs nearer
//    than the near field are skipped, so the two parts partition the sphere by first-hit
//    distance (exactly, with visibility on).
//  * A probe whose near field covers more than kNearFieldBoostFraction of its directions (a
//    corner, a probe by a wall) is traced again with kNearFieldBoost x the directions: there
//    the near field's paths carry most of the light, and their noise would dominate.
//    With adaptive sampling (PathConfig::noiseTarget) the boost gives way to it: the gather
//    comes first (given no direct light, so its cut is at least as fine), and the direct part
//    is traced until its noise relative to the whole probe meets the target.
//
// Thread-safe and deterministic like its parts: the result depends only on (seed, volume,
// probe, position).
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "methods/path_integrator.hpp"
#include "methods/vpl_gather.hpp"
#include "probekit/baker/config.hpp"

namespace probekit::baker {

constexpr float kNearFieldBoostFraction = 0.4f;
constexpr uint32_t kNearFieldBoost = 8;

struct VplProbeSample {
    ProbeSample probe;    // direct + near field + VPLs; rays of every part
    uint32_t cutSize = 0; // clusters the gather used
};

class VplProbeIntegrator {
public:
    // `config` resolved (resolveVplConfig); `scene`, `tracer` and `gatherer` must outlive it.
    // `path` gives adaptive sampling's noise target and cap for the direct part.
    VplProbeIntegrator(const Scene& scene, const RayTracer& tracer, const VplGatherer& gatherer,
                       const VplConfig& config, const PathConfig& path, sh::Order order);

    VplProbeSample bakeProbe(glm::vec3 position, uint64_t seed, uint32_t volume_index,
                             uint64_t probe_index) const;

private:
    // The direct part's path settings: `samples` directions, config.bounces; `adaptive` (null:
    // fixed sampling) gives adaptive sampling's target, cap and floor.
    static PathConfig directConfig(const VplConfig& config, uint32_t samples,
                                   const PathConfig* adaptive);

    PathIntegrator m_direct;
    PathIntegrator m_boosted;
    const VplGatherer& m_gatherer;
    sh::Order m_order;
};

} // namespace probekit::baker
