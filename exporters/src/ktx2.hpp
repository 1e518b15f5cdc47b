// A KTX 2.0 container for one uncompressed RGBA16F 3D texture: what Bevy's KTX2 loader reads as
// an irradiance volume (bevy.cpp). Khronos KTX 2.0 specification: identifier, header, index,
// one level, a Basic Data Format Descriptor (Khronos Data Format specification 1.3, section 5),
// key/value data; no supercompression, no mipmaps, no array layers or cube faces.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace probekit::exporters::ktx2 {

constexpr uint32_t kVkFormatR16G16B16A16Sfloat = 97; // VK_FORMAT_R16G16B16A16_SFLOAT

struct Image3d {
    uint32_t width = 0, height = 0, depth = 0; // texels per axis, each >= 1
    // width * height * depth RGBA texels of binary16 bit patterns, x fastest, then y, then z
    // (the KTX2 level layout).
    std::vector<uint16_t> rgba16f;
    // Key/value entries (keys UTF-8 without NUL; values written as given plus a NUL). Written
    // sorted by key, as the specification requires.
    std::vector<std::pair<std::string, std::string>> keyValues;
};

// The file's bytes. Precondition (asserted): rgba16f holds 4 * width * height * depth values.
std::vector<uint8_t> writeRgba16f(const Image3d& image);

} // namespace probekit::exporters::ktx2
