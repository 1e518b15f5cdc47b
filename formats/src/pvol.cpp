#include "probekit/formats/pvol.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <istream>
#include <ostream>
#include <streambuf>
#include <string>

#include <unistd.h>

#include <cereal/archives/portable_binary.hpp>

#include "probekit/formats/json_nesting.hpp"

#include "posix_file.hpp"
#include "texel_check.hpp"
#include "xxhash64.hpp"

namespace probekit {

namespace {

// The 8 magic bytes: a name, then CR LF and ^Z so that text-mode transfers and `type`/`cat`
// mangle or stop visibly (the PNG trick).
constexpr uint8_t kMagic[8] = {'P', 'K', 'V', 'O', 'L', '\r', '\n', 0x1a};

constexpr size_t kVersionOffset = 8;
constexpr size_t kHeaderBytesOffset = 12;
constexpr size_t kPayloadBytesOffset = 16;
constexpr size_t kChecksumOffset = 24;

// cereal's portable archive opens the payload with one byte naming the byte order it was written
// in. Files are always written little-endian, so anything else is damage, not a foreign machine.
constexpr uint8_t kLittleEndianFlag = 1;

// Smallest encoding of one version-1 volume with empty name and no probe data: layout, name
// length, bounds, resolution, position mode, rotation, translation, sh order, storage,
// priority, fade distance, validity count, texel count. Version 2 adds the visibility flag.
// Bounds the volume count by the bytes that remain.
constexpr size_t kMinVolumeBytesV1 =
    1 + 8 + 6 * 4 + 3 * 4 + 1 + 4 * 4 + 3 * 4 + 1 + 1 + 4 + 4 + 8 + 8;
constexpr size_t kVisibilityFlagBytes = 1;
constexpr size_t kMinVolumeBytes = kMinVolumeBytesV1 + kVisibilityFlagBytes;
constexpr size_t minVolumeBytes(uint32_t version) {
    return version >= 2 ? kMinVolumeBytes : kMinVolumeBytesV1;
}
// Values of the version-2 visibility flag.
constexpr uint8_t kVisibilityAbsent = 0;
constexpr uint8_t kVisibilityPresent = 1;
// A bricked volume adds its max level and brick count, then this much per brick: level and
// coord. Bounds the brick count by the bytes that remain.
constexpr size_t kBrickedExtraBytes = 1 + 8;
constexpr size_t kBrickBytes = 1 + 3 * 4;

void storeLe32(uint8_t* p, uint32_t v) {
    if constexpr (std::endian::native == std::endian::big) {
        v = __builtin_bswap32(v);
    }
    std::memcpy(p, &v, sizeof(v));
}

void storeLe64(uint8_t* p, uint64_t v) {
    if constexpr (std::endian::native == std::endian::big) {
        v = __builtin_bswap64(v);
    }
    std::memcpy(p, &v, sizeof(v));
}

uint32_t loadLe32(const uint8_t* p) {
    uint32_t v;
    std::memcpy(&v, p, sizeof(v));
    if constexpr (std::endian::native == std::endian::big) {
        v = __builtin_bswap32(v);
    }
    return v;
}

uint64_t loadLe64(const uint8_t* p) {
    uint64_t v;
    std::memcpy(&v, p, sizeof(v));
    if constexpr (std::endian::native == std::endian::big) {
        v = __builtin_bswap64(v);
    }
    return v;
}

// Appends everything cereal writes to a byte vector, so the payload lands directly behind the
// header in the final file image (no intermediate string stream and copy).
class ByteSink : public std::streambuf {
public:
    explicit ByteSink(std::vector<uint8_t>& out) : m_out(out) {}

protected:
    std::streamsize xsputn(const char* data, std::streamsize count) override {
        const auto* first = reinterpret_cast<const uint8_t*>(data);
        m_out.insert(m_out.end(), first, first + count);
        return count;
    }
    int_type overflow(int_type ch) override {
        if (!traits_type::eq_int_type(ch, traits_type::eof())) {
            m_out.push_back(uint8_t(traits_type::to_char_type(ch)));
        }
        return traits_type::not_eof(ch);
    }

private:
    std::vector<uint8_t>& m_out;
};

// Internal failure carrying the Error decodePvol / readPvol return; never leaves this file.
struct DecodeFailure {
    Error error;
};

[[noreturn]] void fail(ErrorCode code, const std::string& context, const std::string& what) {
    throw DecodeFailure{makeError(code, context + ": " + what)};
}

// What the payload parser reads from: a streambuf that also knows exactly how many payload bytes
// are left, so that every count is checked against it before anything is allocated.
class PayloadSource : public std::streambuf {
public:
    virtual size_t remaining() const = 0;
};

// Reads from a byte span without copying it. The get area is the whole payload, so remaining()
// is in_avail() and sgetn() of a block is one memcpy.
class ByteSource : public PayloadSource {
public:
    explicit ByteSource(std::span<const uint8_t> bytes) {
        // The get area is only ever read: no put area exists and pbackfail is not overridden.
        char* first = const_cast<char*>(reinterpret_cast<const char*>(bytes.data()));
        setg(first, first, first + bytes.size());
    }
    size_t remaining() const override { return size_t(egptr() - gptr()); }
};

// Reads the payload from a file, hashing every byte as it arrives. Small fields come through a
// chunk buffer; large blocks (texels) are read straight into their destination a slice at a
// time and hashed while the slice is still in cache. The bytes thus cross memory once instead
// of read-into-buffer, hash-the-buffer, copy-out-of-the-buffer, with no second file-sized
// allocation: that is what keeps readPvol near raw read speed (tests/bench/bench_pvol.cpp).
// The digest is only known at the end, so readPvol compares the checksum after parsing.
class FileSource : public PayloadSource {
public:
    FileSource(int fd, uint64_t payload_bytes, std::string path)
        : m_fd(fd), m_unread(payload_bytes), m_path(std::move(path)), m_buffer(kBufferBytes) {}

