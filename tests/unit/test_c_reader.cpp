// The C reader (integrations/c/probekit_pvol.h, compiled as C in probekit_c_reader) against
// formats' decodePvol: on every committed .pvol, on generated files of every volume kind, and on
// every damaged variant of a small file, the two accept and reject the same inputs (with the
// same error kind), and on accepted ones agree on every field and every texel bit for bit
// (tests/unit/c_reader_agreement.hpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "c_reader_agreement.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/volume.hpp"
#include "probekit_pvol.h"

namespace probekit {
namespace {

using c_reader::compareReaders;
using c_reader::withMatchingHeader;

// Counts the inputs checked and keeps the first few disagreements, so one failure report shows
// several of them.
class Tally {
public:
    // `describe()` names the input; called only for a disagreement.
    template <class Describe>
    void check(std::span<const uint8_t> bytes, Describe describe) {
        const c_reader::Outcome outcome = compareReaders(bytes);
        ++m_inputs;
        m_accepted += outcome.cAccepted ? 1 : 0;
        if (!outcome.disagreement.empty() && ++m_disagreements <= 10) {
            ADD_FAILURE() << describe() << ": " << outcome.disagreement;
        }
    }
    size_t inputs() const { return m_inputs; }
    size_t accepted() const { return m_accepted; }
    size_t disagreements() const { return m_disagreements; }
    void print(const char* label) const {
        std::printf("[ c reader ] %s: %zu inputs (%zu accepted), %zu disagreements\n", label,
                    m_inputs, m_accepted, m_disagreements);
    }

private:
    size_t m_inputs = 0;
    size_t m_accepted = 0;
    size_t m_disagreements = 0;
};

std::vector<uint8_t> fileBytes(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// --- generated volumes -------------------------------------------------------------------------

struct Kind {
    VolumeLayout layout;
    sh::Order order;
    Storage storage;
    bool visibility;
};

// The 16 kinds: dense and bricked, L1 and L2, float and half, with and without visibility.
std::vector<Kind> everyKind() {
    std::vector<Kind> kinds;
    for (const VolumeLayout layout : {VolumeLayout::Dense, VolumeLayout::Bricked}) {
        for (const sh::Order order : {sh::Order::L1, sh::Order::L2}) {
            for (const Storage storage : {Storage::Float32, Storage::Float16}) {
                for (const bool visibility : {false, true}) {
                    kinds.push_back({layout, order, storage, visibility});
                }
            }
        }
    }
    return kinds;
}

// Nested bricks over a 1 x 1 x `top_z` top grid: every level-0 brick, and in the first region
// `finer` of its 8 level-1 octants.
brick::BrickLayout nestedBricks(uint32_t top_z, uint32_t finer) {
    brick::BrickLayout layout;
    layout.maxLevel = 1;
    for (uint32_t z = 0; z < top_z; ++z) {
        layout.bricks.push_back({glm::uvec3(0, 0, z), 0});
    }
    for (uint32_t octant = 0; octant < finer; ++octant) {
        layout.bricks.push_back(
            {glm::uvec3(octant & 1, (octant >> 1) & 1, (octant >> 2) & 1), uint8_t(1)});
    }
    return layout;
}

// Coefficients over many binades, signed, with exact zeros and values in half's subnormal range.
sh::ShRgb randomProbe(std::mt19937& rng, sh::Order order) {
    std::uniform_real_distribution<float> mantissa(1.0f, 2.0f);
    std::uniform_int_distribution<int> exponent(-20, 8);
    sh::ShRgb sh;
    for (int i = 0; i < sh::coefficientCount(order); ++i) {
        for (int c = 0; c < 3; ++c) {
            const uint32_t pick = rng() % 16;
            const float value = std::ldexp(mantissa(rng), exponent(rng));
            sh.rgb[i][c] = pick == 0 ? 0.0f : pick == 1 ? -0.0f : (pick & 2 ? value : -value);
        }
    }
    return sh;
}

// A volume of `kind` with seeded contents; `small` gives the fewest probes that still show
// every feature (a 2 x 2 x 2 grid; two nested bricks).
Volume generatedVolume(const Kind& kind, uint32_t seed, bool small = false) {
    std::mt19937 rng(seed);
    VolumeDesc desc;
    desc.name = "generated_" + std::to_string(seed);
    desc.layout = kind.layout;
    desc.shOrder = kind.order;
    desc.storage = kind.storage;
    desc.blendPriority = int32_t(seed % 7) - 3;
    desc.fadeDistance = 0.25f * float(seed % 3);
    grid::RigidFrame frame;
    if (seed % 2 == 1) {
        frame.rotation = glm::angleAxis(0.3f * float(seed), glm::normalize(glm::vec3(1, 2, 3)));
        frame.translation = glm::vec3(1.5f, -2.0f, float(seed));
    }
    const grid::Aabb box{glm::vec3(-3.0f, 0.0f, -1.5f), glm::vec3(2.0f, 2.5f, 4.0f)};
    if (kind.layout == VolumeLayout::Dense) {
        const auto mode = seed % 4 < 2 ? grid::PositionMode::Center : grid::PositionMode::Corner;
        const glm::uvec3 resolution = small ? glm::uvec3(2) : glm::uvec3(4, 2, 2 << (seed % 2));
        desc.grid = grid::GridLayout(box, resolution, mode, frame);
    } else {
        const uint32_t top_z = small ? 1 : 2;
        desc.grid =
            grid::GridLayout(box, glm::uvec3(1, 1, top_z), grid::PositionMode::Center, frame);
        desc.bricks = nestedBricks(top_z, small ? 1 : 1 + seed % 3);
    }
    const size_t probe_count = desc.probeCount();
    std::vector<sh::ShRgb> probes;
    std::vector<uint8_t> validity(probe_count);
    for (size_t i = 0; i < probe_count; ++i) {
        probes.push_back(randomProbe(rng, kind.order));
        validity[i] = rng() % 4 == 0 ? kProbeInvalid : kProbeValid;
    }
    std::vector<uint8_t> occluders;
    if (kind.visibility) {
        occluders.resize(probe_count * visibility::kBytesPerProbe);
        for (uint8_t& byte : occluders) {
            byte = uint8_t(rng());
        }
    }
    auto made = makeVolume(desc, probes, validity, occluders);
    EXPECT_TRUE(made.ok()) << (made.ok() ? "" : made.error().message);
    return std::move(made).value();
}

PvolFile generatedFile(const std::vector<Volume>& volumes) {
    PvolFile file;
    file.metadata.toolVersion = "probekit test";
    file.metadata.method = "synthetic";
    file.metadata.parametersJson = R"({"note": "bytes \u00e9 and \" survive"})";
    file.metadata.seed = 0x0123456789abcdefull;
    file.metadata.sceneHash = 0xfedcba9876543210ull;
    file.metadata.bakeSeconds = 2.5;
    file.volumes = volumes;
    return file;
}

// A version-1 file of one volume without visibility: version 2 differs only by the visibility
// flag, which is then the payload's last byte (pvol.hpp).
std::vector<uint8_t> versionOneBytes(const Volume& volume) {
    std::vector<uint8_t> bytes = encodePvol(generatedFile({volume}));
    EXPECT_EQ(bytes.back(), 0);
    bytes.pop_back();
    bytes[8] = 1;
    return withMatchingHeader(bytes);
}

TEST(CReader, AgreesOnEveryCommittedFile) {
    // tests/data (the hostile files) and the pvol fuzzer's seed corpus (real bakes).
    const std::filesystem::path data = PROBEKIT_TEST_DATA_DIR;
    Tally tally;
    size_t files = 0;
    for (const auto& root : {data, data / ".." / ".." / "fuzz" / "corpus" / "fuzz_pvol"}) {
        for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
            if (!entry.is_regular_file()) {
                continue;
            }
            ++files;
            const std::vector<uint8_t> bytes = fileBytes(entry.path());
            const std::string name = entry.path().string();
            tally.check(bytes, [&] { return name; });
            tally.check(withMatchingHeader(bytes), [&] { return name + " (header rewritten)"; });
        }
    }
    tally.print("committed files and their header-rewritten twins");
    EXPECT_GE(files, 9u);
    EXPECT_EQ(tally.disagreements(), 0u);
}

