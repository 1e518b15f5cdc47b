// glTF 2.0 (.gltf / .glb) -> probekit::baker::Scene, through tinygltf.
//
// Before tinygltf sees the file, gltf_input.cpp checks the GLB container, the JSON's nesting
// depth and the kinds of the fields read here, the glTF version and the required extensions,
// and gltf_io.cpp's callbacks hold every buffer and image read to the scene's folder and the
// memory budget. tinygltf then parses the JSON, resolves buffers (data: URIs, external files, the
// GLB BIN chunk) and decodes images with its stb_image loader (PNG/JPEG come back as 8- or 16-bit
// RGBA). Everything tinygltf does not check (accessor ranges, strides, index values, node graphs,
// light and material values, the bytes each accessor expands to) is checked here, so a malformed
// file gives an error naming the file and the field, never a crash.
#include <algorithm>
#include <cstring>
#include <limits>
#include <span>
#include <sstream>
#include <string_view>
#include <utility>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/json_nesting.hpp"
#include "probekit/formats/pvol.hpp"
#include "scene/gltf_input.hpp"
#include "scene/gltf_loader.hpp"

namespace probekit::baker {
namespace {

using gltf::GltfLoader;
using gltf::LoadError;
using gltf::MemoryBudget;
using gltf::numberText;

std::string trimmed(std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' ')) {
        text.pop_back();
    }
    return text;
}

} // namespace

namespace gltf {

Scene GltfLoader::load(std::optional<int> scene_index, uint64_t source_hash,
                       const std::string& tinygltf_warnings) {
    m_scene.sourceHash = source_hash;
    m_scene.source = m_file;
    std::istringstream lines(tinygltf_warnings);
    for (std::string line; std::getline(lines, line);) {
        if (!trimmed(line).empty()) {
            warn("tinygltf: " + trimmed(line));
        }
    }
    loadMaterials();
    checkNodeForest();
    const std::vector<int> roots = sceneRoots(scene_index);
    const std::vector<int> reachable = traverse(roots);
    checkInstancedGrowth(reachable);
    for (const int node_index : reachable) {
        loadNode(node_index);
    }
    BoundsBuilder scene_bounds;
    for (size_t i = 0; i < m_scene.nodes.size(); ++i) {
        if (m_node_has_triangles[i]) {
            scene_bounds.add(m_scene.nodes[i].worldBounds);
        }
    }
    m_scene.bounds = scene_bounds.box();
    if (m_scene.materials.empty()) {
        defaultMaterial();
    }
    return std::move(m_scene);
}

} // namespace gltf

namespace {

// The GLB magic decides, whatever the extension; a .glb without it is reported as such by the
// container check.
bool isBinaryGltf(std::span<const uint8_t> bytes, const std::filesystem::path& name) {
    const bool has_magic = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    std::string extension = name.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return has_magic || extension == ".glb";
}

// Checks the JSON document before tinygltf sees it: nesting, the parsed size against the
// budget (charged), syntax, and every field gltf_input checks. Returns what the file callbacks
// need to know of it (its URIs' paths, its images). Throws LoadError.
std::pair<gltf::UriPaths, gltf::ImagePlan>
checkJsonDocument(std::span<const uint8_t> text, uint64_t text_offset, const std::string& file,
                  const gltf::GlbChunks* glb, const gltf::AssetFolder& folder,
                  MemoryBudget& budget) {
    const uint64_t values = gltf::checkJsonNesting(text, text_offset, file);
    // Two parses hold the document (the check's, then tinygltf's with its Values); the first is
    // gone before the second, and some of tinygltf's stays in the model.
    const uint64_t document_bytes =
        values > UINT64_MAX / gltf::kJsonValueBytes ? UINT64_MAX : values * gltf::kJsonValueBytes;
    if (!budget.fits(document_bytes)) {
        throw LoadError{
            ErrorCode::OutOfRange,
            file + ": " +
                budget.refusal("the JSON document (" + std::to_string(values) + " values, parsed)",
                               document_bytes)};
    }
    budget.add(document_bytes);
    // glTF 2.0 forbids a key given twice in one object (KhronosGroup/glTF#846); nlohmann and
    // tinygltf keep the last without a word, so an exporter's repeated "bufferViews" would drop
    // the first array's views and bake a different scene. The parse watches for them.
    detail::DuplicateKeyFinder<nlohmann::json> duplicates;
    nlohmann::json document;
    try {
        document = nlohmann::json::parse(
            text.begin(), text.end(),
            [&duplicates](int depth, nlohmann::json::parse_event_t event, nlohmann::json& value) {
                return duplicates(depth, event, value);
            });
    } catch (const nlohmann::json::exception& e) {
        throw LoadError{ErrorCode::InvalidArgument,
                        file + ": not valid JSON: " + std::string(e.what())};
    }
    if (!duplicates.firstRepeated().empty()) {
        throw LoadError{ErrorCode::InvalidArgument,
                        file + ": " + duplicates.firstRepeated() +
                            ": given twice (glTF 2.0 forbids a key repeated in one object; "
                            "readers would keep only the last)"};
    }
    gltf::checkDocument(document, file, glb, folder, budget);
    return {gltf::fileUriPaths(document), gltf::imagePlan(document)};
}

// tinygltf's parse of the checked file, its buffers and images read through the folder rule and
// the budget; `warning` receives tinygltf's warnings. Throws LoadError.
tinygltf::Model parseModel(std::span<const uint8_t> bytes, std::span<const uint8_t> text,
                           bool binary, const gltf::AssetFolder& folder, MemoryBudget& budget,
                           const std::string& file, std::pair<gltf::UriPaths, gltf::ImagePlan> plan,
                           std::string& warning, std::vector<std::filesystem::path>& read) {
    tinygltf::TinyGLTF parser;
    gltf::IoContext io{
        folder, budget, file, std::nullopt, {}, std::move(plan.first), std::move(plan.second)};
    gltf::installIoCallbacks(parser, io);
    tinygltf::Model model;
    std::string error;
    const bool parsed =
        binary ? parser.LoadBinaryFromMemory(&model, &error, &warning, bytes.data(),
                                             static_cast<unsigned int>(bytes.size()), folder.base())
               : parser.LoadASCIIFromString(&model, &error, &warning,
                                            reinterpret_cast<const char*>(text.data()),
                                            static_cast<unsigned int>(text.size()), folder.base());
    if (io.refusal) {
        // A file the rule refused, or an image refused before decoding: say why, rather
        // than tinygltf's "File not found" or nothing (it only warns about images).
        throw *io.refusal;
    }
    if (!parsed) {
        std::string message = trimmed(error);
        if (!trimmed(warning).empty()) {
            message += (message.empty() ? "" : "; ") + trimmed(warning);
        }
        throw LoadError{ErrorCode::InvalidArgument,
                        file + ": " + (message.empty() ? "tinygltf failed" : message)};
    }
    read = std::move(io.read);
    return model;
}

} // namespace

