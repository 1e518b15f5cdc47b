#include "probekit/formats/volume.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <span>
#include <string>

#include <Imath/half.h>
#include <glm/common.hpp>

#include "texel_check.hpp"

namespace probekit {

std::string_view toString(Storage storage) {
    switch (storage) {
    case Storage::Float32:
        return "float";
    case Storage::Float16:
        return "half";
    }
    return "unknown";
}

std::string_view toString(VolumeLayout layout) {
    switch (layout) {
    case VolumeLayout::Dense:
        return "dense";
    case VolumeLayout::Bricked:
        return "bricked";
    }
    return "unknown";
}

namespace {

// Band-2 value j = 3 * k + c sits at plane 3 + j / 4, component j % 4 (see volume.hpp).
constexpr int kBand2First = 4;

std::string volumeLabel(const VolumeDesc& desc) {
    return "volume '" + desc.name + "'";
}

std::string numberText(double value) {
    if (std::isnan(value)) {
        return "nan"; // not "-nan": a NaN's sign means nothing
    }
    char text[32];
    std::snprintf(text, sizeof text, "%g", value);
    return text;
}

} // namespace

namespace detail {

// ORs `bad` over the whole span (no early exit), which GCC and Clang vectorise; only a span that
// holds a bad value is scanned again for its index. `Flag` is an integer of the element's width,
// so the vector lanes match.
template <class T, class Flag, class Bad>
size_t firstBad(std::span<const T> values, Bad bad) {
    Flag any = 0;
    for (const T value : values) {
        any |= Flag(bad(value));
    }
    if (any == 0) {
        return values.size();
    }
    return size_t(std::find_if(values.begin(), values.end(), bad) - values.begin());
}

size_t firstBadTexel(std::span<const float> texels) {
    // |x| > kMaxTexelMagnitude, NaN or infinity is exactly: the bits without the sign, as an
    // integer, exceed those of kMaxTexelMagnitude (no floating-point compare, no NaN rules).
    constexpr int32_t kLimit = std::bit_cast<int32_t>(kMaxTexelMagnitude);
    return firstBad<float, int32_t>(
        texels, [](float x) { return (std::bit_cast<int32_t>(x) & 0x7fffffff) > kLimit; });
}

size_t firstBadTexel(std::span<const uint16_t> bits) {
    // All five exponent bits set: infinity or NaN.
    return firstBad<uint16_t, int16_t>(
        bits, [](uint16_t b) { return int16_t(b & 0x7fff) > int16_t(0x7bff); });
}

Error texelFault(size_t index, size_t probe_count, float value) {
    const size_t texel = index / 4;
    const std::string where = "probe " + std::to_string(texel % probe_count) + " (plane " +
                              std::to_string(texel / probe_count) + ", component " +
                              std::to_string(index % 4) + ") holds " + numberText(value);
    if (!std::isfinite(value)) {
        return makeError(ErrorCode::NonFinite, where + "; every texel must be finite");
    }
    return makeError(ErrorCode::OutOfRange, where + ", more than the texel magnitude bound " +
                                                numberText(kMaxTexelMagnitude));
}

float texelValue(float value) {
    return value;
}

float texelValue(uint16_t bits) {
    Imath::half h;
    h.setBits(bits);
    return float(h);
}

} // namespace detail

void packProbe(const sh::ShRgb& sh, sh::Order order, glm::vec4* out) {
    for (int c = 0; c < 3; ++c) {
        out[c] = glm::vec4(sh.rgb[0][c], sh.rgb[1][c], sh.rgb[2][c], sh.rgb[3][c]);
    }
    if (order == sh::Order::L1) {
        return;
    }
    for (int p = 3; p < 7; ++p) {
        out[p] = glm::vec4(0.0f);
    }
    for (int j = 0; j < 15; ++j) {
        out[3 + j / 4][j % 4] = sh.rgb[kBand2First + j / 3][j % 3];
    }
}

sh::ShRgb unpackProbe(const glm::vec4* texels, sh::Order order) {
    sh::ShRgb sh;
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < 4; ++i) {
            sh.rgb[i][c] = texels[c][i];
        }
    }
    if (order == sh::Order::L2) {
        for (int j = 0; j < 15; ++j) {
            sh.rgb[kBand2First + j / 3][j % 3] = texels[3 + j / 4][j % 4];
        }
    }
    return sh;
}

