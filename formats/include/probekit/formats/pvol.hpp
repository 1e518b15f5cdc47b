// probekit .pvol — the file that carries baked probe volumes from baker to runtime.
//
// Byte layout (all integers little-endian):
//   offset  0  magic         8 bytes  "PKVOL\r\n\x1a" (exactly these 8 bytes, no terminator)
//   offset  8  version       u32      kPvolVersion when written; 1 or 2 accepted on reading
//   offset 12  header bytes  u32      32 (room to grow the header)
//   offset 16  payload bytes u64      N
//   offset 24  checksum      u64      xxHash64 (seed 0) of the N payload bytes
//   offset 32  payload       N bytes  cereal PortableBinaryArchive (see pvol.cpp, serialize())
// Nothing may follow the payload.
//
// The payload holds the bake metadata, then a volume count, then per volume: a layout enum
// (VolumeLayout: 0 dense, 1 bricked), the VolumeDesc fields, for bricked volumes the max level
// and the brick list (brick.hpp; the indirection is derived on reading, not stored), then
// validity bytes and texel planes (volume.hpp documents their packing), then the visibility
// block (version 2 on).
//
// Versions: the writer always writes kPvolVersion (2). Version 2 adds, per volume after the
// texel planes, a u8 visibility flag (0 = none, 1 = present) and, when 1, exactly
// visibility::kBytesPerProbe (6) * probe count bytes, probe-major (visibility.hpp); nothing else
// changed. The block has no byte count of its own: the probe count fixes its size, and a short
// block is rejected as truncated before it is allocated. Version 1 files (kPvolOldestVersion),
// which have no flag, still read, with empty visibility. Any other version is rejected
// (UnsupportedVersion).
//
// Reading never trusts the bytes: every count is checked against the bytes that remain
// before anything is allocated, every enum against its known values, every float field for
// finiteness, every resolution for power-of-two, the parameters' JSON nesting against
// kMaxJsonDepth (json_nesting.hpp: OutOfRange); each failure has its own ErrorCode and a
// message naming the file and the field.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "probekit/formats/file_io.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit {

constexpr uint32_t kPvolVersion = 2;       // what encodePvol writes
constexpr uint32_t kPvolOldestVersion = 1; // the oldest version decodePvol and readPvol accept
constexpr size_t kPvolHeaderBytes = 32;

// How a file was made. Free-form parameters are a JSON object as text, so every method can
// record its own settings without a format change.
struct BakeMetadata {
    std::string toolVersion;    // e.g. "probekit 0.1.0"
    std::string method;         // "path", "vpl", "lpv", "synthetic", ...
    std::string parametersJson; // the resolved settings, as a JSON object
    uint64_t seed = 0;
    uint64_t sceneHash = 0; // xxHash64 of the scene file bytes (0 when there was none)
    // Wall time of the bake. probekit writes 0 so that the same input gives the same bytes (its
    // tools report the time instead); files written before that hold the time. Kept in the
    // layout, so every version still reads unchanged.
    double bakeSeconds = 0.0;
    friend bool operator==(const BakeMetadata&, const BakeMetadata&) = default;
};

struct PvolFile {
    BakeMetadata metadata;
    std::vector<Volume> volumes;
};

// Serialises to the complete file bytes (header + payload). Preconditions: every volume passes
// validateVolume (asserted in debug builds).
std::vector<uint8_t> encodePvol(const PvolFile& file);

// Parses untrusted bytes. `source_name` only labels error messages (usually the path).
Result<PvolFile> decodePvol(std::span<const uint8_t> bytes, std::string_view source_name);

// Reads and decodes a file. Only a regular file is read (file_io.hpp): a FIFO, a device or a
// directory is refused before any read, so readPvol never blocks.
Result<PvolFile> readPvol(const std::filesystem::path& path);

// Writes atomically with writeFileAtomic (file_io.hpp): the bytes go to a temporary file in the
// target's directory, are flushed to disk, then renamed over `path`. If anything fails the
// temporary file is removed, `path` is untouched (an existing file keeps its old contents), and
// the error names the path. Only a regular file is replaced; symbolic links are followed.
Result<void> writePvol(const std::filesystem::path& path, const PvolFile& file);

// xxHash64 (Yann Collet's algorithm, specification at xxhash.com) of a byte range.
uint64_t xxhash64(std::span<const uint8_t> bytes, uint64_t seed = 0);

} // namespace probekit
