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

} // namespace probekit::cli