    size_t remaining() const override { return size_t(m_unread) + size_t(egptr() - gptr()); }

    // Reads and hashes whatever the parser left unread, then returns the payload's digest.
    uint64_t finishDigest() {
        setg(nullptr, nullptr, nullptr);
        while (m_unread > 0) {
            readAndHash(m_buffer.data(), size_t(std::min<uint64_t>(m_unread, m_buffer.size())));
        }
        return m_hash.digest();
    }

protected:
    int_type underflow() override {
        if (gptr() == egptr()) {
            const size_t count = size_t(std::min<uint64_t>(m_unread, m_buffer.size()));
            if (count == 0) {
                return traits_type::eof();
            }
            readAndHash(m_buffer.data(), count);
            setg(m_buffer.data(), m_buffer.data(), m_buffer.data() + count);
        }
        return traits_type::to_int_type(*gptr());
    }

    std::streamsize xsgetn(char* out, std::streamsize wanted) override {
        std::streamsize done = 0;
        while (done < wanted) {
            const std::streamsize buffered = egptr() - gptr();
            if (buffered > 0) {
                const std::streamsize take = std::min(buffered, wanted - done);
                std::memcpy(out + done, gptr(), size_t(take));
                gbump(int(take)); // take <= kBufferBytes
                done += take;
            } else if (uint64_t(wanted - done) >= kBufferBytes) {
                const size_t take = size_t(
                    std::min({uint64_t(wanted - done), uint64_t(kDirectSliceBytes), m_unread}));
                if (take == 0) {
                    break;
                }
                readAndHash(out + done, take);
                done += std::streamsize(take);
            } else if (traits_type::eq_int_type(underflow(), traits_type::eof())) {
                break;
            }
        }
        return done;
    }

private:
    // 64 KiB keeps the syscall count low for runs of small fields; 256 KiB slices stay in L2
    // between the kernel's copy and the hash.
    static constexpr size_t kBufferBytes = size_t(64) << 10;
    static constexpr size_t kDirectSliceBytes = size_t(256) << 10;

    void readAndHash(char* out, size_t count) {
        size_t done = 0;
        while (done < count) {
            const ssize_t n = ::read(m_fd, out + done, count - done);
            if (n < 0) {
                const int error = errno;
                if (error == EINTR) {
                    continue;
                }
                fail(ErrorCode::Io, m_path, "read failed: " + detail::errnoText(error));
            }
            if (n == 0) {
                fail(ErrorCode::Truncated, m_path, "file ended early (it shrank while being read)");
            }
            done += size_t(n);
        }
        m_unread -= count;
        m_hash.update({reinterpret_cast<const uint8_t*>(out), count});
    }

