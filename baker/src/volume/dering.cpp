// Deringing of the stored probes on the baker's parallel loop (dering.hpp).
#include "volume/dering.hpp"

#include <algorithm>

#include "probekit/formats/check.hpp"
#include "trace/parallel.hpp"

namespace probekit::baker {

void deringProbes(std::span<sh::ShRgb> probes, sh::Order order, Storage storage, uint32_t threads,
                  std::span<float> changes) {
    PK_CHECK(changes.size() == probes.size());
    const sh::Rounding rounding = deringRounding(storage);
    // A probe that needs no window costs three exact minima (~1 us), one that does ~40 us per
    // channel: chunks of 64 keep the threads busy without much handing out.
    constexpr size_t kChunk = 64;
    parallelFor(probes.size(), threads, kChunk, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            const sh::DeringResult r = sh::deringIrradiance(probes[i], order, rounding);
            if (r.changed()) {
                probes[i] = r.sh;
                changes[i] = std::max(changes[i], r.relativeChange);
            }
        }
    });
}

DeringTally tallyDering(std::span<const float> changes) {
    DeringTally t;
    for (const float c : changes) {
        if (c >= 0.0f) {
            ++t.probes;
            t.sumChange += double(c);
            t.maxChange = std::max(t.maxChange, double(c));
        }
    }
    return t;
}

} // namespace probekit::baker
