// Deringing of the probes a bake stores (sh::deringIrradiance, formats/.../sh.hpp): every probe,
// valid or not (invalid probes are interpolated as a fallback), on the baker's parallel loop.
// Dense volumes are deringed after dilation; bricked volumes before their borders are
// stitched (stitched probes are then interpolations, with non-negative weights, of deringed
// ones, and keep the guarantee but for rounding) and again after, so the coefficients as
// stored always pass. docs/baking.md#deringing.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::baker {

// The rounding deringing checks against for a volume's storage.
constexpr sh::Rounding deringRounding(Storage storage) {
    return storage == Storage::Float16 ? sh::Rounding::Float16 : sh::Rounding::Float32;
}

// Per-probe record of what deringing did: the relative RMS change of E of the probe's most
// changing pass (sh::DeringResult::relativeChange), or a negative value where no pass changed
// it. Starts as kNotDeringed for every probe.
constexpr float kNotDeringed = -1.0f;

// Derings every probe in place for `storage` and records each changed probe's relative change
// in `changes` (same size as `probes`; the larger of the recorded and the new value).
// Deterministic: each probe depends only on itself.
void deringProbes(std::span<sh::ShRgb> probes, sh::Order order, Storage storage, uint32_t threads,
                  std::span<float> changes);

struct DeringTally {
    uint64_t probes = 0;    // probes changed
    double sumChange = 0.0; // sum of their relative changes
    double maxChange = 0.0; // largest relative change
};

// Sums `changes` in index order.
DeringTally tallyDering(std::span<const float> changes);

} // namespace probekit::baker