size_t Volume::validCount() const {
    return size_t(std::count(validity.begin(), validity.end(), kProbeValid));
}

glm::vec4 Volume::texel(uint32_t plane, size_t probe_index) const {
    assert(plane < planes() && probe_index < probeCount());
    const size_t base = 4 * (size_t(plane) * probeCount() + probe_index);
    glm::vec4 t;
    if (desc.storage == Storage::Float32) {
        for (int i = 0; i < 4; ++i) {
            t[i] = texelsF32[base + i];
        }
    } else {
        for (int i = 0; i < 4; ++i) {
            Imath::half h;
            h.setBits(texelsF16[base + i]);
            t[i] = float(h);
        }
    }
    return t;
}

sh::ShRgb Volume::probe(size_t probe_index) const {
    glm::vec4 texels[7];
    for (uint32_t p = 0; p < planes(); ++p) {
        texels[p] = texel(p, probe_index);
    }
    return unpackProbe(texels, desc.shOrder);
}

namespace {

// Checks the probe, validity and visibility counts against the desc's probe count.
Result<void> checkInputSizes(const VolumeDesc& desc, std::span<const sh::ShRgb> probes,
                             std::span<const uint8_t> validity,
                             std::span<const uint8_t> visibility) {
    const size_t probe_count = desc.probeCount();
    if (probes.size() != probe_count) {
        return makeError(ErrorCode::InconsistentSize,
                         volumeLabel(desc) + ": " + std::to_string(probes.size()) +
                             " probes given for a grid of " + std::to_string(probe_count));
    }
    if (!validity.empty() && validity.size() != probe_count) {
        return makeError(ErrorCode::InconsistentSize,
                         volumeLabel(desc) + ": " + std::to_string(validity.size()) +
                             " validity bytes given for a grid of " + std::to_string(probe_count));
    }
    if (!visibility.empty() && visibility.size() != visibility::kBytesPerProbe * probe_count) {
        return makeError(ErrorCode::InconsistentSize,
                         volumeLabel(desc) + ": " + std::to_string(visibility.size()) +
                             " visibility bytes given for a grid of " +
                             std::to_string(probe_count) + " probes (6 per probe)");
    }
    return {};
}

// The probes as float texels (plane-major), and the largest magnitude and the probe it is in.
struct PackedTexels {
    std::vector<float> texels;
    float largest = 0.0f;
    size_t largestProbe = 0;
};

// Packs the probes into texels, refusing a non-finite coefficient or one past the bound.
Result<PackedTexels> packTexels(const VolumeDesc& desc, std::span<const sh::ShRgb> probes) {
    const size_t probe_count = probes.size();
    const uint32_t planes = planeCount(desc.shOrder);
    PackedTexels out;
    out.texels.resize(size_t(planes) * probe_count * 4);
    for (size_t i = 0; i < probe_count; ++i) {
        glm::vec4 packed[7];
        packProbe(probes[i], desc.shOrder, packed);
        for (uint32_t p = 0; p < planes; ++p) {
            for (int k = 0; k < 4; ++k) {
                const float v = packed[p][k];
                if (!std::isfinite(v)) {
                    return makeError(ErrorCode::NonFinite, volumeLabel(desc) + ": probe " +
                                                               std::to_string(i) +
                                                               " has a non-finite SH coefficient");
                }
                if (std::abs(v) > kMaxTexelMagnitude) {
                    return makeError(ErrorCode::OutOfRange,
                                     volumeLabel(desc) + ": probe " + std::to_string(i) +
                                         " has the SH coefficient " + numberText(v) +
                                         ", more than the texel magnitude bound " +
                                         numberText(kMaxTexelMagnitude));
                }
                if (std::abs(v) > out.largest) {
                    out.largest = std::abs(v);
                    out.largestProbe = i;
                }
                out.texels[4 * (size_t(p) * probe_count + i) + k] = v;
            }
        }
    }
    return out;
}

// Puts the texels into the volume in the desc's storage; half refuses values past kHalfMax.
Result<void> storeTexels(Volume& volume, const VolumeDesc& desc, PackedTexels packed) {
    if (desc.storage != Storage::Float16) {
        volume.texelsF32 = std::move(packed.texels);
        return {};
    }
    if (packed.largest > kHalfMax) {
        return makeError(ErrorCode::OutOfRange,
                         volumeLabel(desc) + ": largest SH coefficient " +
                             std::to_string(packed.largest) + " (probe " +
                             std::to_string(packed.largestProbe) + ") exceeds the half-float " +
                             "maximum 65504; use \"format\": \"float\" storage");
    }
    volume.texelsF16.resize(packed.texels.size());
    for (size_t i = 0; i < packed.texels.size(); ++i) {
        // Imath::half rounds to nearest even; the range check above rules out overflow.
        volume.texelsF16[i] = Imath::half(packed.texels[i]).bits();
    }
    return {};
}

} // namespace

