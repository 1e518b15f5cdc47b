// Shared pieces of the baker benchmarks (one executable, several files).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <benchmark/benchmark.h>
#include <glm/vec3.hpp>

#include "probekit/baker/bake.hpp"
#include "probekit/baker/scene.hpp"

namespace probekit::bench {

// Figures recorded by benchmarks, printed as ratios after all have run.
std::map<std::string, double>& results();
// The shared Cornell box (../shared/scenes/cornell-box), loaded once.
const baker::Scene& cornellScene();
uint32_t benchThreads();

// The Cycles reference of the shared Cornell box (reference.json), loaded once: the points,
// the 64 normals and E_L2 [point][normal].
struct CornellReference {
    std::vector<glm::vec3> points;
    std::vector<glm::vec3> normals;
    std::vector<std::vector<glm::dvec3>> irradianceL2;
};
const CornellReference& cornellReference();
// One probe exactly at each reference point (a 1x1x1 centre-mode float volume around it), as
// the baker test BakeCornell does.
baker::BakeConfig referenceProbes();
// E of each probe of a referenceProbes() bake at the reference normals: [point][normal].
std::vector<std::vector<glm::dvec3>> probeIrradiance(const baker::BakeResult& r);
// sqrt(sum |e - reference|^2 / sum |reference|^2) over points, normals and channels.
double relRmse(const std::vector<std::vector<glm::dvec3>>& e,
               const std::vector<std::vector<glm::dvec3>>& reference);
// A bake of the shared Cornell box on benchThreads() threads.
Result<baker::BakeResult> bakeCornell(const baker::BakeConfig& config);

// A method's bake time against the path method's, summed over alternating Cornell bakes.
struct VersusPath {
    double seconds = 0.0;
    double pathSeconds = 0.0;
    double ratio = 0.0; // seconds / pathSeconds
};
// `rounds` rounds of bakeCornell(config) then bakeCornell(path_config) (alternating, so both see
// the same load on average), each printed as "[<method> cornell] 16^3 round ..." with the
// method's seconds to `digits` decimals, and `each` (when set) called with the method's result.
// Records the counters `<method>_s` and path4096_s (means per round) and time_ratio on `state`,
// and the ratio as results()[ratio_key]. When a bake fails: skips `state` with the first error
// (the method's before the path's) and returns nothing.
std::optional<VersusPath>
timeAgainstPath(benchmark::State& state, const std::string& method, int digits,
                const std::string& ratio_key, const baker::BakeConfig& config,
                const baker::BakeConfig& path_config, int rounds,
                const std::function<void(const baker::BakeResult& result)>& each = {});

} // namespace probekit::bench