TEST(CReader, AgreesOnGeneratedFilesOfEveryKind) {
    const std::vector<Kind> kinds = everyKind();
    std::vector<Volume> volumes;
    for (size_t k = 0; k < kinds.size(); ++k) {
        volumes.push_back(generatedVolume(kinds[k], uint32_t(k)));
    }
    Tally tally;
    // Three volumes a file, each kind in three files at three positions.
    for (size_t k = 0; k < kinds.size(); ++k) {
        const std::vector<Volume> three = {volumes[k], volumes[(k + 5) % kinds.size()],
                                           volumes[(k + 11) % kinds.size()]};
        tally.check(encodePvol(generatedFile(three)), [k] { return "file " + std::to_string(k); });
    }
    tally.check(encodePvol(generatedFile(volumes)), [] { return "every kind in one file"; });
    tally.check(encodePvol(generatedFile({})), [] { return "no volume"; });
    for (size_t k = 0; k < kinds.size(); ++k) {
        if (!kinds[k].visibility) {
            tally.check(versionOneBytes(volumes[k]),
                        [k] { return "version 1, kind " + std::to_string(k); });
        }
    }
    tally.print("generated files");
    std::printf("[ c reader ] %zu generated volumes\n", volumes.size());
    EXPECT_EQ(tally.accepted(), tally.inputs()) << "every generated file is valid";
    EXPECT_EQ(tally.disagreements(), 0u);
}

