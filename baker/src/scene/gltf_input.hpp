// What the glTF loader checks before tinygltf sees a byte (private to baker/src/gltf_*.cpp).
//
// tinygltf trusts its input in ways a hostile file can exploit: its JSON-to-Value conversion
// recurses once per nesting level, it silently skips fields of the wrong JSON kind and wraps
// integers above 2^31, its GLB reader checks the BIN chunk's length 8 bytes short, it reads an
// image's bufferView without checking it against the buffer, and its file callbacks read any
// path (absolute, `..`, the working directory, FIFOs). The checks here run first, on the raw
// bytes and on one nlohmann-json parse of the document, so that whatever reaches tinygltf is a
// container and a document whose fields the loader reads have the kinds it expects; the file
// callbacks (gltf_io.cpp) then hold every read to the folder rule and the memory budget.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "probekit/formats/result.hpp"

namespace tinygltf {
class TinyGLTF;
}

namespace probekit::baker::gltf {

// Thrown inside the loader's files only and turned into a Result at loadGltfBytes' boundary, so
// the many checks stay one line each. The message already names the file.
struct LoadError {
    ErrorCode code;
    std::string message;
};

// Deepest nesting of JSON arrays and objects accepted. glTF's own schema nests about eight
// levels (root, materials, [i], pbrMetallicRoughness, baseColorTexture, extensions,
// KHR_texture_transform, offset); only `extras` and extensions are free-form, and no exporter
// writes them hundreds of levels deep. tinygltf converts extras and extensions recursively,
// about 600 bytes of stack per level (20,000 levels overflowed an 8 MiB stack), so 512 levels
// use ~300 KiB: far above any real asset, far below any thread's stack.
constexpr size_t kMaxJsonDepth = 512;

// The bytes the parsed document is assumed to take per JSON value (nlohmann node and object
// key, plus the tinygltf::Value that extras and extensions become), for the memory budget.
constexpr uint64_t kJsonValueBytes = 256;

// Counts the nesting depth and the values of JSON text without parsing it (strings, with their
// escapes, are skipped); fails naming the file, the byte offset (`base_offset` + position), the
// depth and the limit when the depth exceeds kMaxJsonDepth. Returns the number of values
// (an upper bound on the document's nodes).
uint64_t checkJsonNesting(std::span<const uint8_t> text, uint64_t base_offset,
                          const std::string& file);

// The two chunks of a GLB whose header and chunk table passed every check of the glTF 2.0
// specification's binary layout (section 4.4), each failure naming its byte offset.
struct GlbChunks {
    std::span<const uint8_t> json;
    uint64_t jsonOffset = 20;
    std::span<const uint8_t> bin; // empty without a BIN chunk
};
GlbChunks checkGlbContainer(std::span<const uint8_t> bytes, const std::string& file);

// A number as a message shows it: integral values in full (10000000000, not 1e+10), others in
// the shortest form that reads back the same double.
std::string numberText(double value);

// tinygltf's own decision and decoding of a URI: the data: prefixes it decodes itself, and its
// percent-decoding, which takes '+' for a space as HTML forms do.
bool isEmbeddedDataUri(const std::string& uri);
std::string percentDecoded(const std::string& uri);
// The path a relative URI names (RFC 3986): percent-decoding only, '+' is itself.
std::string uriPath(const std::string& uri);
// Every file URI of the document's buffers and images, by tinygltf's decoding of it (what its
// file callbacks receive) to the path it names: "a+b.bin" reaches the callbacks as "a b.bin"
// and is read as "a+b.bin". Two URIs that tinygltf decodes alike but name different files
// keep the first.
using UriPaths = std::map<std::string, std::string>;
UriPaths fileUriPaths(const nlohmann::json& document);

// What the file callbacks need to know of a checked document's images.
struct ImagePlan {
    // Per image, how messages name it: "'wood.png'", "(bufferView 3, image/webp)", "(data: URI)".
    std::vector<std::string> names;
    // Per image, 1 when no texture's "source" uses it, only an extension's (EXT_texture_webp,
    // KHR_texture_basisu, MSFT_texture_dds name a WebP, KTX2 or DDS image beside the PNG or JPEG
    // fallback of "source"): such an image is never decoded, as no material reads it.
    std::vector<uint8_t> extensionOnly;
};
ImagePlan imagePlan(const nlohmann::json& document);

// Running account of the bytes a load holds or is about to allocate, against
// LoadOptions::maxMemoryBytes.
class MemoryBudget {
public:
    explicit MemoryBudget(uint64_t limit) : m_limit(limit) {}

