// The bake config that `probekit bake`, `bench` and `bench-noise` start from: one place that
// reads --config (or takes the defaults) and gives it a volume to bake.
#pragma once

#include <string>

#include "probekit/baker/config.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::cli {

// The config at `path`, or the defaults when `path` is empty; with one default volume when it
// places none.
Result<baker::BakeConfig> loadConfigOrDefaults(const std::string& path);

} // namespace probekit::cli
