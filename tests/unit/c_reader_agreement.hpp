// The C reader (integrations/c/probekit_pvol.h) against formats' decodePvol on the same bytes:
// shared by tests/unit/test_c_reader.cpp and fuzz/fuzz_c_reader.cpp.
//
// They agree when both reject with the same error kind, or both accept and every field, every
// stored byte and every texel (as stored and as unpacked float SH) is the same, floats compared
// bit for bit.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "probekit/formats/pvol.hpp"
#include "probekit_pvol.h"

namespace probekit::c_reader {

// pkv_status for each of decodePvol's error codes (the C header lists them in the same terms).
inline pkv_status statusOf(ErrorCode code) {
    switch (code) {
    case ErrorCode::BadMagic:
        return PKV_ERROR_BAD_MAGIC;
    case ErrorCode::UnsupportedVersion:
        return PKV_ERROR_UNSUPPORTED_VERSION;
    case ErrorCode::Truncated:
        return PKV_ERROR_TRUNCATED;
    case ErrorCode::TrailingBytes:
        return PKV_ERROR_TRAILING_BYTES;
    case ErrorCode::ChecksumMismatch:
        return PKV_ERROR_CHECKSUM_MISMATCH;
    case ErrorCode::InconsistentSize:
        return PKV_ERROR_INCONSISTENT_SIZE;
    case ErrorCode::BadResolution:
        return PKV_ERROR_BAD_RESOLUTION;
    case ErrorCode::NonFinite:
        return PKV_ERROR_NON_FINITE;
    case ErrorCode::OutOfRange:
        return PKV_ERROR_OUT_OF_RANGE;
    case ErrorCode::BadEnum:
        return PKV_ERROR_BAD_ENUM;
    case ErrorCode::Io:
    case ErrorCode::InvalidArgument:
        break;
    }
    return PKV_ERROR_INVALID_ARGUMENT;
}

// The same bytes with the header's payload length and checksum (pvol.hpp: u64 at 16 and 24)
// rewritten to match what follows the header, so that a damaged payload reaches the parsers.
// Shorter inputs come back unchanged.
inline std::vector<uint8_t> withMatchingHeader(std::span<const uint8_t> bytes) {
    std::vector<uint8_t> fixed(bytes.begin(), bytes.end());
    if (fixed.size() >= kPvolHeaderBytes) {
        const std::span<const uint8_t> payload(fixed.data() + kPvolHeaderBytes,
                                               fixed.size() - kPvolHeaderBytes);
        const uint64_t length = payload.size();
        const uint64_t checksum = xxhash64(payload);
        for (int i = 0; i < 8; ++i) {
            fixed[16 + i] = uint8_t(length >> (8 * i));
            fixed[24 + i] = uint8_t(checksum >> (8 * i));
        }
    }
    return fixed;
}

// Collects the first difference found, with where it is.
class Comparison {
public:
    bool differs() const { return !m_first.empty(); }
    const std::string& first() const { return m_first; }