    int m_fd;
    uint64_t m_unread; // payload bytes not yet read from the file
    std::string m_path;
    std::vector<char> m_buffer;
    detail::XxHash64 m_hash;
};

// ---------------------------------------------------------------------------------------------
// Payload layout (cereal PortableBinaryArchive, every number little-endian, no padding):
//
//   u8      byte order flag, always 1 (written by cereal's archive itself)
//   string  metadata.toolVersion      (string = u64 byte count, then the bytes, no terminator)
//   string  metadata.method
//   string  metadata.parametersJson
//   u64     metadata.seed
//   u64     metadata.sceneHash
//   f64     metadata.bakeSeconds
//   u64     volume count
//   per volume:
//     u8      layout (VolumeLayout: 0 dense, 1 bricked)
//     string  name
//     f32 x3  bounds.min (x, y, z)        f32 x3  bounds.max
//     u32 x3  resolution (x, y, z)
//     u8      position mode (grid::PositionMode)
//     f32 x4  frame.rotation (w, x, y, z) f32 x3  frame.translation
//     u8      sh order (sh::Order: 1 or 2)
//     u8      storage (Storage: 0 float, 1 half)
//     i32     blend priority
//     f32     fade distance (metres)
//     bricked only (brick.hpp; position mode must be 0 = center):
//       u8      max level (0..3)
//       u64     brick count B
//       per brick: u8 level, u32 x3 coord (x, y, z) at that level
//     u64     validity byte count (== probe count: grid probes, or 64 * B), then the bytes
//     u64     texel component count (== planes * probes * 4), then the components as f32 or
//             as binary16 bit patterns (u16), plane-major as volume.hpp describes
//     version 2 on:
//       u8      visibility flag (0 = none, 1 = present)
//       flag 1: visibility::kBytesPerProbe (6) * probes bytes, probe-major (visibility.hpp:
//               probe i's half-axes +x, -x, +y, -y, +z, -z at 6 i .. 6 i + 5); no count
//
// Counts are stored even though the resolution (or brick count) implies them so that a reader
// can check the two against each other; the visibility block, added later, is sized by the
// probe count alone (its flag says whether it is there); the indirection is not stored (the
// reader derives it from the bricks, brick::buildIndirection); blocks go through binary_data
// so that loading them is one bulk copy.
// ---------------------------------------------------------------------------------------------

void saveString(cereal::PortableBinaryOutputArchive& archive, const std::string& text) {
    archive(uint64_t(text.size()));
    archive(cereal::binary_data(text.data(), text.size()));
}

void serialize(cereal::PortableBinaryOutputArchive& archive, const PvolFile& file) {
    const BakeMetadata& meta = file.metadata;
    saveString(archive, meta.toolVersion);
    saveString(archive, meta.method);
    saveString(archive, meta.parametersJson);
    archive(meta.seed, meta.sceneHash, meta.bakeSeconds);

    archive(uint64_t(file.volumes.size()));
    for (const Volume& volume : file.volumes) {
        const VolumeDesc& desc = volume.desc;
        const grid::GridLayout& layout = desc.grid;
        archive(uint8_t(desc.layout));
        saveString(archive, desc.name);
        const grid::Aabb& bounds = layout.bounds();
        archive(bounds.min.x, bounds.min.y, bounds.min.z, bounds.max.x, bounds.max.y, bounds.max.z);
        const glm::uvec3 resolution = layout.resolution();
        archive(uint32_t(resolution.x), uint32_t(resolution.y), uint32_t(resolution.z));
        archive(uint8_t(layout.mode()));
        const grid::RigidFrame& frame = layout.frame();
        archive(frame.rotation.w, frame.rotation.x, frame.rotation.y, frame.rotation.z);
        archive(frame.translation.x, frame.translation.y, frame.translation.z);
        archive(uint8_t(desc.shOrder), uint8_t(desc.storage));
        archive(int32_t(desc.blendPriority), desc.fadeDistance);
        if (desc.layout == VolumeLayout::Bricked) {
            archive(uint8_t(desc.bricks.maxLevel), uint64_t(desc.bricks.bricks.size()));
            for (const brick::Brick& b : desc.bricks.bricks) {
                archive(b.level, uint32_t(b.coord.x), uint32_t(b.coord.y), uint32_t(b.coord.z));
            }
        }

        archive(uint64_t(volume.validity.size()));
        archive(cereal::binary_data(volume.validity.data(), volume.validity.size()));
        if (desc.storage == Storage::Float32) {
            archive(uint64_t(volume.texelsF32.size()));
            archive(cereal::binary_data(volume.texelsF32.data(),
                                        volume.texelsF32.size() * sizeof(float)));
        } else {
            archive(uint64_t(volume.texelsF16.size()));
            archive(cereal::binary_data(volume.texelsF16.data(),
                                        volume.texelsF16.size() * sizeof(uint16_t)));
        }

        // Version 2: the visibility flag, then the block (validateVolume guarantees its size).
        archive(volume.hasVisibility() ? kVisibilityPresent : kVisibilityAbsent);
        archive(cereal::binary_data(volume.visibility.data(), volume.visibility.size()));
    }
}

// Reads the payload above. Every failure throws DecodeFailure (or cereal::Exception when a
// fixed-size field runs past the end); parsePayload turns both into an Error.
class PayloadReader {
public:
    // `version` is the header's (kPvolOldestVersion .. kPvolVersion): version 1 volumes have
    // no visibility flag.
    PayloadReader(PayloadSource& payload, std::string source, uint32_t version)
        : m_source(std::move(source)), m_version(version), m_payload(payload), m_stream(&m_payload),
          m_archive(m_stream) {}

