#include "config_options.hpp"

#include <utility>

namespace probekit::cli {

Result<baker::BakeConfig> loadConfigOrDefaults(const std::string& path) {
    Result<baker::BakeConfig> loaded =
        path.empty() ? Result<baker::BakeConfig>(baker::BakeConfig{}) : baker::loadBakeConfig(path);
    if (!loaded) {
        return loaded;
    }
    baker::BakeConfig config = std::move(loaded).value();
    if (config.volumes.empty()) {
        config.volumes.push_back(baker::VolumeConfig{});
    }
    return config;
}

Result<baker::Environment> configEnvironment(const baker::BakeConfig& config,
                                             const std::string& config_path, bool from_env_flag) {
    Result<baker::Environment> environment =
        baker::makeEnvironment(config.environment, config.maxMemoryBytes);
    if (environment) {
        return environment;
    }
    const std::string where = from_env_flag         ? std::string("--env")
                              : config_path.empty() ? std::string("environment.file")
                                                    : config_path + ": environment.file";
    return makeError(environment.error().code, where + ": " + environment.error().message);
}

} // namespace probekit::cli
