#include "probekit/formats/check.hpp"

#include <cstdio>
#include <cstdlib>

namespace probekit::detail {

void checkFailed(const char* condition, const char* detail, const char* function, const char* file,
                 int line) {
    if (detail != nullptr) {
        std::fprintf(stderr, "probekit: precondition failed in %s: %s (%s) at %s:%d\n", function,
                     condition, detail, file, line);
    } else {
        std::fprintf(stderr, "probekit: precondition failed in %s: %s at %s:%d\n", function,
                     condition, file, line);
    }
    std::fflush(stderr);
    std::abort();
}

} // namespace probekit::detail