// --- damaged files -----------------------------------------------------------------------------

// A small file with a dense L2 float volume in a rotated frame, a nested bricked L1 half volume
// with visibility and a two-probe dense volume with visibility.
std::vector<uint8_t> smallFile() {
    Volume dense =
        generatedVolume({VolumeLayout::Dense, sh::Order::L2, Storage::Float32, false}, 1, true);
    Volume bricked =
        generatedVolume({VolumeLayout::Bricked, sh::Order::L1, Storage::Float16, true}, 0, true);
    VolumeDesc tiny_desc;
    tiny_desc.name = "tiny";
    tiny_desc.grid = grid::GridLayout(grid::Aabb{glm::vec3(0.0f), glm::vec3(1.0f)},
                                      glm::uvec3(2, 1, 1), grid::PositionMode::Center);
    tiny_desc.shOrder = sh::Order::L1;
    const std::vector<sh::ShRgb> probes(2);
    const std::vector<uint8_t> occluders(2 * visibility::kBytesPerProbe, 128);
    auto tiny = makeVolume(tiny_desc, probes, {}, occluders);
    EXPECT_TRUE(tiny.ok());
    return encodePvol(generatedFile({dense, bricked, tiny.value()}));
}

// Writes the low `width` bytes of `value` little-endian at `offset`, as far as the bytes go.
std::vector<uint8_t> patched(std::vector<uint8_t> bytes, size_t offset, uint64_t value,
                             size_t width) {
    for (size_t i = 0; i < width && offset + i < bytes.size(); ++i) {
        bytes[offset + i] = uint8_t(value >> (8 * i));
    }
    return bytes;
}

uint64_t loadLe(const std::vector<uint8_t>& bytes, size_t offset, size_t width) {
    uint64_t value = 0;
    for (size_t i = 0; i < width && offset + i < bytes.size(); ++i) {
        value |= uint64_t(bytes[offset + i]) << (8 * i);
    }
    return value;
}

