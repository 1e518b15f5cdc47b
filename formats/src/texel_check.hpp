// Private to formats: the texel value check shared by validateVolume and the .pvol reader, which
// runs it on each slice of texels right after reading it, while the slice is still in cache.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::detail {

// Index of the first float that is NaN, infinite or beyond kMaxTexelMagnitude, or size().
size_t firstBadTexel(std::span<const float> texels);
// Index of the first binary16 infinity or NaN, or size() (every finite half is within bounds).
size_t firstBadTexel(std::span<const uint16_t> bits);

// The failure for the bad texel at plane-major component `index` of a volume of
// `probe_count` probes, without a label: "probe 5 (plane 1, component 2) holds nan; every texel
// must be finite" (NonFinite) or "... holds 3e+38, more than the texel magnitude bound 1e+30"
// (OutOfRange).
Error texelFault(size_t index, size_t probe_count, float value);
float texelValue(float value);
float texelValue(uint16_t bits);

// validateVolume without the texel values (the .pvol reader checks those while reading).
Result<void> validateVolumeStructure(const Volume& volume);

} // namespace probekit::detail
