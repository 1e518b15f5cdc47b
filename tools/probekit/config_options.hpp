// The bake config that `probekit bake`, `bench` and `bench-noise` start from: one place that
// reads --config (or takes the defaults) and gives it a volume to bake.
#pragma once

#include <string>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::cli {

// The config at `path`, or the defaults when `path` is empty; with one default volume when it
// places none.
Result<baker::BakeConfig> loadConfigOrDefaults(const std::string& path);

// The config's environment, made (an image map read within its max_memory_mb). An error names
// where the map was given: `--env` when `from_env_flag`, else the config file (`config_path`,
// empty for the defaults) and its field environment.file.
Result<baker::Environment> configEnvironment(const baker::BakeConfig& config,
                                             const std::string& config_path,
                                             bool from_env_flag = false);

} // namespace probekit::cli
