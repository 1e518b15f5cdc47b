// Error of one set of probe volumes against a reference set with the same grids.
//
// The metric every probekit accuracy figure uses (bench CSV, `probekit diff`, tests): at every
// probe valid in both volumes, irradiance E(n) (W/m^2, sh::irradiance, as the runtime evaluates
// it) over kCompareNormals spherical-Fibonacci normals (sh::fibonacciDirection; the same set
// reference.json uses) and the three channels:
//   relRmse     = sqrt(sum (E - E_ref)^2 / sum E_ref^2)               over everything
//   maxProbeErr = max over probes of rms_n,c(E - E_ref) / rms(E_ref)  the worst single probe,
//                 relative to the whole set's RMS irradiance (so dark probes do not explode)
//   maxAbsErr   = max |E - E_ref| in W/m^2
#pragma once

#include <cstddef>
#include <span>

#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::runtime {

constexpr int kCompareNormals = 64;

struct VolumeError {
    double relRmse = 0.0;
    double maxProbeErr = 0.0;
    double maxAbsErr = 0.0;
    size_t probesCompared = 0; // valid in both
    size_t worstProbe = 0;     // linear index of the worst probe
    size_t worstVolume = 0;    // index of its volume
};

// Fails (naming the volume) when the sets differ in volume count or a volume's resolution.
Result<VolumeError> compareVolumes(std::span<const Volume> test, std::span<const Volume> reference);

} // namespace probekit::runtime