    PvolFile read(std::string& context) {
        context = m_source;
        PvolFile file;
        BakeMetadata& meta = file.metadata;
        meta.toolVersion = readString(context, "metadata.tool_version");
        meta.method = readString(context, "metadata.method");
        meta.parametersJson = readString(context, "metadata.parameters_json");
        checkParametersNesting(meta.parametersJson, context);
        m_archive(meta.seed, meta.sceneHash, meta.bakeSeconds);
        if (!std::isfinite(meta.bakeSeconds)) {
            fail(ErrorCode::NonFinite, context, "metadata.bake_seconds is not finite");
        }

        const uint64_t volume_count = readValue<uint64_t>();
        const size_t min_volume_bytes = minVolumeBytes(m_version);
        if (volume_count > remaining() / min_volume_bytes) {
            fail(ErrorCode::Truncated, context,
                 "volume count " + std::to_string(volume_count) + " needs at least " +
                     std::to_string(min_volume_bytes) + " bytes each but only " +
                     std::to_string(remaining()) + " payload bytes remain");
        }
        for (uint64_t i = 0; i < volume_count; ++i) {
            context = m_source + ": volume " + std::to_string(i);
            file.volumes.push_back(readVolume(context));
        }
        context = m_source;
        if (remaining() != 0) {
            fail(ErrorCode::TrailingBytes, context,
                 std::to_string(remaining()) + " unread payload bytes after the last volume");
        }
        return file;
    }

private:
    template <class T>
    T readValue() {
        T value;
        m_archive(value);
        return value;
    }

    size_t remaining() const { return m_payload.remaining(); }

    // Throws unless `count` elements of `element_bytes` each fit in what is left of the payload;
    // called before every allocation so a forged count cannot allocate more than the file holds.
    void requireBytes(uint64_t count, size_t element_bytes, const std::string& context,
                      const std::string& what) {
        if (count > remaining() / element_bytes) {
            fail(ErrorCode::Truncated, context,
                 what + " " + std::to_string(count) +
                     (element_bytes == 1 ? std::string()
                                         : " (" + std::to_string(element_bytes) + " bytes each)") +
                     " needs more than the " + std::to_string(remaining()) +
                     " payload bytes that remain");
        }
    }

    std::string readString(const std::string& context, const char* field) {
        const uint64_t length = readValue<uint64_t>();
        requireBytes(length, 1, context, std::string(field) + " length");
        std::string text(size_t(length), '\0');
        m_archive(cereal::binary_data(text.data(), text.size()));
        return text;
    }

    // Every reader of the parameters parses them as JSON (probekit info, render's recorded
    // settings), so text nested past kMaxJsonDepth is refused here, before any of them sees it.
    static void checkParametersNesting(const std::string& json, const std::string& context) {
        if (Result<void> nesting = checkJsonNesting(json, "metadata.parameters_json"); !nesting) {
            fail(nesting.error().code, context, nesting.error().message);
        }
    }

    // The fields of a volume's header that are checked together once all are read.
    struct RawVolumeFields {
        grid::Aabb bounds;
        glm::uvec3 resolution{};
        uint8_t mode = 0;
        grid::RigidFrame frame;
        uint8_t order = 0;
        uint8_t storage = 0;
    };

    Volume readVolume(std::string& context) {
        Volume volume;
        VolumeDesc& desc = volume.desc;
        desc.layout = readLayout(context);
        desc.name = readString(context, "name");
        context += " ('" + desc.name + "')";

        const RawVolumeFields raw = readVolumeFields(desc);
        checkVolumeEnums(raw, desc.layout, context);
        desc.shOrder = sh::Order(raw.order);
        desc.storage = Storage(raw.storage);
        checkVolumeFinite(raw, desc.fadeDistance, context);
        desc.grid = makeGrid(raw, context);
        if (desc.layout == VolumeLayout::Bricked) {
            readBricks(volume, context);
        }

        readValidity(volume, context);
        readTexelBlock(volume, context);
        if (m_version >= 2) {
            readVisibility(volume, context);
        }

        // The texel values were checked by readTexels.
        checkStructure(volume, context);
        return volume;
    }

    // Reads the layout byte and checks that it names a known layout.
    VolumeLayout readLayout(const std::string& context) {
        const uint8_t layout = readValue<uint8_t>();
        if (layout != uint8_t(VolumeLayout::Dense) && layout != uint8_t(VolumeLayout::Bricked)) {
            fail(ErrorCode::BadEnum, context,
                 "layout " + std::to_string(layout) +
                     " is not a known layout (0 = dense, 1 = bricked)");
        }
        return VolumeLayout(layout);
    }