Result<Volume> makeVolume(VolumeDesc desc, std::span<const sh::ShRgb> probes,
                          std::span<const uint8_t> validity, std::span<const uint8_t> visibility) {
    std::vector<uint32_t> indirection;
    if (desc.layout == VolumeLayout::Bricked) {
        auto built =
            brick::buildIndirection(desc.grid.resolution(), desc.bricks, volumeLabel(desc));
        if (!built) {
            return built.error();
        }
        indirection = std::move(built).value();
    }
    if (auto sizes = checkInputSizes(desc, probes, validity, visibility); !sizes) {
        return sizes.error();
    }
    auto packed = packTexels(desc, probes);
    if (!packed) {
        return packed.error();
    }
    Volume volume;
    if (auto stored = storeTexels(volume, desc, std::move(packed).value()); !stored) {
        return stored.error();
    }
    if (validity.empty()) {
        volume.validity.assign(desc.probeCount(), kProbeValid);
    } else {
        volume.validity.assign(validity.begin(), validity.end());
    }
    volume.visibility.assign(visibility.begin(), visibility.end());
    volume.indirection = std::move(indirection);
    volume.desc = std::move(desc);
    return volume;
}

Result<void> validateVolume(const Volume& volume) {
    if (Result<void> structure = detail::validateVolumeStructure(volume); !structure) {
        return structure;
    }
    const size_t probe_count = volume.probeCount();
    const auto fault = [&](size_t index, float value) -> Result<void> {
        const Error e = detail::texelFault(index, probe_count, value);
        return makeError(e.code, volumeLabel(volume.desc) + ": " + e.message);
    };
    if (volume.desc.storage == Storage::Float32) {
        const std::span<const float> texels = volume.texelsF32;
        if (const size_t bad = detail::firstBadTexel(texels); bad != texels.size()) {
            return fault(bad, texels[bad]);
        }
    } else {
        const std::span<const uint16_t> texels = volume.texelsF16;
        if (const size_t bad = detail::firstBadTexel(texels); bad != texels.size()) {
            return fault(bad, detail::texelValue(texels[bad]));
        }
    }
    return {};
}

