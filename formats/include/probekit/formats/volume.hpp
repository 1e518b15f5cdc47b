// probekit::Volume — one probe volume as it is stored on disk and uploaded to the GPU.
//
// Coefficients are stored as RGBA texel planes, exactly as the runtime uploads them as 3D
// textures (one texture per plane, each texel one probe, same x-fastest order as the grid):
//
//   L1 (3 planes): plane c (c = 0 red, 1 green, 2 blue) = (L00, L1-1, L10, L11) of channel c.
//   L2 (7 planes): planes 0..2 as for L1; planes 3..6 hold the 15 band-2 values in order
//                  value j = 3 * k + c (k = 0..4 for L2-2, L2-1, L20, L21, L22; c = channel),
//                  at plane 3 + j / 4, component j % 4:
//                    plane 3 = (L2-2.r, L2-2.g, L2-2.b, L2-1.r)
//                    plane 4 = (L2-1.g, L2-1.b, L20.r,  L20.g)
//                    plane 5 = (L20.b,  L21.r,  L21.g,  L21.b)
//                    plane 6 = (L22.r,  L22.g,  L22.b,  0)
//   So an L1 view of an L2 volume is its first three planes.
//
// Texel storage is plane-major: texel (plane p, probe i) starts at float/half index
// 4 * (p * probeCount + i). Float16 texels are IEEE 754 binary16 bit patterns, converted with
// round-to-nearest-even (Imath::half).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec4.hpp>

#include "probekit/formats/brick.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/formats/visibility.hpp"

namespace probekit {

enum class Storage : uint8_t {
    Float32 = 0,
    Float16 = 1,
};

std::string_view toString(Storage storage);

constexpr uint32_t planeCount(sh::Order order) {
    return order == sh::Order::L1 ? 3u : 7u;
}
constexpr size_t bytesPerComponent(Storage storage) {
    return storage == Storage::Float32 ? 4 : 2;
}

// Largest finite binary16 value; larger magnitudes cannot be stored as half.
constexpr float kHalfMax = 65504.0f;

// Largest texel magnitude a volume may hold (validateVolume, makeVolume). Irradiance from SH is
// a sum of at most 9 products per channel (27 over RGB) of a coefficient and a constant below
// 1.1, blended with weights that sum to 1; under this bound it stays below about 1e31, far
// from float's 3.4e38, so every evaluation of a valid file is finite. Real radiance is many
// orders of magnitude below it (the sun is about 2e7 W/(sr m^2)).
constexpr float kMaxTexelMagnitude = 1e30f;

// Probe validity: 1 = the probe sees the scene from open space, 0 = it was inside geometry
// (its coefficients were filled by dilation from valid neighbours).
constexpr uint8_t kProbeValid = 1;
constexpr uint8_t kProbeInvalid = 0;

enum class VolumeLayout : uint8_t {
    Dense = 0,   // a full grid of probes (grid.resolution() probes)
    Bricked = 1, // a coarse level of bricks plus finer bricks (brick.hpp)
};

std::string_view toString(VolumeLayout layout); // "dense", "bricked"

// Everything about a volume except its probe data.
struct VolumeDesc {
    std::string name;
    // Dense: the probe grid. Bricked: bounds and frame of the box, resolution = level-0 bricks
    // per axis (powers of two); the position mode is Center and carries no meaning.
    grid::GridLayout grid;
    VolumeLayout layout = VolumeLayout::Dense;
    brick::BrickLayout bricks; // bricked only (empty for dense)
    sh::Order shOrder = sh::Order::L2;
    Storage storage = Storage::Float32;
    int32_t blendPriority = 0; // higher wins where volumes overlap
    float fadeDistance = 0.0f; // metres inside the border over which the volume fades out

    // Probes stored: the grid's for dense, 64 per brick for bricked.
    size_t probeCount() const {
        return layout == VolumeLayout::Dense ? grid.probeCount()
                                             : bricks.bricks.size() * brick::kBrickProbeCount;
    }
};

struct Volume {
    VolumeDesc desc;
    std::vector<uint8_t> validity; // one byte per probe
    // Occluder distances for leak-proof interpolation (visibility.hpp): empty (plain
    // trilinear interpolation, as in .pvol version 1 files) or visibility::kBytesPerProbe per
    // probe, probe-major (probe i's six half-axes at 6 i .. 6 i + 5).
    std::vector<uint8_t> visibility;
    std::vector<float> texelsF32;    // planeCount * probeCount * 4, when storage == Float32
    std::vector<uint16_t> texelsF16; // planeCount * probeCount * 4, when storage == Float16
    // Bricked only: brick index per finest cell (brick::buildIndirection), derived from
    // desc.bricks by makeVolume and by the .pvol reader; empty for dense volumes.
    std::vector<uint32_t> indirection;

