// The glTF loader's checks on raw bytes and on the JSON document, before tinygltf (gltf_input.hpp
// says what each guards against).
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string_view>

#include "probekit/formats/json_nesting.hpp"
#include "scene/gltf_input.hpp"

namespace probekit::baker::gltf {

using nlohmann::json;

namespace {

constexpr uint32_t kGlbJson = 0x4E4F534A; // "JSON"
constexpr uint32_t kGlbBin = 0x004E4942;  // "BIN\0"

uint32_t readLe32(std::span<const uint8_t> bytes, uint64_t offset) {
    return uint32_t(bytes[offset]) | uint32_t(bytes[offset + 1]) << 8 |
           uint32_t(bytes[offset + 2]) << 16 | uint32_t(bytes[offset + 3]) << 24;
}

std::string hex32(uint32_t value) {
    char text[16];
    std::snprintf(text, sizeof(text), "0x%08X", value);
    return text;
}

} // namespace

uint64_t checkJsonNesting(std::span<const uint8_t> text, uint64_t base_offset,
                          const std::string& file) {
    const JsonNesting nesting = scanJsonNesting(
        std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), kMaxJsonDepth);
    const size_t deepest = nesting.deepest;
    const uint64_t first_too_deep = base_offset + nesting.firstTooDeep;
    if (deepest > kMaxJsonDepth) {
        throw LoadError{ErrorCode::OutOfRange,
                        file + ": JSON arrays and objects nest " + std::to_string(deepest) +
                            " levels deep (level " + std::to_string(kMaxJsonDepth + 1) +
                            " opens at byte " + std::to_string(first_too_deep) +
                            "), more than the limit of " + std::to_string(kMaxJsonDepth) +
                            " (a glTF nests about 8; the limit keeps the parser's recursion "
                            "within its stack)"};
    }
    return nesting.values + 1;
}

namespace {

[[noreturn]] void failGlb(const std::string& file, ErrorCode code, const std::string& what) {
    throw LoadError{code, file + ": GLB " + what};
}

std::string fileSizeText(uint64_t size) {
    return "the file has " + std::to_string(size) + " bytes";
}

// The 12-byte header: magic, container version 2, total length equal to the file's size.
void checkGlbHeader(std::span<const uint8_t> bytes, const std::string& file) {
    auto fail = [&](ErrorCode code, const std::string& what) { failGlb(file, code, what); };
    const uint64_t size = bytes.size();
    const std::string file_size = fileSizeText(size);
    if (size < 12) {
        fail(ErrorCode::Truncated, "header truncated: it needs 12 bytes, " + file_size);
    }
    if (std::memcmp(bytes.data(), "glTF", 4) != 0) {
        fail(ErrorCode::InvalidArgument, "byte 0: expected the magic 'glTF' of a binary glTF");
    }
    const uint32_t version = readLe32(bytes, 4);
    if (version == 1) {
        fail(ErrorCode::UnsupportedVersion,
             "byte 4: container version 1 is glTF 1.0 (KHR_binary_glTF), which probekit does "
             "not read; it reads glTF 2.x (container version 2)");
    }
    if (version != 2) {
        fail(ErrorCode::UnsupportedVersion,
             "byte 4: container version " + std::to_string(version) + ", expected 2 (glTF 2.x)");
    }
    const uint32_t length = readLe32(bytes, 8);
    if (length > size) {
        fail(ErrorCode::Truncated, "byte 8: total length " + std::to_string(length) + " but " +
                                       file_size + ": the file is truncated");
    }
    if (length != size) {
        fail(ErrorCode::InconsistentSize, "byte 8: total length " + std::to_string(length) +
                                              ", expected the file's size, " +
                                              std::to_string(size));
    }
}

// The first chunk: JSON, non-empty, within the file.
std::span<const uint8_t> checkJsonChunk(std::span<const uint8_t> bytes, const std::string& file) {
    auto fail = [&](ErrorCode code, const std::string& what) { failGlb(file, code, what); };
    const uint64_t size = bytes.size();
    const std::string file_size = fileSizeText(size);
    if (size < 20) {
        fail(ErrorCode::Truncated,
             "byte 12: the JSON chunk's 8-byte header is cut off (" + file_size + ")");
    }
    const uint32_t json_length = readLe32(bytes, 12);
    const uint32_t json_type = readLe32(bytes, 16);
    if (json_type != kGlbJson) {
        fail(ErrorCode::InvalidArgument,
             "byte 16: first chunk type " + hex32(json_type) + ", expected JSON (0x4E4F534A)");
    }
    if (json_length == 0) {
        fail(ErrorCode::InvalidArgument, "byte 12: JSON chunk length 0, expected the length of "
                                         "the JSON text");
    }
    if (20 + uint64_t(json_length) > size) {
        fail(ErrorCode::Truncated,
             "byte 12: JSON chunk length " + std::to_string(json_length) + " runs to byte " +
                 std::to_string(20 + uint64_t(json_length)) + ", past the end (" + file_size + ")");
    }
    return bytes.subspan(20, json_length);
}

// The chunks after the JSON: each within the file; the second, if any, a padded BIN chunk.
std::span<const uint8_t> checkBinChunk(std::span<const uint8_t> bytes, uint32_t json_length,
                                       const std::string& file) {
    auto fail = [&](ErrorCode code, const std::string& what) { failGlb(file, code, what); };
    const uint64_t size = bytes.size();
    const std::string file_size = fileSizeText(size);
    std::span<const uint8_t> bin;
    uint64_t offset = 20 + uint64_t(json_length);
    for (int chunk = 1; offset < size; ++chunk) {
        const std::string at =
            "byte " + std::to_string(offset) + ": chunk " + std::to_string(chunk);
        if (size - offset < 8) {
            fail(ErrorCode::Truncated, at + "'s 8-byte header is cut off (" + file_size + ")");
        }
        const uint32_t chunk_length = readLe32(bytes, offset);
        const uint32_t chunk_type = readLe32(bytes, offset + 4);
        const uint64_t end = offset + 8 + uint64_t(chunk_length);
        if (end > size) {
            fail(ErrorCode::Truncated, at + " length " + std::to_string(chunk_length) +
                                           " runs to byte " + std::to_string(end) +
                                           ", past the end (" + file_size + ")");
        }
        if (chunk == 1) {
            // tinygltf takes the second chunk as BIN or fails; say so here, with the offset.
            if (chunk_type != kGlbBin) {
                fail(ErrorCode::InvalidArgument, "byte " + std::to_string(offset + 4) +
                                                     ": second chunk type " + hex32(chunk_type) +
                                                     ", expected BIN (0x004E4942)");
            }
            if (chunk_length == 0 || chunk_length % 4 != 0) {
                fail(ErrorCode::InvalidArgument,
                     at + " (BIN) length " + std::to_string(chunk_length) +
                         ", expected a positive multiple of 4 (chunks are padded to 4 bytes; "
                         "an empty BIN chunk is left out)");
            }
            bin = bytes.subspan(offset + 8, chunk_length);
        }
        offset = end;
    }
    return bin;
}

} // namespace