Result<Scene> loadGltfBytes(std::span<const uint8_t> bytes, const std::filesystem::path& name,
                            const LoadOptions& options) {
    const std::string file = name.string();
    try {
        MemoryBudget budget(options.maxMemoryBytes);
        if (!budget.fits(bytes.size())) {
            return makeError(ErrorCode::OutOfRange,
                             file + ": " + budget.refusal("the file", bytes.size()));
        }
        budget.add(bytes.size());
        if (bytes.size() > std::numeric_limits<unsigned int>::max()) {
            return makeError(ErrorCode::OutOfRange, file + ": larger than 4 GiB");
        }
        gltf::AssetFolder folder(name, options.assetRoots);
        if (!folder.unresolvedRoots().empty()) {
            return makeError(ErrorCode::Io, "LoadOptions::assetRoots: '" +
                                                folder.unresolvedRoots().front() +
                                                "' is not an existing folder");
        }
        const bool binary = isBinaryGltf(bytes, name);
        gltf::GlbChunks glb;
        std::span<const uint8_t> text = bytes;
        uint64_t text_offset = 0;
        if (binary) {
            glb = gltf::checkGlbContainer(bytes, file);
            text = glb.json;
            text_offset = glb.jsonOffset;
        }
        std::pair<gltf::UriPaths, gltf::ImagePlan> plan =
            checkJsonDocument(text, text_offset, file, binary ? &glb : nullptr, folder, budget);
        std::string warning;
        std::vector<std::filesystem::path> read;
        const tinygltf::Model model =
            parseModel(bytes, text, binary, folder, budget, file, std::move(plan), warning, read);
        GltfLoader loader(model, file, budget);
        Result<Scene> scene = loader.load(options.sceneIndex, xxhash64(bytes), warning);
        if (scene) {
            scene.value().files = std::move(read);
            applyUnitScale(scene.value(), options.scale);
            if (Result<void> size = checkSceneSize(scene.value(), file, options.scale); !size) {
                return size.error();
            }
            if (std::string w = implausibleSizeWarning(scene.value(), file); !w.empty()) {
                scene.value().warnings.push_back(std::move(w));
            }
        }
        return scene;
    } catch (const LoadError& e) {
        return makeError(e.code, e.message);
    } catch (const std::exception& e) {
        return makeError(ErrorCode::InvalidArgument, file + ": " + e.what());
    }
}

Result<Scene> loadGltf(const std::filesystem::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
        return makeError(ErrorCode::Io, file + ": no such file");
    }
    // The budget here only bounds the read; loadGltfBytes charges the bytes again.
    MemoryBudget read_budget(options.maxMemoryBytes);
    Result<std::vector<uint8_t>> bytes = gltf::readRegularFile(path, file, read_budget);
    if (!bytes) {
        return bytes.error();
    }
    Result<Scene> scene = loadGltfBytes(bytes.value(), path, options);
    if (scene) {
        scene.value().files.insert(scene.value().files.begin(), path);
    }
    return scene;
}

} // namespace probekit::baker