    size_t probeCount() const { return desc.probeCount(); }
    uint32_t planes() const { return planeCount(desc.shOrder); }
    // Bytes of texel data (what the GPU textures hold).
    size_t texelBytes() const {
        return size_t(planes()) * probeCount() * 4 * bytesPerComponent(desc.storage);
    }
    // Bytes of the volume's GPU data: texels plus, for bricked volumes, the u32 indirection.
    // (runtime::GpuVolumeSet rounds a brick atlas's slot count up to a power of two, so its
    // allocation can hold up to twice these texels.)
    size_t gpuBytes() const {
        return texelBytes() + indirection.size() * sizeof(uint32_t) + visibilityGpuBytes();
    }
    bool hasVisibility() const { return !visibility.empty(); }
    // Bytes of the visibility on the GPU: 8 per probe (one RG32_UINT texel, runtime::
    // GpuVolumeSet), 0 without visibility data. For a bricked volume this is a lower bound:
    // the runtime's atlas has power-of-two slot counts (up to twice the bricks) and shares its
    // image with the indirection (GpuVolumeSet::texelBytes reports the allocation).
    size_t visibilityGpuBytes() const { return hasVisibility() ? probeCount() * 8 : 0; }
    size_t validCount() const;

    // Texel of one plane at one probe, converted to float. Preconditions (asserted, so not
    // checked in Release builds): plane < planes(), probe < probeCount(), and the texel arrays
    // hold what validateVolume requires. The CPU sampler calls this for every plane of every
    // tap, where an always-on check costs measurable time (ARCHITECTURE.md, "Preconditions");
    // a Volume from makeVolume or readPvol, indexed within probeCount(), meets them.
    glm::vec4 texel(uint32_t plane, size_t probe) const;
    // Unpacks one probe's coefficients (band 2 zero for L1). Preconditions as texel's.
    sh::ShRgb probe(size_t probe) const;
};

// Packs one probe's coefficients into `planeCount(order)` RGBA texels (out has room for 7).
void packProbe(const sh::ShRgb& sh, sh::Order order, glm::vec4* out);
sh::ShRgb unpackProbe(const glm::vec4* texels, sh::Order order);

// Builds a volume from per-probe coefficients (grid order, or brick order for bricked volumes)
// and validity (empty = all valid) and visibility (empty = none; else
// visibility::kBytesPerProbe per probe). Fails, naming the volume and the offending probe or value,
// when:
//  * a bricked layout fails brick::buildIndirection (a gap, a repeated brick, ...);
//  * probes.size() or validity.size() differs from desc.probeCount(), or visibility.size()
//    from 0 and kBytesPerProbe * desc.probeCount();
//  * a coefficient is NaN or infinite, or its magnitude exceeds kMaxTexelMagnitude;
//  * storage is Float16 and a coefficient's magnitude exceeds kHalfMax (the message gives the
//    largest magnitude and suggests float storage) -- never a silent infinity.
Result<Volume> makeVolume(VolumeDesc desc, std::span<const sh::ShRgb> probes,
                          std::span<const uint8_t> validity = {},
                          std::span<const uint8_t> visibility = {});

// Checks a volume's internal consistency (sizes, enums, bounds, resolution, validity bytes;
// for bricked volumes the tiling and that `indirection` matches it; visibility empty or
// kBytesPerProbe per probe) and every texel: finite (float and half storage) and of magnitude at
// most kMaxTexelMagnitude. A texel failure names the probe, plane, component and value:
//   "volume 'v': probe 5 (plane 2, component 3) holds nan; every texel must be finite"
//   "volume 'v': probe 5 (plane 2, component 3) holds 3e+38, more than the texel magnitude
//    bound 1e+30"
Result<void> validateVolume(const Volume& volume);

// The smallest box holding every volume's world bounds (GridLayout::worldBounds); with no volume
// an empty box, min +inf and max -inf.
grid::Aabb worldBounds(std::span<const Volume> volumes);

} // namespace probekit
