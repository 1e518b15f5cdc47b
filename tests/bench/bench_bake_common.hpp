// Shared pieces of the baker benchmarks (one executable, several files).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <thread>

#include "probekit/baker/scene.hpp"

namespace probekit::bench {

// Figures recorded by benchmarks, printed as ratios after all have run.
std::map<std::string, double>& results();
// The shared Cornell box (../shared/scenes/cornell-box), loaded once.
const baker::Scene& cornellScene();
uint32_t benchThreads();

} // namespace probekit::bench
