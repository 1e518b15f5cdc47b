// The KTX 2.0 writer (ktx2.hpp). Every multi-byte field is little-endian, as the specification
// fixes it.
#include "ktx2.hpp"

#include <algorithm>
#include <array>
#include <cassert>

namespace probekit::exporters::ktx2 {
namespace {

constexpr std::array<uint8_t, 12> kIdentifier = {0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32,
                                                 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};
constexpr uint32_t kHeaderEnd = 12 + 9 * 4;            // identifier and the nine header words
constexpr uint32_t kLevelIndexStart = kHeaderEnd + 32; // after the index (4 u32, 2 u64)
constexpr uint32_t kDfdStart = kLevelIndexStart + 24;  // after one level's (u64 x 3)

// Khronos Data Format: a Basic block is 24 bytes plus 16 per sample.
constexpr uint32_t kSampleCount = 4;
constexpr uint32_t kBasicBlockSize = 24 + 16 * kSampleCount;

void putU32(std::vector<uint8_t>& out, uint32_t v) {
    for (int i = 0; i < 4; ++i)
        out.push_back(uint8_t(v >> (8 * i)));
}

void putU64(std::vector<uint8_t>& out, uint64_t v) {
    putU32(out, uint32_t(v));
    putU32(out, uint32_t(v >> 32));
}

void padTo(std::vector<uint8_t>& out, size_t alignment) {
    while (out.size() % alignment != 0)
        out.push_back(0);
}

// The Basic Data Format Descriptor of VK_FORMAT_R16G16B16A16_SFLOAT, preceded by
// dfdTotalSize: RGBSDA model, BT.709 primaries, linear transfer, straight alpha, one 8-byte
// texel block, and one sample per channel (16 bits at bit 16 i, float and signed qualifiers,
// sampleLower -1.0f and sampleUpper 1.0f as the Data Format specification sets for floats).
void putDfd(std::vector<uint8_t>& out) {
    putU32(out, 4 + kBasicBlockSize);
    putU32(out, 0);                            // vendorId 0 (Khronos), descriptorType 0 (basic)
    putU32(out, 2u | (kBasicBlockSize << 16)); // versionNumber 2 (spec 1.3), descriptorBlockSize
    putU32(out, 1u | (1u << 8) | (1u << 16));  // model RGBSDA, primaries BT709, transfer LINEAR
    putU32(out, 0);                            // texelBlockDimension 1x1x1x1 (stored minus one)
    putU32(out, 8);                            // bytesPlane0 = 8, planes 1..3 unused
    putU32(out, 0);                            // bytesPlane4..7 unused
    constexpr std::array<uint8_t, kSampleCount> kChannelIds = {0, 1, 2, 15}; // R, G, B, A
    constexpr uint8_t kFloatSigned = 0x80 | 0x40;
    for (uint32_t s = 0; s < kSampleCount; ++s) {
        putU32(out, (16 * s) | (15u << 16) | (uint32_t(kChannelIds[s] | kFloatSigned) << 24));
        putU32(out, 0);          // samplePosition 0,0,0,0
        putU32(out, 0xBF800000); // sampleLower: -1.0f
        putU32(out, 0x3F800000); // sampleUpper: 1.0f
    }
}

void putKeyValues(std::vector<uint8_t>& out,
                  std::vector<std::pair<std::string, std::string>> entries) {
    std::sort(entries.begin(), entries.end());
    for (const auto& [key, value] : entries) {
        putU32(out, uint32_t(key.size() + 1 + value.size() + 1));
        out.insert(out.end(), key.begin(), key.end());
        out.push_back(0);
        out.insert(out.end(), value.begin(), value.end());
        out.push_back(0);
        padTo(out, 4);
    }
}

} // namespace

std::vector<uint8_t> writeRgba16f(const Image3d& image) {
    const size_t texels = size_t(image.width) * image.height * image.depth;
    assert(texels > 0 && image.rgba16f.size() == 4 * texels);
    std::vector<uint8_t> dfd, kvd;
    putDfd(dfd);
    putKeyValues(kvd, image.keyValues);
    const uint32_t kvdStart = kDfdStart + uint32_t(dfd.size()); // a multiple of 4
    // Level data is aligned to lcm(texel block size 8, 4) = 8 bytes.
    const uint64_t levelStart = (uint64_t(kvdStart) + kvd.size() + 7) / 8 * 8;
    const uint64_t levelBytes = texels * 8;

    std::vector<uint8_t> out(kIdentifier.begin(), kIdentifier.end());
    out.reserve(levelStart + levelBytes);
    for (uint32_t v : {kVkFormatR16G16B16A16Sfloat, 2u /* typeSize */, image.width, image.height,
                       image.depth, 0u /* layerCount */, 1u /* faceCount */, 1u /* levelCount */,
                       0u /* supercompressionScheme */})
        putU32(out, v);
    putU32(out, kDfdStart);
    putU32(out, uint32_t(dfd.size()));
    putU32(out, kvd.empty() ? 0 : kvdStart);
    putU32(out, uint32_t(kvd.size()));
    putU64(out, 0); // no supercompression global data
    putU64(out, 0);
    putU64(out, levelStart);
    putU64(out, levelBytes);
    putU64(out, levelBytes); // uncompressedByteLength
    out.insert(out.end(), dfd.begin(), dfd.end());
    out.insert(out.end(), kvd.begin(), kvd.end());
    padTo(out, 8);
    for (uint16_t h : image.rgba16f) {
        out.push_back(uint8_t(h));
        out.push_back(uint8_t(h >> 8));
    }
    return out;
}

} // namespace probekit::exporters::ktx2