    // Reads bounds through fade distance, unchecked; priority and fade land in `desc`.
    RawVolumeFields readVolumeFields(VolumeDesc& desc) {
        RawVolumeFields raw;
        m_archive(raw.bounds.min.x, raw.bounds.min.y, raw.bounds.min.z, raw.bounds.max.x,
                  raw.bounds.max.y, raw.bounds.max.z);
        m_archive(raw.resolution.x, raw.resolution.y, raw.resolution.z);
        raw.mode = readValue<uint8_t>();
        m_archive(raw.frame.rotation.w, raw.frame.rotation.x, raw.frame.rotation.y,
                  raw.frame.rotation.z);
        m_archive(raw.frame.translation.x, raw.frame.translation.y, raw.frame.translation.z);
        raw.order = readValue<uint8_t>();
        raw.storage = readValue<uint8_t>();
        m_archive(desc.blendPriority, desc.fadeDistance);
        return raw;
    }

    // Checks the position mode (center only when bricked), sh order and storage bytes.
    static void checkVolumeEnums(const RawVolumeFields& raw, VolumeLayout layout,
                                 const std::string& context) {
        const uint8_t mode = raw.mode;
        if (mode != uint8_t(grid::PositionMode::Center) &&
            mode != uint8_t(grid::PositionMode::Corner)) {
            fail(ErrorCode::BadEnum, context,
                 "position_mode " + std::to_string(mode) + " is not 0 (center) or 1 (corner)");
        }
        // Checked before the grid: corner placement would fail there on a 1-brick axis.
        if (layout == VolumeLayout::Bricked && mode != uint8_t(grid::PositionMode::Center)) {
            fail(ErrorCode::BadEnum, context,
                 "position_mode " + std::to_string(mode) +
                     " of a bricked volume must be 0 (center)");
        }
        if (raw.order != uint8_t(sh::Order::L1) && raw.order != uint8_t(sh::Order::L2)) {
            fail(ErrorCode::BadEnum, context,
                 "sh_order " + std::to_string(raw.order) + " is not 1 (L1) or 2 (L2)");
        }
        if (raw.storage != uint8_t(Storage::Float32) && raw.storage != uint8_t(Storage::Float16)) {
            fail(ErrorCode::BadEnum, context,
                 "storage " + std::to_string(raw.storage) + " is not 0 (float) or 1 (half)");
        }
    }

    // Checks bounds, frame and fade distance for finiteness, naming the first bad field.
    static void checkVolumeFinite(const RawVolumeFields& raw, float fade_distance,
                                  const std::string& context) {
        // Finiteness is checked here, field by field, so the message can say which one; the
        // grid factory then checks resolution, bound ordering and the unit quaternion.
        static constexpr const char* kAxes[3] = {"x", "y", "z"};
        for (int axis = 0; axis < 3; ++axis) {
            if (!std::isfinite(raw.bounds.min[axis]) || !std::isfinite(raw.bounds.max[axis])) {
                fail(ErrorCode::NonFinite, context,
                     std::string("bounds.") + kAxes[axis] + " is not finite (min " +
                         std::to_string(raw.bounds.min[axis]) + ", max " +
                         std::to_string(raw.bounds.max[axis]) + ")");
            }
            if (!std::isfinite(raw.frame.translation[axis])) {
                fail(ErrorCode::NonFinite, context,
                     std::string("frame.translation.") + kAxes[axis] + " is not finite");
            }
        }
        for (int i = 0; i < 4; ++i) {
            if (!std::isfinite(raw.frame.rotation[i])) {
                fail(ErrorCode::NonFinite, context, "frame.rotation is not finite");
            }
        }
        if (!std::isfinite(fade_distance)) {
            fail(ErrorCode::NonFinite, context, "fade_distance is not finite");
        }
    }

    // Builds the grid from the checked fields; the factory's error becomes the failure.
    static grid::GridLayout makeGrid(const RawVolumeFields& raw, const std::string& context) {
        auto layout_result = grid::GridLayout::make(raw.bounds, raw.resolution,
                                                    grid::PositionMode(raw.mode), raw.frame);
        if (!layout_result) {
            fail(layout_result.error().code, context, layout_result.error().message);
        }
        return layout_result.value();
    }

    // Reads the validity block after checking its count against the probe count.
    void readValidity(Volume& volume, const std::string& context) {
        const VolumeDesc& desc = volume.desc;
        const size_t probe_count = desc.probeCount();
        const uint64_t validity_count = readValue<uint64_t>();
        if (validity_count != probe_count) {
            fail(ErrorCode::InconsistentSize, context,
                 "validity holds " + std::to_string(validity_count) + " bytes but the " +
                     (desc.layout == VolumeLayout::Dense
                          ? resolutionText(desc.grid.resolution()) + " grid has "
                          : std::to_string(desc.bricks.bricks.size()) + " bricks hold ") +
                     std::to_string(probe_count) + " probes");
        }
        requireBytes(validity_count, 1, context, "validity byte count");
        volume.validity.resize(probe_count);
        m_archive(cereal::binary_data(volume.validity.data(), volume.validity.size()));
    }