TEST(CReader, AgreesOnEveryDamagedVariantOfASmallFile) {
    const std::vector<uint8_t> good = smallFile();
    ASSERT_TRUE(compareReaders(good).cAccepted);
    Tally tally;
    // Each damage twice: as it is (the checksum catches payload damage) and with the header
    // rewritten to match, so that the payload parsers see it.
    const auto both = [&](const std::vector<uint8_t>& bytes, auto describe) {
        tally.check(bytes, describe);
        tally.check(withMatchingHeader(bytes), [&] { return describe() + ", header rewritten"; });
    };
    for (size_t length = 0; length <= good.size(); ++length) {
        both(std::vector<uint8_t>(good.begin(), good.begin() + length),
             [length] { return "truncated to " + std::to_string(length); });
    }
    std::vector<uint8_t> longer = good;
    longer.push_back(0);
    both(longer, [] { return std::string("one byte appended"); });
    for (size_t offset = 0; offset < good.size(); ++offset) {
        for (const uint8_t mask : {uint8_t(0x01), uint8_t(0x80), uint8_t(0xff)}) {
            std::vector<uint8_t> flipped = good;
            flipped[offset] ^= mask;
            both(flipped, [offset, mask] {
                return "byte " + std::to_string(offset) + " xor " + std::to_string(mask);
            });
        }
        // Counts, lengths, enums and floats: every field width, with values that sit on and
        // around the limits, and the value already there plus and minus one.
        for (const size_t width : {size_t(1), size_t(4), size_t(8)}) {
            const uint64_t here = loadLe(good, offset, width);
            for (const uint64_t value :
                 {uint64_t(0), uint64_t(1), uint64_t(2), uint64_t(3), uint64_t(256),
                  uint64_t(0x7f800000), uint64_t(0xbf800000), uint64_t(0xffffffff),
                  uint64_t(1) << 32, uint64_t(1) << 63, ~uint64_t(0), here + 1, here - 1}) {
                tally.check(withMatchingHeader(patched(good, offset, value, width)), [=] {
                    return std::to_string(width) + "-byte value " + std::to_string(value) + " at " +
                           std::to_string(offset);
                });
            }
        }
    }
    tally.print("damaged variants");
    EXPECT_EQ(tally.disagreements(), 0u);
}

TEST(CReader, AgreesOnTheVolumeCountBoundOfEachVersion) {
    // A volume count of 1 followed by 99, 100 or 101 zero bytes: the smallest volume is 100
    // bytes in version 1 and 101 in version 2 (pvol.cpp's kMinVolumeBytes), so the count check
    // passes or fails by one byte. (The C reader once took version 1's bound for every file;
    // fuzz_c_reader found it.)
    const std::vector<uint8_t> empty = encodePvol(generatedFile({}));
    Tally tally;
    for (const uint8_t version : {uint8_t(1), uint8_t(2)}) {
        for (const size_t tail : {size_t(99), size_t(100), size_t(101)}) {
            std::vector<uint8_t> bytes = empty;
            bytes[8] = version;
            bytes[bytes.size() - 8] = 1; // the volume count, the payload's last field
            bytes.resize(bytes.size() + tail);
            tally.check(withMatchingHeader(bytes), [=] {
                return "version " + std::to_string(version) + ", " + std::to_string(tail) +
                       " bytes after the count";
            });
        }
    }
    EXPECT_EQ(tally.disagreements(), 0u);
}

TEST(CReader, AgreesOnRotationsAtTheUnitLengthTolerance) {
    // The frame's quaternion must have length 1 within 1e-3 (grid.cpp), computed in float: the
    // C reader has to round as the C++ one does. Quaternions (w, x, 0, 0) of length 1 - 1e-3 and
    // 1 + 1e-3, a few ulps either way, at several angles.
    const Volume volume =
        generatedVolume({VolumeLayout::Dense, sh::Order::L1, Storage::Float32, false}, 0, true);
    const std::vector<uint8_t> good = encodePvol(generatedFile({volume}));
    // The identity rotation (w, x, y, z) = (1, 0, 0, 0), then the zero translation.
    const uint8_t identity[28] = {0, 0, 0x80, 0x3f};
    const auto found =
        std::search(good.begin(), good.end(), std::begin(identity), std::end(identity));
    ASSERT_NE(found, good.end());
    const size_t rotation_at = size_t(found - good.begin());
    Tally tally;
    for (const float length : {1.0f - 1e-3f, 1.0f + 1e-3f}) {
        for (const float angle : {0.0f, 0.1f, 0.7f, 1.3f, 2.9f}) {
            const float w0 = length * std::cos(angle), x0 = length * std::sin(angle);
            for (int dw = -4; dw <= 4; ++dw) {
                for (int dx = -4; dx <= 4; ++dx) {
                    const float w = std::bit_cast<float>(std::bit_cast<int32_t>(w0) + dw);
                    const float x = std::bit_cast<float>(std::bit_cast<int32_t>(x0) + dx);
                    std::vector<uint8_t> bytes =
                        patched(good, rotation_at, std::bit_cast<uint32_t>(w), 4);
                    bytes = patched(bytes, rotation_at + 4, std::bit_cast<uint32_t>(x), 4);
                    tally.check(withMatchingHeader(bytes), [=] {
                        return "rotation w " + std::to_string(w) + ", x " + std::to_string(x);
                    });
                }
            }
        }
    }
    tally.print("rotations at the tolerance");
    EXPECT_GT(tally.accepted(), 0u);
    EXPECT_LT(tally.accepted(), tally.inputs());
    EXPECT_EQ(tally.disagreements(), 0u);
}