    uint64_t limit() const { return m_limit; }
    uint64_t used() const { return m_used; }
    bool fits(uint64_t bytes) const { return m_used <= m_limit && bytes <= m_limit - m_used; }
    void add(uint64_t bytes) { m_used = bytes > UINT64_MAX - m_used ? UINT64_MAX : m_used + bytes; }
    void release(uint64_t bytes) { m_used -= std::min(bytes, m_used); }
    // "`what` needs N bytes; with M already loaded that exceeds the memory limit of L bytes
    // (...)": the tail of every refusal.
    std::string refusal(const std::string& what, uint64_t bytes) const;

private:
    uint64_t m_limit;
    uint64_t m_used = 0;
};

// The rule for files a glTF names: a relative URI resolves against the scene file's folder, and
// the canonical path of what it names (`..` and symbolic links resolved) must be a regular file
// under that folder or under one of the extra roots (LoadOptions::assetRoots). Absolute URIs,
// the working directory and anything else are refused. Refusals never say whether a path
// outside the allowed folders exists, nor its size or contents.
class AssetFolder {
public:
    AssetFolder(const std::filesystem::path& scene_name,
                const std::vector<std::filesystem::path>& extra_roots);

    // The canonical scene folder, as tinygltf's base_dir; empty when it cannot be resolved (no
    // external file can then be read).
    const std::string& base() const { return m_base; }
    // Extra roots that are not existing folders (the load refuses them rather than ignore them).
    const std::vector<std::string>& unresolvedRoots() const { return m_unresolved; }

    struct Resolved {
        enum Kind { File, Missing, Refused } kind = Missing;
        std::filesystem::path path; // canonical, for File
        std::string reason;         // for Refused: completes "URI 'x' ..."
    };
    // `decoded` is the percent-decoded URI (relative to base()).
    Resolved resolve(const std::string& decoded) const;

private:
    std::string m_base;
    std::vector<std::filesystem::path> m_roots; // canonical: the scene folder first
    std::vector<std::string> m_unresolved;
};

// Reads a whole regular file without blocking on a FIFO or device: opened non-blocking, checked
// with fstat, then read to its size, refusing a size the budget cannot hold. `label` names the
// file in messages (the caller's field and URI).
Result<std::vector<uint8_t>> readRegularFile(const std::filesystem::path& path,
                                             const std::string& label, MemoryBudget& budget);

// The checks on the parsed JSON document, in this order: glTF version (2.x; asset.minVersion at
// most 2.0), extensionsRequired, then the JSON kind of every field the loader reads (an object
// where an array belongs, an index that is not an integer in 0..2^31-1, a number array of the
// wrong length), values tinygltf cannot keep apart (a light's `range` of 0), buffer sizes
// against their data and bufferView ranges against their buffers, and every buffer and image
// URI against `folder`. Charges the buffers tinygltf will copy to `budget`. Throws LoadError.
void checkDocument(const nlohmann::json& doc, const std::string& file, const GlbChunks* glb,
                   const AssetFolder& folder, MemoryBudget& budget);

// Largest image decoded, in pixels: 8192 x 8192, the largest texture size in common use. The
// baker keeps every texel as linear float RGBA (16 bytes), so this is 1 GiB per image; a bake
// reads albedo at ray hits and cannot use finer detail than its probes resolve.
constexpr uint64_t kMaxImagePixels = uint64_t(8192) * 8192;

// What tinygltf's file and image callbacks share: the folder rule, the budget, and the first
// refusal, which the loader reports instead of tinygltf's generic "File not found".
struct IoContext {
    const AssetFolder& folder;
    MemoryBudget& budget;
    std::string file;
    std::optional<LoadError> refusal;
    std::vector<std::filesystem::path> read; // every buffer and image file read, in order
    UriPaths uriPaths;                       // fileUriPaths of the document
    ImagePlan images;                        // imagePlan of the document
};

// Replaces tinygltf's file callbacks (every read goes through AssetFolder::resolve and
// readRegularFile; the working-directory fallback finds nothing) and its image loader (the
// header's dimensions are checked against kMaxImagePixels and the budget before stb decodes).
// `context` must outlive the parser's loads.
void installIoCallbacks(tinygltf::TinyGLTF& parser, IoContext& context);

} // namespace probekit::baker::gltf