    // Reads the texel block in the volume's storage after checking its component count.
    void readTexelBlock(Volume& volume, const std::string& context) {
        const size_t probe_count = volume.desc.probeCount();
        const size_t component_count = size_t(volume.planes()) * probe_count * 4;
        const uint64_t texel_count = readValue<uint64_t>();
        if (texel_count != component_count) {
            fail(ErrorCode::InconsistentSize, context,
                 "texel data holds " + std::to_string(texel_count) + " values, expected " +
                     std::to_string(component_count) + " (" + std::to_string(volume.planes()) +
                     " planes x " + std::to_string(probe_count) + " probes x 4)");
        }
        if (volume.desc.storage == Storage::Float32) {
            requireBytes(texel_count, sizeof(float), context, "float texel count");
            volume.texelsF32.resize(component_count);
            readTexels(volume.texelsF32, probe_count, context);
        } else {
            requireBytes(texel_count, sizeof(uint16_t), context, "half texel count");
            volume.texelsF16.resize(component_count);
            readTexels(volume.texelsF16, probe_count, context);
        }
    }

    // Runs the structural validation, relabelling its messages with this reader's context.
    static void checkStructure(const Volume& volume, const std::string& context) {
        if (auto valid = detail::validateVolumeStructure(volume); !valid) {
            // validateVolume labels its messages "volume '<name>': "; the context already says
            // that, with the file and the index.
            std::string message = valid.error().message;
            const std::string own_label = "volume '" + volume.desc.name + "': ";
            if (message.starts_with(own_label)) {
                message.erase(0, own_label.size());
            }
            fail(valid.error().code, context, message);
        }
    }

    // The bricked part of a volume (after its common fields): max level, brick list, then the
    // indirection, whose construction is the tiling check.
    void readBricks(Volume& volume, const std::string& context) {
        VolumeDesc& desc = volume.desc;
        desc.bricks.maxLevel = readValue<uint8_t>();
        const uint64_t brick_count = readValue<uint64_t>();
        requireBytes(brick_count, kBrickBytes, context, "brick count");
        desc.bricks.bricks.resize(size_t(brick_count));
        for (brick::Brick& b : desc.bricks.bricks) {
            m_archive(b.level, b.coord.x, b.coord.y, b.coord.z);
        }
        // The indirection takes up to 2 KiB per brick (8^3 finest cells of u32). Building it
        // only once there is a brick per level-0 region and the bricks' probe data is known to
        // be in the file keeps a forged brick list from allocating more than the file holds.
        const glm::uvec3 top = desc.grid.resolution();
        if (brick_count < uint64_t(top.x) * top.y * top.z) {
            fail(ErrorCode::InconsistentSize, context,
                 std::to_string(brick_count) + " bricks cannot cover the " + resolutionText(top) +
                     " level-0 grid (every level-0 region needs a brick)");
        }
        requireBytes(brick_count * brick::kBrickProbeCount,
                     1 + size_t(planeCount(desc.shOrder)) * 4 * bytesPerComponent(desc.storage),
                     context, "probe count of the bricks");
        auto built = brick::buildIndirection(desc.grid.resolution(), desc.bricks, context);
        if (!built) {
            throw DecodeFailure{built.error()}; // already labelled with `context`
        }
        volume.indirection = std::move(built).value();
    }

    // Reads a texel block a slice at a time and checks each slice's values (finite, within
    // kMaxTexelMagnitude) while it is still in cache: a second pass over a whole volume would
    // read it from memory again (measured with probekit_bench_formats: 1.5-2x the decode time).
    // Each slice is one sgetn: a memcpy from a span (ByteSource) or read() straight into the
    // vector (FileSource), as a single block read would be.
    template <class T>
    void readTexels(std::vector<T>& texels, size_t probe_count, const std::string& context) {
        constexpr size_t kSliceElements = (size_t(256) << 10) / sizeof(T);
        for (size_t start = 0; start < texels.size(); start += kSliceElements) {
            const size_t count = std::min(kSliceElements, texels.size() - start);
            m_archive(cereal::binary_data(texels.data() + start, count * sizeof(T)));
            const std::span<const T> slice(texels.data() + start, count);
            if (const size_t bad = detail::firstBadTexel(slice); bad != count) {
                const Error e =
                    detail::texelFault(start + bad, probe_count, detail::texelValue(slice[bad]));
                fail(e.code, context, e.message);
            }
        }
    }