GlbChunks checkGlbContainer(std::span<const uint8_t> bytes, const std::string& file) {
    checkGlbHeader(bytes, file);
    GlbChunks chunks;
    chunks.json = checkJsonChunk(bytes, file);
    chunks.bin = checkBinChunk(bytes, uint32_t(chunks.json.size()), file);
    return chunks;
}

std::string numberText(double value) {
    char text[40];
    if (value == std::floor(value) && std::fabs(value) < 1e18) {
        std::snprintf(text, sizeof(text), "%.0f", value);
        return text;
    }
    const auto end = std::to_chars(text, text + sizeof(text), value).ptr;
    return std::string(text, end);
}

bool isEmbeddedDataUri(const std::string& uri) {
    // The prefixes tinygltf decodes (its IsDataURI); any other data: URI is taken as a path.
    static constexpr std::array<std::string_view, 7> kPrefixes = {
        "data:application/octet-stream;base64,",
        "data:image/jpeg;base64,",
        "data:image/png;base64,",
        "data:image/bmp;base64,",
        "data:image/gif;base64,",
        "data:text/plain;base64,",
        "data:application/gltf-buffer;base64,"};
    return std::any_of(kPrefixes.begin(), kPrefixes.end(),
                       [&](std::string_view prefix) { return uri.starts_with(prefix); });
}

