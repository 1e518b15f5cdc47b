// libFuzzer target: bake config JSON through parseBakeConfig. A config that parses must also pass
// validateBakeConfig (parsing applies the same table) and its description must parse back to a
// config with the same description.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "probekit/baker/bake.hpp"
#include "probekit/baker/settings.hpp"

namespace {

// Prints why the input is a failure, then aborts so libFuzzer saves it.
[[noreturn]] void fail(const char* why) {
    std::fprintf(stderr, "fuzz_config: %s\n", why);
    std::abort();
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const auto config = probekit::baker::parseBakeConfig(text, "fuzz.json", "/nonexistent");
    if (!config) {
        return 0;
    }
    if (!probekit::baker::validateBakeConfig(config.value())) {
        fail("parsing accepted a config that validation rejects");
    }
    const std::string described = probekit::baker::describeConfig(config.value());
    const auto reparsed = probekit::baker::parseBakeConfig(described, "described", "/nonexistent");
    if (!reparsed || probekit::baker::describeConfig(reparsed.value()) != described) {
        fail("describeConfig wrote something parseBakeConfig does not read back");
    }
    return 0;
}