    void note(bool same, const std::string& where) {
        if (!same && m_first.empty()) {
            m_first = where;
        }
    }
    void bits(float c, float cpp, const std::string& where) {
        note(std::bit_cast<uint32_t>(c) == std::bit_cast<uint32_t>(cpp), where);
    }
    void text(const pkv_string& c, const std::string& cpp, const std::string& where) {
        note(c.data != nullptr && std::string(c.data, c.size) == cpp && c.data[c.size] == '\0',
             where);
    }
    template <class T>
    void block(const T* c, const std::vector<T>& cpp, const std::string& where) {
        note(cpp.empty() ? c == nullptr
                         : c != nullptr && std::memcmp(c, cpp.data(), cpp.size() * sizeof(T)) == 0,
             where);
    }

private:
    std::string m_first;
};

inline void compareMetadata(Comparison& cmp, const pkv_file& c, const PvolFile& cpp) {
    const BakeMetadata& meta = cpp.metadata;
    cmp.text(c.metadata.tool_version, meta.toolVersion, "metadata.tool_version");
    cmp.text(c.metadata.method, meta.method, "metadata.method");
    cmp.text(c.metadata.parameters_json, meta.parametersJson, "metadata.parameters_json");
    cmp.note(c.metadata.seed == meta.seed, "metadata.seed");
    cmp.note(c.metadata.scene_hash == meta.sceneHash, "metadata.scene_hash");
    cmp.note(std::bit_cast<uint64_t>(c.metadata.bake_seconds) ==
                 std::bit_cast<uint64_t>(meta.bakeSeconds),
             "metadata.bake_seconds");
    cmp.note(c.volume_count == cpp.volumes.size(), "volume count");
}

// Everything but the probe data.
inline void compareVolumeDesc(Comparison& cmp, const pkv_volume& c, const Volume& cpp,
                              const std::string& at) {
    const VolumeDesc& desc = cpp.desc;
    const grid::GridLayout& grid = desc.grid;
    cmp.text(c.name, desc.name, at + "name");
    cmp.note(uint32_t(c.layout) == uint32_t(desc.layout), at + "layout");
    for (int a = 0; a < 3; ++a) {
        cmp.bits(c.bounds_min[a], grid.bounds().min[a], at + "bounds.min");
        cmp.bits(c.bounds_max[a], grid.bounds().max[a], at + "bounds.max");
        cmp.note(c.resolution[a] == grid.resolution()[a], at + "resolution");
        cmp.bits(c.translation[a], grid.frame().translation[a], at + "frame.translation");
    }
    const glm::quat& q = grid.frame().rotation;
    const float rotation[4] = {q.w, q.x, q.y, q.z};
    for (int i = 0; i < 4; ++i) {
        cmp.bits(c.rotation[i], rotation[i], at + "frame.rotation");
    }
    cmp.note(uint32_t(c.position_mode) == uint32_t(grid.mode()), at + "position_mode");
    cmp.note(c.sh_order == uint32_t(desc.shOrder), at + "sh_order");
    cmp.note(c.coefficient_count == uint32_t(sh::coefficientCount(desc.shOrder)),
             at + "coefficient_count");
    cmp.note(c.plane_count == cpp.planes(), at + "plane_count");
    cmp.note(uint32_t(c.storage) == uint32_t(desc.storage), at + "storage");
    cmp.note(c.blend_priority == desc.blendPriority, at + "blend_priority");
    cmp.bits(c.fade_distance, desc.fadeDistance, at + "fade_distance");
    cmp.note(c.max_level == desc.bricks.maxLevel, at + "max_level");
    cmp.note(c.brick_count == desc.bricks.bricks.size(), at + "brick count");
    for (size_t b = 0; b < c.brick_count && b < desc.bricks.bricks.size(); ++b) {
        const brick::Brick& brick = desc.bricks.bricks[b];
        cmp.note(c.bricks[b].level == brick.level && c.bricks[b].coord[0] == brick.coord.x &&
                     c.bricks[b].coord[1] == brick.coord.y && c.bricks[b].coord[2] == brick.coord.z,
                 at + "brick " + std::to_string(b));
    }
    const size_t cells =
        size_t(c.finest_cells[0]) * size_t(c.finest_cells[1]) * size_t(c.finest_cells[2]);
    cmp.note((c.layout == PKV_LAYOUT_DENSE ? 0 : cells) == cpp.indirection.size(),
             at + "indirection size");
    cmp.block(c.indirection, cpp.indirection, at + "indirection");
}

// Probe data: validity, visibility, stored texels, and every probe's unpacked SH.
inline void compareProbes(Comparison& cmp, const pkv_volume& c, const Volume& cpp,
                          const std::string& at) {
    cmp.note(c.probe_count == cpp.probeCount(), at + "probe count");
    cmp.block(c.validity, cpp.validity, at + "validity");
    cmp.block(c.visibility, cpp.visibility, at + "visibility");
    cmp.block(c.texels_f32, cpp.texelsF32, at + "float texels");
    cmp.block(c.texels_f16, cpp.texelsF16, at + "half texels");
    cmp.note(c.component_count == cpp.texelsF32.size() + cpp.texelsF16.size(),
             at + "component count");
    if (cmp.differs()) {
        return; // sizes disagree: indexing by probe would not be safe
    }
    for (size_t probe = 0; probe < c.probe_count; ++probe) {
        float sh[9][3];
        pkv_probe_sh(&c, probe, sh);
        const sh::ShRgb expected = cpp.probe(probe);
        for (int i = 0; i < 9; ++i) {
            for (int ch = 0; ch < 3; ++ch) {
                // The label only on a difference: this runs for every coefficient.
                if (std::bit_cast<uint32_t>(sh[i][ch]) !=
                    std::bit_cast<uint32_t>(expected.rgb[i][ch])) {
                    cmp.note(false, at + "probe " + std::to_string(probe) + " coefficient " +
                                        std::to_string(i));
                }
            }
        }
    }
}

// The header's version field (pvol.hpp: u32 at offset 8) of an accepted file.
inline uint32_t loadVersion(std::span<const uint8_t> bytes) {
    return uint32_t(bytes[8]) | uint32_t(bytes[9]) << 8 | uint32_t(bytes[10]) << 16 |
           uint32_t(bytes[11]) << 24;
}

// What the two readers made of one input.
struct Outcome {
    bool cAccepted = false;
    bool cppAccepted = false;
    std::string disagreement; // empty when they agree
    std::string cMessage;     // the C reader's error message (empty on success)
};

inline Outcome compareReaders(std::span<const uint8_t> bytes) {
    Outcome out;
    pkv_file file;
    char message[512];
    const pkv_status status =
        pkv_open_memory(bytes.data(), bytes.size(), &file, message, sizeof message);
    const Result<PvolFile> decoded = decodePvol(bytes, "input");
    out.cAccepted = status == PKV_OK;
    out.cppAccepted = decoded.ok();
    if (!out.cAccepted) {
        out.cMessage = message;
    }
    if (out.cAccepted != out.cppAccepted) {
        out.disagreement = std::string("C reader ") + (out.cAccepted ? "accepts" : "rejects") +
                           ", decodePvol " + (out.cppAccepted ? "accepts" : "rejects") + " (" +
                           (out.cAccepted ? decoded.error().message : out.cMessage) + ")";
    } else if (!out.cAccepted && status != statusOf(decoded.error().code)) {
        out.disagreement = std::string("both reject, the C reader as '") + pkv_status_name(status) +
                           "' (" + out.cMessage + "), decodePvol as '" +
                           pkv_status_name(statusOf(decoded.error().code)) + "' (" +
                           decoded.error().message + ")";
    } else if (out.cAccepted) {
        Comparison cmp;
        const PvolFile& cpp = decoded.value();
        cmp.note(file.version == loadVersion(bytes), "version");
        compareMetadata(cmp, file, cpp);
        for (size_t v = 0; v < file.volume_count && v < cpp.volumes.size(); ++v) {
            const std::string at = "volume " + std::to_string(v) + ": ";
            compareVolumeDesc(cmp, file.volumes[v], cpp.volumes[v], at);
            compareProbes(cmp, file.volumes[v], cpp.volumes[v], at);
        }
        if (cmp.differs()) {
            out.disagreement = "both accept, but they differ in " + cmp.first();
        }
    }
    pkv_free(&file);
    return out;
}

} // namespace probekit::c_reader