namespace {

// Percent-decoding as tinygltf's dlib::urldecode does it, byte for byte (a non-hex digit counts
// as 0), with '+' a space or itself.
std::string decodeUri(const std::string& uri, bool plus_is_space) {
    auto hex = [](unsigned char c) -> unsigned {
        if (c >= '0' && c <= '9') {
            return c - '0';
        }
        if (c >= 'a' && c <= 'f') {
            return c - 'a' + 10;
        }
        if (c >= 'A' && c <= 'F') {
            return c - 'A' + 10;
        }
        return 0;
    };
    std::string out;
    for (size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '+' && plus_is_space) {
            out += ' ';
        } else if (uri[i] == '%' && uri.size() > i + 2) {
            out += static_cast<char>(hex(static_cast<unsigned char>(uri[i + 1])) << 4 |
                                     hex(static_cast<unsigned char>(uri[i + 2])));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

} // namespace

std::string percentDecoded(const std::string& uri) {
    return decodeUri(uri, true);
}

std::string uriPath(const std::string& uri) {
    return decodeUri(uri, false);
}

UriPaths fileUriPaths(const nlohmann::json& document) {
    UriPaths paths;
    for (const char* list : {"buffers", "images"}) {
        const auto found = document.find(list);
        if (found == document.end() || !found->is_array()) {
            continue;
        }
        for (const nlohmann::json& item : *found) {
            const auto uri = item.is_object() ? item.find("uri") : item.end();
            if (uri != item.end() && uri->is_string() &&
                !isEmbeddedDataUri(uri->get<std::string>())) {
                paths.emplace(percentDecoded(uri->get<std::string>()),
                              uriPath(uri->get<std::string>()));
            }
        }
    }
    return paths;
}

ImagePlan imagePlan(const nlohmann::json& document) {
    ImagePlan plan;
    const auto images = document.find("images");
    if (images == document.end() || !images->is_array()) {
        return plan;
    }
    for (const nlohmann::json& image : *images) {
        const auto uri = image.is_object() ? image.find("uri") : image.end();
        const auto view = image.is_object() ? image.find("bufferView") : image.end();
        const auto mime = image.is_object() ? image.find("mimeType") : image.end();
        if (uri != image.end() && uri->is_string()) {
            const std::string text = uri->get<std::string>();
            plan.names.push_back(isEmbeddedDataUri(text) ? "(data: URI)" : "'" + text + "'");
        } else if (view != image.end()) {
            plan.names.push_back("(bufferView " + view->dump() +
                                 (mime != image.end() && mime->is_string()
                                      ? ", " + mime->get<std::string>()
                                      : std::string()) +
                                 ")");
        } else {
            plan.names.emplace_back("(no uri or bufferView)");
        }
    }
    std::vector<uint8_t> by_source(plan.names.size(), 0);
    std::vector<uint8_t> by_extension(plan.names.size(), 0);
    const auto mark = [](std::vector<uint8_t>& used, const nlohmann::json& holder) {
        const auto source = holder.find("source");
        if (source != holder.end() && source->is_number_unsigned() &&
            source->get<uint64_t>() < used.size()) {
            used[size_t(source->get<uint64_t>())] = 1;
        }
    };
    const auto textures = document.find("textures");
    if (textures != document.end() && textures->is_array()) {
        for (const nlohmann::json& texture : *textures) {
            if (!texture.is_object()) {
                continue;
            }
            mark(by_source, texture);
            const auto extensions = texture.find("extensions");
            if (extensions != texture.end() && extensions->is_object()) {
                for (const auto& [name, extension] : extensions->items()) {
                    if (extension.is_object()) {
                        mark(by_extension, extension);
                    }
                }
            }
        }
    }
    plan.extensionOnly.resize(plan.names.size());
    for (size_t i = 0; i < plan.names.size(); ++i) {
        plan.extensionOnly[i] = by_extension[i] && !by_source[i];
    }
    return plan;
}

namespace {

// Extensions whose presence in extensionsRequired we honour. KHR_mesh_quantization only widens
// the accessor component types allowed for POSITION/TEXCOORD, which the loader reads in
// general. KHR_texture_transform is deliberately absent: uvs are used untransformed.
constexpr std::array<std::string_view, 3> kSupportedRequiredExtensions = {
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_mesh_quantization",
};

constexpr int64_t kMaxIndex = std::numeric_limits<int32_t>::max();

const char* kindName(const json& value) {
    switch (value.type()) {
    case json::value_t::object:
        return "an object";
    case json::value_t::array:
        return "an array";
    case json::value_t::string:
        return "a string";
    case json::value_t::boolean:
        return "a boolean";
    case json::value_t::null:
        return "null";
    default:
        return "a number";
    }
}

// A JSON number as written, integers exactly (10000000000, not 1e10 or a wrapped int).
std::string jsonNumberText(const json& value) {
    if (value.is_number_unsigned()) {
        return std::to_string(value.get<uint64_t>());
    }
    if (value.is_number_integer()) {
        return std::to_string(value.get<int64_t>());
    }
    return numberText(value.get<double>());
}

// MAJOR.MINOR as glTF's asset.version pattern allows; nothing when `text` is not of that form.
std::optional<std::pair<uint64_t, uint64_t>> parseVersion(const std::string& text) {
    const size_t dot = text.find('.');
    auto number = [](std::string_view digits) -> std::optional<uint64_t> {
        if (digits.empty() || digits.size() > 9 ||
            !std::all_of(digits.begin(), digits.end(),
                         [](char c) { return c >= '0' && c <= '9'; })) {
            return std::nullopt;
        }
        return std::stoull(std::string(digits));
    };
    if (dot == std::string::npos) {
        return std::nullopt;
    }
    const auto major = number(std::string_view(text).substr(0, dot));
    const auto minor = number(std::string_view(text).substr(dot + 1));
    if (!major || !minor) {
        return std::nullopt;
    }
    return std::make_pair(*major, *minor);
}

class DocumentCheck {
public:
    DocumentCheck(const json& doc, const std::string& file, const GlbChunks* glb,
                  const AssetFolder& folder, MemoryBudget& budget)
        : m_doc(doc), m_file(file), m_glb(glb), m_folder(folder), m_budget(budget) {}

    void run() {
        if (!m_doc.is_object()) {
            fail(ErrorCode::InvalidArgument,
                 std::string("the document is ") + kindName(m_doc) + ", expected a JSON object");
        }
        version();
        requiredExtensions();
        scenesAndNodes();
        meshes();
        accessors();
        buffersAndViews();
        materialsAndTextures();
        images();
        lights();
    }

private:
    [[noreturn]] void fail(ErrorCode code, const std::string& what) const {
        throw LoadError{code, m_file + ": " + what};
    }

    static std::string join(const std::string& path, const std::string& key) {
        return path.empty() ? key : path + "." + key;
    }
    static std::string item(const std::string& path, size_t i) {
        return path + "[" + std::to_string(i) + "]";
    }

    static const json* find(const json& object, const char* key) {
        const auto it = object.find(key);
        return it == object.end() ? nullptr : &*it;
    }

    void expectKind(const json& value, bool ok, const std::string& path,
                    const char* expected) const {
        if (!ok) {
            fail(ErrorCode::InvalidArgument,
                 path + " is " + kindName(value) + ", expected " + expected);
        }
    }

    // Each returns the member, or null when it is absent (failing when `required`), after
    // checking its kind.
    using KindTest = bool (json::*)() const noexcept;
    const json* typed(const json& parent, const char* key, const std::string& path, KindTest test,
                      const char* expected, bool required) const {
        const json* value = member(parent, key, path, required);
        if (value) {
            expectKind(*value, ((*value).*test)(), join(path, key), expected);
        }
        return value;
    }
    const json* object(const json& parent, const char* key, const std::string& path,
                       bool required = false) const {
        return typed(parent, key, path, &json::is_object, "an object", required);
    }
    const json* array(const json& parent, const char* key, const std::string& path,
                      bool required = false) const {
        return typed(parent, key, path, &json::is_array, "an array", required);
    }
    const json* string(const json& parent, const char* key, const std::string& path,
                       bool required = false) const {
        return typed(parent, key, path, &json::is_string, "a string", required);
    }
    const json* number(const json& parent, const char* key, const std::string& path) const {
        return typed(parent, key, path, &json::is_number, "a number", false);
    }
    void boolean(const json& parent, const char* key, const std::string& path) const {
        typed(parent, key, path, &json::is_boolean, "a boolean", false);
    }
    const json* member(const json& parent, const char* key, const std::string& path,
                       bool required) const {
        const json* value = find(parent, key);
        if (!value && required) {
            fail(ErrorCode::InvalidArgument, join(path, key) + " is missing");
        }
        return value;
    }

    // tinygltf keeps indices and small counts in an int and wraps anything above 2^31 - 1, and
    // it skips a value that is not an integer literal; both must be refused here.
    int64_t indexValue(const json& value, const std::string& path,
                       const char* what = "an index") const {
        const std::string expected = std::string(what) + " (an integer in 0..2147483647)";
        if (!value.is_number()) {
            expectKind(value, false, path, expected.c_str());
        }
        const bool integer =
            value.is_number_integer() &&
            (value.is_number_unsigned() ? value.get<uint64_t>() <= uint64_t(kMaxIndex)
                                        : value.get<int64_t>() >= 0);
        if (!integer) {
            fail(ErrorCode::OutOfRange, path + " " + jsonNumberText(value) + " is not " + expected);
        }
        return value.get<int64_t>();
    }
    std::optional<int64_t> index(const json& parent, const char* key, const std::string& path,
                                 bool required = false, const char* what = "an index") const {
        const json* value = member(parent, key, path, required);
        return value ? std::optional<int64_t>(indexValue(*value, join(path, key), what))
                     : std::nullopt;
    }
    // A byte offset, length or count tinygltf keeps in a size_t: a non-negative integer literal.
    std::optional<uint64_t> size(const json& parent, const char* key, const std::string& path,
                                 bool required = false) const {
        const json* value = member(parent, key, path, required);
        if (!value) {
            return std::nullopt;
        }
        if (!value->is_number()) {
            expectKind(*value, false, join(path, key), "a non-negative integer");
        }
        if (!value->is_number_unsigned() &&
            !(value->is_number_integer() && value->get<int64_t>() >= 0)) {
            fail(ErrorCode::OutOfRange,
                 join(path, key) + " " + jsonNumberText(*value) + " is not a non-negative integer");
        }
        return value->get<uint64_t>();
    }
    void numberArray(const json& parent, const char* key, const std::string& path,
                     size_t length) const {
        const json* value = array(parent, key, path);
        if (!value) {
            return;
        }
        if (value->size() != length) {
            fail(ErrorCode::InvalidArgument, join(path, key) + " has " +
                                                 std::to_string(value->size()) +
                                                 " values, expected " + std::to_string(length));
        }
        for (size_t i = 0; i < value->size(); ++i) {
            expectKind((*value)[i], (*value)[i].is_number(), item(join(path, key), i), "a number");
        }
    }
    void indexArray(const json& parent, const char* key, const std::string& path) const {
        if (const json* value = array(parent, key, path)) {
            for (size_t i = 0; i < value->size(); ++i) {
                indexValue((*value)[i], item(join(path, key), i));
            }
        }
    }
    // Calls f(element, its path, its index) for each element of an array of objects.
    template <class F>
    void eachObject(const json& parent, const char* key, const std::string& path, F&& f,
                    bool required = false) const {
        const json* list = array(parent, key, path, required);
        if (!list) {
            return;
        }
        for (size_t i = 0; i < list->size(); ++i) {
            const std::string element = item(join(path, key), i);
            expectKind((*list)[i], (*list)[i].is_object(), element, "an object");
            f((*list)[i], element, i);
        }
    }
    size_t countOf(const char* key) const {
        const json* list = find(m_doc, key);
        return list && list->is_array() ? list->size() : 0;
    }

    void version() const {
        const json* asset = object(m_doc, "asset", "", true);
        const json* version = find(*asset, "version");
        if (!version) {
            fail(ErrorCode::InvalidArgument,
                 "asset.version is missing (glTF 2.x files say \"2.0\")");
        }
        const std::string text = version->is_string()   ? version->get<std::string>()
                                 : version->is_number() ? jsonNumberText(*version)
                                                        : std::string();
        const auto parsed = parseVersion(text);
        if (text == "1" || text.starts_with("1.")) {
            fail(ErrorCode::UnsupportedVersion,
                 "asset.version '" + text +
                     "': this is a glTF 1.0 file, which probekit does not read (it reads glTF "
                     "2.x; re-export the scene as glTF 2.0)");
        }
        expectKind(*version, version->is_string(), "asset.version", "a string");
        if (!parsed) {
            fail(ErrorCode::InvalidArgument,
                 "asset.version '" + text + "' is not of the form MAJOR.MINOR");
        }
        if (parsed->first != 2) {
            fail(ErrorCode::UnsupportedVersion,
                 "asset.version '" + text + "': probekit reads glTF 2.x only");
        }
        if (const json* min_version = string(*asset, "minVersion", "asset")) {
            const std::string min_text = min_version->get<std::string>();
            const auto min_parsed = parseVersion(min_text);
            if (!min_parsed) {
                fail(ErrorCode::InvalidArgument,
                     "asset.minVersion '" + min_text + "' is not of the form MAJOR.MINOR");
            }
            if (min_parsed->first != 2 || min_parsed->second != 0) {
                fail(ErrorCode::UnsupportedVersion,
                     "asset.minVersion '" + min_text +
                         "': the file needs a loader of that glTF version; probekit implements "
                         "glTF 2.0");
            }
        }
    }

    void requiredExtensions() const {
        for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
            if (const json* list = array(m_doc, key, "")) {
                for (size_t i = 0; i < list->size(); ++i) {
                    expectKind((*list)[i], (*list)[i].is_string(), item(key, i), "a string");
                }
            }
        }
        if (const json* required = find(m_doc, "extensionsRequired")) {
            for (const json& name : *required) {
                const std::string text = name.get<std::string>();
                if (std::find(kSupportedRequiredExtensions.begin(),
                              kSupportedRequiredExtensions.end(),
                              text) == kSupportedRequiredExtensions.end()) {
                    fail(ErrorCode::InvalidArgument,
                         "extensionsRequired: unsupported required extension " + text);
                }
            }
        }
    }

    void scenesAndNodes() const {
        index(m_doc, "scene", "");
        eachObject(m_doc, "scenes", "", [&](const json& scene, const std::string& path, size_t) {
            indexArray(scene, "nodes", path);
        });
        eachObject(m_doc, "nodes", "", [&](const json& node, const std::string& path, size_t) {
            indexArray(node, "children", path);
            index(node, "mesh", path);
            index(node, "skin", path);
            numberArray(node, "matrix", path, 16);
            numberArray(node, "translation", path, 3);
            numberArray(node, "rotation", path, 4);
            numberArray(node, "scale", path, 3);
            string(node, "name", path);
            if (const json* extensions = object(node, "extensions", path)) {
                const std::string extensions_path = join(path, "extensions");
                if (const json* light =
                        object(*extensions, "KHR_lights_punctual", extensions_path)) {
                    index(*light, "light", join(extensions_path, "KHR_lights_punctual"), true);
                }
            }
        });
    }

    void meshes() const {
        const bool draco_required = [&] {
            const json* required = find(m_doc, "extensionsRequired");
            return required && std::find(required->begin(), required->end(),
                                         "KHR_draco_mesh_compression") != required->end();
        }();
        eachObject(
            m_doc, "meshes", "", [&](const json& mesh, const std::string& mesh_path, size_t) {
                string(mesh, "name", mesh_path);
                eachObject(
                    mesh, "primitives", mesh_path,
                    [&](const json& primitive, const std::string& path, size_t) {
                        if (const json* attributes = object(primitive, "attributes", path, true)) {
                            for (const auto& [name, value] : attributes->items()) {
                                indexValue(value, join(join(path, "attributes"), name));
                            }
                        }
                        const std::optional<int64_t> indices = index(primitive, "indices", path);
                        index(primitive, "material", path);
                        index(primitive, "mode", path, false, "a mode");
                        const json* extensions = object(primitive, "extensions", path);
                        if (indices) {
                            indicesAccessor(*indices, path);
                        }
                        if (!draco_required && extensions &&
                            extensions->contains("KHR_draco_mesh_compression")) {
                            dracoFallback(primitive, path);
                        }
                    },
                    true);
            });
    }

    // tinygltf requires an index accessor with a bufferView and fails with "accessor[N]
    // invalid bufferView" otherwise; say which primitive, and why.
    void indicesAccessor(int64_t accessor, const std::string& path) const {
        const size_t count = countOf("accessors");
        if (size_t(accessor) >= count) {
            fail(ErrorCode::OutOfRange, join(path, "indices") + " " + std::to_string(accessor) +
                                            " is out of range (" + std::to_string(count) +
                                            " accessors)");
        }
        const json& target = m_doc.at("accessors").at(size_t(accessor));
        if (target.is_object() && !target.contains("bufferView")) {
            fail(ErrorCode::InvalidArgument,
                 join(path, "indices") + ": accessors[" + std::to_string(accessor) +
                     "] has no bufferView, which index accessors need" +
                     (target.contains("sparse") ? " (sparse values alone are not enough)" : ""));
        }
    }

    // A Draco primitive the file does not require must carry uncompressed accessors too (glTF's
    // fallback rule); without them there is nothing probekit can read.
    void dracoFallback(const json& primitive, const std::string& path) const {
        const json& attributes = primitive.at("attributes");
        const auto position = attributes.find("POSITION");
        if (position == attributes.end()) {
            return; // the loader skips it with a warning
        }
        const size_t accessor = position->get<size_t>();
        if (accessor < countOf("accessors")) {
            const json& target = m_doc.at("accessors").at(accessor);
            if (target.is_object() && !target.contains("bufferView") &&
                !target.contains("sparse")) {
                fail(ErrorCode::InvalidArgument,
                     path +
                         " is compressed with KHR_draco_mesh_compression, which probekit "
                         "does not decode, and has no uncompressed fallback (POSITION, "
                         "accessors[" +
                         std::to_string(accessor) + "], has no bufferView)");
            }
        }
    }

    void accessors() const {
        eachObject(m_doc, "accessors", "",
                   [&](const json& accessor, const std::string& path, size_t) {
                       index(accessor, "bufferView", path);
                       size(accessor, "byteOffset", path);
                       index(accessor, "componentType", path, true, "a component type");
                       size(accessor, "count", path, true);
                       string(accessor, "type", path, true);
                       boolean(accessor, "normalized", path);
                       if (const json* sparse = object(accessor, "sparse", path)) {
                           const std::string sparse_path = join(path, "sparse");
                           index(*sparse, "count", sparse_path, true, "a count");
                           const json* indices = object(*sparse, "indices", sparse_path, true);
                           const std::string indices_path = join(sparse_path, "indices");
                           index(*indices, "bufferView", indices_path, true);
                           index(*indices, "byteOffset", indices_path, false, "a byte offset");
                           index(*indices, "componentType", indices_path, true, "a component type");
                           const json* values = object(*sparse, "values", sparse_path, true);
                           const std::string values_path = join(sparse_path, "values");
                           index(*values, "bufferView", values_path, true);
                           index(*values, "byteOffset", values_path, false, "a byte offset");
                       }
                   });
    }

    void buffersAndViews() const {
        std::vector<uint64_t> lengths;
        eachObject(m_doc, "buffers", "",
                   [&](const json& buffer, const std::string& path, size_t i) {
                       const uint64_t length = *size(buffer, "byteLength", path, true);
                       if (length == 0) {
                           fail(ErrorCode::OutOfRange,
                                join(path, "byteLength") + " is 0, expected at least 1");
                       }
                       lengths.push_back(length);
                       const json* uri = string(buffer, "uri", path);
                       bufferData(path, length, uri ? uri->get<std::string>() : std::string(), i);
                   });
        eachObject(
            m_doc, "bufferViews", "", [&](const json& view, const std::string& path, size_t) {
                const int64_t buffer = *index(view, "buffer", path, true);
                const uint64_t offset = size(view, "byteOffset", path).value_or(0);
                const uint64_t length = *size(view, "byteLength", path, true);
                size(view, "byteStride", path);
                if (size_t(buffer) >= lengths.size()) {
                    fail(ErrorCode::OutOfRange, join(path, "buffer") + " " +
                                                    std::to_string(buffer) + " is out of range (" +
                                                    std::to_string(lengths.size()) + " buffers)");
                }
                // tinygltf reads an image's bufferView without checking it against its buffer.
                const uint64_t available = lengths[size_t(buffer)];
                if (length == 0 || offset > available || length > available - offset) {
                    fail(ErrorCode::Truncated, path + " (byteOffset " + std::to_string(offset) +
                                                   ", byteLength " + std::to_string(length) +
                                                   ") does not fit in buffers[" +
                                                   std::to_string(buffer) + "] (byteLength " +
                                                   std::to_string(available) + ")");
                }
            });
    }

    // Where a buffer's bytes come from, checked before tinygltf copies them: the budget for the
    // copy, the length against what the data: URI or BIN chunk holds, and the folder rule.
    void bufferData(const std::string& path, uint64_t length, const std::string& uri,
                    size_t index) const {
        const std::string length_text = join(path, "byteLength") + " " + std::to_string(length);
        if (uri.empty()) {
            if (!m_glb) {
                fail(ErrorCode::InvalidArgument,
                     path + " has no uri (only a GLB's buffer may leave it out)");
            }
            // The BIN chunk is buffers[0]'s alone (glTF 2.0, GLB stored buffer): a later buffer
            // without a uri would silently alias it.
            if (index != 0) {
                fail(ErrorCode::InvalidArgument,
                     path + " has no uri (in a GLB only buffers[0], the BIN chunk, may leave it "
                            "out)");
            }
            if (m_glb->bin.empty()) {
                fail(ErrorCode::InvalidArgument, path + " has no uri and the GLB has no BIN chunk");
            }
            if (length > m_glb->bin.size()) {
                fail(ErrorCode::Truncated, length_text +
                                               " is more than the GLB's BIN chunk holds (" +
                                               std::to_string(m_glb->bin.size()) + " bytes)");
            }
        } else if (isEmbeddedDataUri(uri)) {
            // Four base64 characters hold three bytes; a short last group, at most two.
            const uint64_t payload = uri.size() - uri.find(',') - 1;
            const uint64_t most = (payload * 3 + 3) / 4;
            if (length > most) {
                fail(ErrorCode::InconsistentSize,
                     length_text + " is more than its data: URI holds (at most " +
                         std::to_string(most) + " bytes)");
            }
        } else {
            fileUri(path, uri, true);
            bufferFileSize(path, uri, length);
            return; // readRegularFile charges what it reads
        }
        if (!m_budget.fits(length)) {
            fail(ErrorCode::OutOfRange,
                 m_budget.refusal("buffers[" + std::to_string(index) + "]", length));
        }
        m_budget.add(length);
    }

    void fileUri(const std::string& path, const std::string& uri, bool required) const {
        const AssetFolder::Resolved resolved = m_folder.resolve(uriPath(uri));
        const std::string field = join(path, "uri") + " '" + uri + "'";
        if (resolved.kind == AssetFolder::Resolved::Refused) {
            fail(ErrorCode::InvalidArgument, field + " " + resolved.reason);
        }
        if (resolved.kind == AssetFolder::Resolved::Missing && required) {
            fail(ErrorCode::Io, field + ": no such file in " +
                                    (m_folder.base().empty() ? std::string("the scene's folder")
                                                             : m_folder.base()));
        }
    }

    // A buffer file's size from stat, before tinygltf reads it: tinygltf takes only a file of
    // exactly byteLength bytes, but reads the whole file first, so a 10 MB buffer beside a
    // byteLength of 12 was read in full (up to the memory budget) only to be refused.
    void bufferFileSize(const std::string& path, const std::string& uri, uint64_t length) const {
        const AssetFolder::Resolved resolved = m_folder.resolve(percentDecoded(uri));
        if (resolved.kind != AssetFolder::Resolved::File) {
            return; // the folder rule's refusal is fileUri's
        }
        std::error_code ec;
        const uint64_t bytes = std::filesystem::file_size(resolved.path, ec);
        if (!ec && bytes != length) {
            fail(ErrorCode::InconsistentSize,
                 join(path, "uri") + " '" + uri + "' holds " + std::to_string(bytes) +
                     " bytes, but " + join(path, "byteLength") + " is " + std::to_string(length) +
                     " (the file must hold exactly byteLength bytes)");
        }
    }

    void textureInfo(const json& parent, const char* key, const std::string& path) const {
        if (const json* info = object(parent, key, path)) {
            const std::string info_path = join(path, key);
            index(*info, "index", info_path, true);
            index(*info, "texCoord", info_path, false, "a set number");
            object(*info, "extensions", info_path);
        }
    }

    void materialsAndTextures() const {
        eachObject(
            m_doc, "materials", "", [&](const json& material, const std::string& path, size_t) {
                string(material, "name", path);
                if (const json* pbr = object(material, "pbrMetallicRoughness", path)) {
                    const std::string pbr_path = join(path, "pbrMetallicRoughness");
                    numberArray(*pbr, "baseColorFactor", pbr_path, 4);
                    textureInfo(*pbr, "baseColorTexture", pbr_path);
                }
                numberArray(material, "emissiveFactor", path, 3);
                textureInfo(material, "emissiveTexture", path);
                if (const json* extensions = object(material, "extensions", path)) {
                    const std::string extensions_path = join(path, "extensions");
                    if (const json* strength = object(
                            *extensions, "KHR_materials_emissive_strength", extensions_path)) {
                        number(*strength, "emissiveStrength",
                               join(extensions_path, "KHR_materials_emissive_strength"));
                    }
                }
            });
        eachObject(m_doc, "textures", "",
                   [&](const json& texture, const std::string& path, size_t) {
                       index(texture, "source", path);
                   });
    }

    void images() const {
        eachObject(m_doc, "images", "", [&](const json& image, const std::string& path, size_t) {
            index(image, "bufferView", path);
            string(image, "mimeType", path);
            if (const json* uri = string(image, "uri", path)) {
                const std::string text = uri->get<std::string>();
                if (!isEmbeddedDataUri(text)) {
                    // A missing image is tinygltf's warning, and an error only if a material
                    // uses it.
                    fileUri(path, text, false);
                }
            }
        });
    }

    void lights() const {
        const json* extensions = object(m_doc, "extensions", "");
        const json* punctual =
            extensions ? object(*extensions, "KHR_lights_punctual", "extensions") : nullptr;
        if (!punctual) {
            return;
        }
        eachObject(*punctual, "lights", "extensions.KHR_lights_punctual",
                   [&](const json& light, const std::string& path, size_t) {
                       string(light, "type", path, true);
                       string(light, "name", path);
                       numberArray(light, "color", path, 3);
                       number(light, "intensity", path);
                       // tinygltf stores an absent range as 0, so only the JSON tells an
                       // explicit 0 (or a negative range) apart.
                       if (const json* range = number(light, "range", path);
                           range && !(range->get<double>() > 0.0)) {
                           fail(ErrorCode::OutOfRange, join(path, "range") + " " +
                                                           jsonNumberText(*range) +
                                                           " must be > 0 (absent: infinite)");
                       }
                       if (const json* spot = object(light, "spot", path)) {
                           number(*spot, "innerConeAngle", join(path, "spot"));
                           number(*spot, "outerConeAngle", join(path, "spot"));
                       }
                   });
    }

    const json& m_doc;
    const std::string& m_file;
    const GlbChunks* m_glb;
    const AssetFolder& m_folder;
    MemoryBudget& m_budget;
};

} // namespace

void checkDocument(const json& doc, const std::string& file, const GlbChunks* glb,
                   const AssetFolder& folder, MemoryBudget& budget) {
    DocumentCheck(doc, file, glb, folder, budget).run();
}

} // namespace probekit::baker::gltf