    // Version 2's visibility flag and, when it says so, kBytesPerProbe bytes per probe.
    void readVisibility(Volume& volume, const std::string& context) {
        const uint8_t flag = readValue<uint8_t>();
        if (flag == kVisibilityAbsent) {
            return;
        }
        if (flag != kVisibilityPresent) {
            fail(ErrorCode::BadEnum, context,
                 "visibility flag " + std::to_string(flag) + " is not 0 (none) or 1 (present)");
        }
        const size_t probe_count = volume.probeCount();
        requireBytes(probe_count, visibility::kBytesPerProbe, context, "visibility probe count");
        volume.visibility.resize(probe_count * visibility::kBytesPerProbe);
        m_archive(cereal::binary_data(volume.visibility.data(), volume.visibility.size()));
    }

    static std::string resolutionText(glm::uvec3 resolution) {
        return std::to_string(resolution.x) + "x" + std::to_string(resolution.y) + "x" +
               std::to_string(resolution.z);
    }

    std::string m_source;
    uint32_t m_version;
    PayloadSource& m_payload;
    std::istream m_stream;
    cereal::PortableBinaryInputArchive m_archive;
};

size_t estimatePayloadBytes(const PvolFile& file) {
    const BakeMetadata& meta = file.metadata;
    size_t bytes = 1 + 3 * 8 + meta.toolVersion.size() + meta.method.size() +
                   meta.parametersJson.size() + 3 * 8 + 8;
    for (const Volume& volume : file.volumes) {
        bytes += kMinVolumeBytes + volume.desc.name.size() + volume.validity.size() +
                 volume.texelBytes() + volume.visibility.size();
        if (volume.desc.layout == VolumeLayout::Bricked) {
            bytes += kBrickedExtraBytes + kBrickBytes * volume.desc.bricks.bricks.size();
        }
    }
    return bytes;
}

Error ioError(const std::filesystem::path& path, const std::string& what, int error) {
    return makeError(ErrorCode::Io, path.string() + ": " + what + ": " + detail::errnoText(error));
}

Error checksumError(const std::string& source) {
    return makeError(ErrorCode::ChecksumMismatch,
                     source + ": payload checksum does not match the header (file corrupt)");
}

struct PvolHeader {
    uint32_t version = 0;
    uint64_t payloadBytes = 0;
    uint64_t checksum = 0;
};

// Checks the header of a file of `file_bytes` bytes whose first min(file_bytes, 32) bytes are
// `head`: magic, version, header size, and payload size against the file size.
Result<PvolHeader> parseHeader(std::span<const uint8_t> head, uint64_t file_bytes,
                               const std::string& source) {
    // A short file that does not even start like a .pvol is "not a .pvol", not "truncated".
    const size_t magic_bytes = std::min(head.size(), sizeof(kMagic));
    if (magic_bytes > 0 && std::memcmp(head.data(), kMagic, magic_bytes) != 0) {
        return makeError(ErrorCode::BadMagic, source + ": not a .pvol file (bad magic bytes)");
    }
    if (file_bytes < kPvolHeaderBytes) {
        return makeError(ErrorCode::Truncated, source + ": file is " + std::to_string(file_bytes) +
                                                   " bytes, shorter than the " +
                                                   std::to_string(kPvolHeaderBytes) +
                                                   "-byte header");
    }
    const uint32_t version = loadLe32(head.data() + kVersionOffset);
    if (version < kPvolOldestVersion || version > kPvolVersion) {
        return makeError(ErrorCode::UnsupportedVersion,
                         source + ": format version " + std::to_string(version) +
                             " is not supported; this build reads versions " +
                             std::to_string(kPvolOldestVersion) + " to " +
                             std::to_string(kPvolVersion));
    }
    // Every version so far has the same 32-byte header.
    const uint32_t header_bytes = loadLe32(head.data() + kHeaderBytesOffset);
    if (header_bytes != kPvolHeaderBytes) {
        return makeError(ErrorCode::InconsistentSize,
                         source + ": header size " + std::to_string(header_bytes) + " is not the " +
                             std::to_string(kPvolHeaderBytes) + " bytes of version " +
                             std::to_string(version));
    }
    PvolHeader header;
    header.version = version;
    header.payloadBytes = loadLe64(head.data() + kPayloadBytesOffset);
    header.checksum = loadLe64(head.data() + kChecksumOffset);
    const uint64_t available = file_bytes - kPvolHeaderBytes;
    if (header.payloadBytes > available) {
        return makeError(ErrorCode::Truncated,
                         source + ": header promises " + std::to_string(header.payloadBytes) +
                             " payload bytes but the file holds " + std::to_string(available));
    }
    if (header.payloadBytes < available) {
        return makeError(ErrorCode::TrailingBytes,
                         source + ": " + std::to_string(available - header.payloadBytes) +
                             " bytes follow the " + std::to_string(header.payloadBytes) +
                             "-byte payload");
    }
    return header;
}

// Parses a whole payload; every failure, whether found by the checks or by cereal running out
// of bytes, becomes an Error naming the source and the volume being read.
Result<PvolFile> parsePayload(PayloadSource& payload, uint32_t version, const std::string& source) {
    std::string context = source;
    try {
        const auto first = payload.sgetc();
        if (std::streambuf::traits_type::eq_int_type(first, std::streambuf::traits_type::eof())) {
            fail(ErrorCode::Truncated, source, "payload is empty");
        }
        if (first != kLittleEndianFlag) {
            fail(ErrorCode::BadEnum, source,
                 "payload byte-order flag " + std::to_string(first) + " is not 1 (little-endian)");
        }
        PayloadReader reader(payload, source, version);
        return reader.read(context);
    } catch (const DecodeFailure& failure) {
        return failure.error;
    } catch (const cereal::Exception& e) {
        return makeError(ErrorCode::Truncated, context + ": payload ends early (" + e.what() + ")");
    } catch (const std::exception& e) {
        return makeError(ErrorCode::InvalidArgument, context + ": " + e.what());
    }
}

} // namespace

std::vector<uint8_t> encodePvol(const PvolFile& file) {
#ifndef NDEBUG
    for (const Volume& volume : file.volumes) {
        assert(validateVolume(volume).ok());
    }
#endif
    std::vector<uint8_t> bytes(kPvolHeaderBytes);
    bytes.reserve(kPvolHeaderBytes + estimatePayloadBytes(file));
    {
        ByteSink sink(bytes);
        std::ostream stream(&sink);
        // Little-endian whatever the host, as the file header promises.
        cereal::PortableBinaryOutputArchive archive(
            stream, cereal::PortableBinaryOutputArchive::Options::LittleEndian());
        serialize(archive, file);
    }
    const std::span<const uint8_t> payload(bytes.data() + kPvolHeaderBytes,
                                           bytes.size() - kPvolHeaderBytes);
    std::memcpy(bytes.data(), kMagic, sizeof(kMagic));
    storeLe32(bytes.data() + kVersionOffset, kPvolVersion);
    storeLe32(bytes.data() + kHeaderBytesOffset, uint32_t(kPvolHeaderBytes));
    storeLe64(bytes.data() + kPayloadBytesOffset, payload.size());
    storeLe64(bytes.data() + kChecksumOffset, xxhash64(payload));
    return bytes;
}

Result<PvolFile> decodePvol(std::span<const uint8_t> bytes, std::string_view source_name) {
    const std::string source(source_name);
    auto header =
        parseHeader(bytes.first(std::min(bytes.size(), kPvolHeaderBytes)), bytes.size(), source);
    if (!header) {
        return header.error();
    }
    const std::span<const uint8_t> payload = bytes.subspan(kPvolHeaderBytes);
    if (xxhash64(payload) != header.value().checksum) {
        return checksumError(source);
    }
    ByteSource reader(payload);
    return parsePayload(reader, header.value().version, source);
}

Result<PvolFile> readPvol(const std::filesystem::path& path) {
    const std::string source = path.string();
    auto opened = detail::openRegularFile(path, {});
    if (!opened) {
        return opened.error();
    }
    const detail::FileDescriptor& fd = opened.value().fd;
    const uint64_t file_bytes = opened.value().bytes;

    uint8_t head[kPvolHeaderBytes];
    const size_t head_wanted = size_t(std::min<uint64_t>(file_bytes, kPvolHeaderBytes));
    size_t head_read = 0;
    while (head_read < head_wanted) {
        const ssize_t n = ::read(fd.get(), head + head_read, head_wanted - head_read);
        if (n < 0) {
            const int error = errno;
            if (error == EINTR) {
                continue;
            }
            return ioError(path, "read failed", error);
        }
        if (n == 0) {
            break; // shrank since fstat: the header check below reports the truncation
        }
        head_read += size_t(n);
    }
    auto header = parseHeader(std::span<const uint8_t>(head, head_read),
                              head_read < head_wanted ? head_read : file_bytes, source);
    if (!header) {
        return header.error();
    }

    // Parse first and check the checksum after, because the hash is computed while reading.
    // A mismatch still wins over whatever the parser said about the damaged bytes, exactly as
    // in decodePvol, which checks it first.
    FileSource reader(fd.get(), header.value().payloadBytes, source);
    Result<PvolFile> result = parsePayload(reader, header.value().version, source);
    uint64_t digest = 0;
    try {
        digest = reader.finishDigest();
    } catch (const DecodeFailure&) {
        // Only reachable after a parse failure (a successful parse consumed every byte); the
        // file cannot be hashed to the end, so the parser's error is the best report.
        return result;
    }
    if (digest != header.value().checksum) {
        return checksumError(source);
    }
    return result;
}

Result<void> writePvol(const std::filesystem::path& path, const PvolFile& file) {
    return writeFileAtomic(path, encodePvol(file));
}

} // namespace probekit
