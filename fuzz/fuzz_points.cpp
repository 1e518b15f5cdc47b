// libFuzzer target: the receiver points CSV of `probekit sample` through parsePointsCsv. Beyond
// "no crash, no sanitizer report": every point it returns is finite with a unit normal, and an
// error message names the source.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include <glm/geometric.hpp>

#include "points_csv.hpp"

namespace {

// Prints why the input is a failure, then aborts so libFuzzer saves it.
[[noreturn]] void fail(const char* why) {
    std::fprintf(stderr, "fuzz_points: %s\n", why);
    std::abort();
}

bool finite(glm::vec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    // A small point limit, so the limit's own error path is reached too.
    const auto points = probekit::cli::parsePointsCsv(text, "fuzz.csv", 64);
    if (!points) {
        if (!points.error().message.starts_with("fuzz.csv")) {
            fail("an error message does not name the file");
        }
        return 0;
    }
    if (points.value().size() > 64) {
        fail("more points than the limit were returned");
    }
    for (const probekit::cli::SamplePoint& p : points.value()) {
        if (!finite(p.position) || !finite(p.normal) ||
            std::abs(glm::length(p.normal) - 1.0f) > 1e-4f) {
            fail("a point with a non-finite position or a normal that is not unit length");
        }
    }
    return 0;
}