Result<void> detail::validateVolumeStructure(const Volume& volume) {
    const VolumeDesc& desc = volume.desc;
    const std::string label = volumeLabel(desc);
    if (desc.shOrder != sh::Order::L1 && desc.shOrder != sh::Order::L2) {
        return makeError(ErrorCode::BadEnum, label + ": sh_order " +
                                                 std::to_string(int(desc.shOrder)) +
                                                 " is not 1 or 2");
    }
    if (desc.storage != Storage::Float32 && desc.storage != Storage::Float16) {
        return makeError(ErrorCode::BadEnum, label + ": storage " +
                                                 std::to_string(int(desc.storage)) +
                                                 " is not 0 (float) or 1 (half)");
    }
    if (desc.layout != VolumeLayout::Dense && desc.layout != VolumeLayout::Bricked) {
        return makeError(ErrorCode::BadEnum, label + ": layout " +
                                                 std::to_string(int(desc.layout)) +
                                                 " is not 0 (dense) or 1 (bricked)");
    }
    if (desc.layout == VolumeLayout::Dense && !desc.bricks.bricks.empty()) {
        return makeError(ErrorCode::InconsistentSize, label + ": a dense volume lists bricks");
    }
    if (desc.layout == VolumeLayout::Bricked) {
        if (desc.grid.mode() != grid::PositionMode::Center) {
            return makeError(ErrorCode::BadEnum,
                             label + ": a bricked volume's position mode must be center (0)");
        }
        auto built = brick::buildIndirection(desc.grid.resolution(), desc.bricks, label);
        if (!built) {
            return built.error();
        }
        if (built.value() != volume.indirection) {
            return makeError(ErrorCode::InconsistentSize,
                             label + ": indirection does not match the brick layout");
        }
    } else if (!volume.indirection.empty()) {
        return makeError(ErrorCode::InconsistentSize,
                         label + ": a dense volume has an indirection");
    }
    if (auto r = grid::validateResolution(desc.grid.resolution(), desc.grid.mode()); !r) {
        return makeError(r.error().code, label + ": " + r.error().message);
    }
    if (auto r = grid::validateBounds(desc.grid.bounds()); !r) {
        return makeError(r.error().code, label + ": " + r.error().message);
    }
    if (!std::isfinite(desc.fadeDistance) || desc.fadeDistance < 0.0f) {
        return makeError(ErrorCode::OutOfRange, label + ": fade_distance must be finite and >= 0");
    }
    const size_t probe_count = volume.probeCount();
    if (volume.validity.size() != probe_count) {
        return makeError(ErrorCode::InconsistentSize,
                         label + ": " + std::to_string(volume.validity.size()) +
                             " validity bytes for " + std::to_string(probe_count) + " probes");
    }
    for (uint8_t v : volume.validity) {
        if (v != kProbeValid && v != kProbeInvalid) {
            return makeError(ErrorCode::OutOfRange,
                             label + ": validity byte " + std::to_string(v) + " is not 0 or 1");
        }
    }
    if (volume.hasVisibility() &&
        volume.visibility.size() != visibility::kBytesPerProbe * probe_count) {
        return makeError(ErrorCode::InconsistentSize,
                         label + ": " + std::to_string(volume.visibility.size()) +
                             " visibility bytes for " + std::to_string(probe_count) +
                             " probes (6 per probe, or none)");
    }
    const size_t components = size_t(volume.planes()) * probe_count * 4;
    const size_t have_f32 = volume.texelsF32.size();
    const size_t have_f16 = volume.texelsF16.size();
    const bool is_f32 = desc.storage == Storage::Float32;
    if ((is_f32 ? have_f32 : have_f16) != components || (is_f32 ? have_f16 : have_f32) != 0) {
        return makeError(ErrorCode::InconsistentSize,
                         label + ": texel data holds " +
                             std::to_string(is_f32 ? have_f32 : have_f16) + " values, expected " +
                             std::to_string(components) + " (" + std::to_string(volume.planes()) +
                             " planes x " + std::to_string(probe_count) + " probes x 4)");
    }
    return {};
}

grid::Aabb worldBounds(std::span<const Volume> volumes) {
    grid::Aabb out{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (const Volume& v : volumes) {
        const grid::Aabb b = v.desc.grid.worldBounds();
        out.min = glm::min(out.min, b.min);
        out.max = glm::max(out.max, b.max);
    }
    return out;
}

} // namespace probekit