// --- the pieces ---------------------------------------------------------------------------------

TEST(CReader, XxHash64MatchesFormats) {
    std::mt19937 rng(7);
    std::vector<uint8_t> bytes(1000);
    for (uint8_t& byte : bytes) {
        byte = uint8_t(rng());
    }
    for (size_t length = 0; length <= bytes.size(); ++length) {
        for (const uint64_t seed : {uint64_t(0), uint64_t(0x9e3779b97f4a7c15ull)}) {
            const std::span<const uint8_t> span(bytes.data(), length);
            ASSERT_EQ(pkv_xxhash64(span.data(), span.size(), seed), xxhash64(span, seed))
                << length << " bytes, seed " << seed;
        }
    }
}

TEST(CReader, HalfToFloatMatchesTheVolumeForEveryFiniteHalf) {
    // Every finite binary16 pattern through Volume::texel (Imath) and pkv_half_to_float.
    Volume volume;
    volume.desc.grid = grid::GridLayout(grid::Aabb{glm::vec3(0.0f), glm::vec3(1.0f)},
                                        glm::uvec3(64, 64, 4), grid::PositionMode::Center);
    volume.desc.shOrder = sh::Order::L1;
    volume.desc.storage = Storage::Float16;
    volume.texelsF16.resize(size_t(volume.planes()) * volume.probeCount() * 4);
    for (size_t i = 0; i < volume.texelsF16.size(); ++i) {
        volume.texelsF16[i] = uint16_t(i);
    }
    for (uint32_t bits = 0; bits < 0x10000; ++bits) {
        if ((bits & 0x7c00) == 0x7c00) {
            continue; // infinity and NaN never reach a caller: the reader rejects them
        }
        const size_t texel = bits / 4;
        const float expected = volume.texel(uint32_t(texel / volume.probeCount()),
                                            texel % volume.probeCount())[bits % 4];
        ASSERT_EQ(std::bit_cast<uint32_t>(pkv_half_to_float(uint16_t(bits))),
                  std::bit_cast<uint32_t>(expected))
            << "half bits " << bits;
    }
}

TEST(CReader, MessagesNameTheVolumeAndTheField) {
    Volume volume =
        generatedVolume({VolumeLayout::Dense, sh::Order::L1, Storage::Float32, false}, 0);
    volume.desc.name = "hall\x1b[2J";
    std::vector<uint8_t> bytes = encodePvol(generatedFile({volume}));
    // The sh order byte: the payload's end less the flag, texels, texel count, validity, its
    // count, fade, priority, storage (pvol.cpp's layout), then the order.
    const size_t probes = volume.probeCount();
    const size_t order_at = bytes.size() - 1 - probes * 48 - 8 - probes - 8 - 4 - 4 - 1 - 1;
    ASSERT_EQ(bytes[order_at], 1);
    bytes[order_at] = 3;
    pkv_file file;
    char message[256];
    EXPECT_EQ(pkv_open_memory(bytes.data(), bytes.size(), &file, message, sizeof message),
              PKV_ERROR_CHECKSUM_MISMATCH);
    bytes = withMatchingHeader(bytes);
    EXPECT_EQ(pkv_open_memory(bytes.data(), bytes.size(), &file, message, sizeof message),
              PKV_ERROR_BAD_ENUM);
    EXPECT_STREQ(message, "volume 0 ('hall?[2J'): sh_order 3 is not 1 (L1) or 2 (L2)");
    EXPECT_EQ(file.volumes, nullptr) << "a failed open leaves the file empty";
    // A message cut to the caller's buffer stays terminated.
    char shorter[8];
    EXPECT_EQ(pkv_open_memory(bytes.data(), bytes.size(), &file, shorter, sizeof shorter),
              PKV_ERROR_BAD_ENUM);
    EXPECT_STREQ(shorter, "volume ");
}

} // namespace
} // namespace probekit
