#include "info_format.hpp"

#include <cstdarg>
#include <cstdio>
#include <exception>
#include <vector>

#include <nlohmann/json.hpp>

#include "probekit/formats/json_nesting.hpp"

#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

nlohmann::json vec3Json(glm::vec3 v) {
    return nlohmann::json::array({v.x, v.y, v.z});
}

// printf onto the end of a string.
[[gnu::format(printf, 2, 3)]] void appendf(std::string& out, const char* format, ...) {
    va_list args;
    va_start(args, format);
    va_list again;
    va_copy(again, args);
    const int length = std::vsnprintf(nullptr, 0, format, args);
    va_end(args);
    if (length > 0) {
        const size_t old_size = out.size();
        out.resize(old_size + size_t(length) + 1);
        std::vsnprintf(out.data() + old_size, size_t(length) + 1, format, again);
        out.resize(old_size + size_t(length));
    }
    va_end(again);
}

// Bytes of a dense volume at the finest level of a bricked one: probes on the finest lattice,
// (3 N + 1) per axis for N finest cells, same planes and storage.
size_t denseEquivalentBytes(const Volume& v) {
    const glm::uvec3 cells = brick::finestCells(v.desc.grid.resolution(), v.desc.bricks.maxLevel);
    const glm::uvec3 probes = cells * brick::kBrickCells + 1u;
    return size_t(probes.x) * probes.y * probes.z * v.planes() * 4 *
           bytesPerComponent(v.desc.storage);
}

// The bricked-only fields: levels, brick counts and the GPU footprint against dense.
void describeBricks(const Volume& v, nlohmann::json& jv) {
    const brick::BrickLayout& layout = v.desc.bricks;
    std::vector<size_t> per_level(layout.maxLevel + 1, 0);
    for (const brick::Brick& b : layout.bricks) {
        ++per_level[b.level]; // validateVolume: every level is within maxLevel
    }
    const glm::uvec3 cells = brick::finestCells(v.desc.grid.resolution(), layout.maxLevel);
    const size_t dense_bytes = denseEquivalentBytes(v);
    jv["max_level"] = layout.maxLevel;
    jv["bricks"] = layout.bricks.size();
    jv["bricks_per_level"] = per_level;
    jv["finest_cells"] = {cells.x, cells.y, cells.z};
    jv["indirection_bytes"] = v.indirection.size() * sizeof(uint32_t);
    jv["gpu_bytes"] = v.gpuBytes();
    jv["dense_equivalent_bytes"] = dense_bytes;
    jv["gpu_to_dense_ratio"] = double(v.gpuBytes()) / double(dense_bytes);
}

// Strings hold the file's bytes unchanged; jsonText and terminalText make them printable.
nlohmann::json describe(const PvolFile& file, std::string_view source, uint64_t file_bytes) {
    nlohmann::json j;
    j["file"] = std::string(source);
    j["file_bytes"] = file_bytes;
    const BakeMetadata& m = file.metadata;
    // Parameters that are not JSON are shown as the string they are.
    Result<nlohmann::json> params = parseJsonText<nlohmann::json>(m.parametersJson, "parameters");
    char hash[17];
    std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(m.sceneHash));
    j["metadata"] = {
        {"tool_version", m.toolVersion},
        {"method", m.method},
        {"parameters", params ? std::move(params).value() : nlohmann::json(m.parametersJson)},
        {"seed", m.seed},
        {"scene_hash", hash},
        // 0 in files baked since bake seconds left the file (docs/format.md#the-pvol-format).
        {"bake_seconds", m.bakeSeconds}};
    j["volumes"] = nlohmann::json::array();
    for (const Volume& v : file.volumes) {
        const grid::GridLayout& g = v.desc.grid;
        const glm::uvec3 res = g.resolution();
        nlohmann::json jv = {
            {"name", v.desc.name},
            {"layout", std::string(toString(v.desc.layout))},
            {"resolution", {res.x, res.y, res.z}},
            {"position", std::string(grid::toString(g.mode()))},
            {"sh_order", int(v.desc.shOrder)},
            {"format", std::string(toString(v.desc.storage))},
            {"bounds_min", vec3Json(g.bounds().min)},
            {"bounds_max", vec3Json(g.bounds().max)},
            {"spacing", vec3Json(g.spacing())},
            {"frame_rotation_wxyz",
             {g.frame().rotation.w, g.frame().rotation.x, g.frame().rotation.y,
              g.frame().rotation.z}},
            {"frame_translation", vec3Json(g.frame().translation)},
            {"blend_priority", v.desc.blendPriority},
            {"fade_distance", v.desc.fadeDistance},
            {"probes", v.probeCount()},
            {"valid_probes", v.validCount()},
            {"invalid_probes", v.probeCount() - v.validCount()},
            {"texel_planes", v.planes()},
            {"texel_bytes", v.texelBytes()},
            {"visibility", v.hasVisibility()},
            {"visibility_bytes", v.visibility.size()},
            {"visibility_gpu_bytes", v.visibilityGpuBytes()},
        };
        if (v.desc.layout == VolumeLayout::Bricked) {
            describeBricks(v, jv);
        }
        j["volumes"].push_back(jv);
    }
    return j;
}

// A string field of `j`, escaped for the terminal.
std::string shown(const nlohmann::json& j) {
    return terminalText(j.get<std::string>());
}

std::string formatText(const nlohmann::json& j) {
    std::string out;
    appendf(out, "%s: %llu bytes, %zu volume(s)\n", shown(j["file"]).c_str(),
            j["file_bytes"].get<unsigned long long>(), j["volumes"].size());
    const auto& m = j["metadata"];
    // Bakes record no wall time (0) so that their files are reproducible; older files do.
    const double seconds = m["bake_seconds"].get<double>();
    std::string took;
    if (seconds > 0.0) {
        appendf(took, ", %.3f s", seconds);
    }
    appendf(out, "  baked by %s, method %s, seed %llu, scene hash %s%s\n",
            shown(m["tool_version"]).c_str(), shown(m["method"]).c_str(),
            m["seed"].get<unsigned long long>(), shown(m["scene_hash"]).c_str(), took.c_str());
    // Parameters that are not JSON are shown as the file holds them, escaped.
    const nlohmann::json& params = m["parameters"];
    appendf(
        out, "  parameters: %s\n",
        terminalText(params.is_string() ? params.get<std::string>() : jsonText(params)).c_str());
    for (const auto& v : j["volumes"]) {
        const auto& r = v["resolution"];
        const auto& lo = v["bounds_min"];
        const auto& hi = v["bounds_max"];
        const bool bricked = v["layout"] == "bricked";
        if (bricked) {
            appendf(out, "  volume '%s': bricked, %ux%ux%u level-0 bricks, max level %u, L%d, %s\n",
                    shown(v["name"]).c_str(), r[0].get<unsigned>(), r[1].get<unsigned>(),
                    r[2].get<unsigned>(), v["max_level"].get<unsigned>(), v["sh_order"].get<int>(),
                    v["format"].get<std::string>().c_str());
            std::string per_level;
            for (size_t level = 0; level < v["bricks_per_level"].size(); ++level) {
                per_level += (level == 0 ? "" : ", ") + std::string("level ") +
                             std::to_string(level) + ": " +
                             std::to_string(v["bricks_per_level"][level].get<size_t>());
            }
            appendf(out, "    bricks %zu (%s)\n", v["bricks"].get<size_t>(), per_level.c_str());
            const auto& cells = v["finest_cells"];
            const size_t visibility_gpu = v["visibility_gpu_bytes"].get<size_t>();
            const std::string visibility_term =
                visibility_gpu == 0 ? "" : " + visibility " + std::to_string(visibility_gpu);
            appendf(out,
                    "    GPU bytes %zu (texels %zu + indirection %zu%s); dense at the finest "
                    "level (%ux%ux%u cells) %zu bytes: ratio %.3f\n",
                    v["gpu_bytes"].get<size_t>(), v["texel_bytes"].get<size_t>(),
                    v["indirection_bytes"].get<size_t>(), visibility_term.c_str(),
                    cells[0].get<unsigned>(), cells[1].get<unsigned>(), cells[2].get<unsigned>(),
                    v["dense_equivalent_bytes"].get<size_t>(),
                    v["gpu_to_dense_ratio"].get<double>());
        } else {
            appendf(out, "  volume '%s': %ux%ux%u %s probes, L%d, %s, %zu texel bytes\n",
                    shown(v["name"]).c_str(), r[0].get<unsigned>(), r[1].get<unsigned>(),
                    r[2].get<unsigned>(), v["position"].get<std::string>().c_str(),
                    v["sh_order"].get<int>(), v["format"].get<std::string>().c_str(),
                    v["texel_bytes"].get<size_t>());
        }
        // Bricked: the spacing of the level-0 bricks (the grid is their grid).
        appendf(out, "    bounds (%g, %g, %g) .. (%g, %g, %g) m, %s (%g, %g, %g) m\n",
                lo[0].get<double>(), lo[1].get<double>(), lo[2].get<double>(), hi[0].get<double>(),
                hi[1].get<double>(), hi[2].get<double>(),
                bricked ? "level-0 brick size" : "spacing", v["spacing"][0].get<double>(),
                v["spacing"][1].get<double>(), v["spacing"][2].get<double>());
        appendf(out, "    probes %zu (valid %zu, invalid %zu), blend priority %d, fade %g m\n",
                v["probes"].get<size_t>(), v["valid_probes"].get<size_t>(),
                v["invalid_probes"].get<size_t>(), v["blend_priority"].get<int>(),
                v["fade_distance"].get<double>());
        if (v["visibility"].get<bool>()) {
            const size_t probes = v["probes"].get<size_t>();
            appendf(out,
                    "    visibility: yes, %zu B/probe on disk (%zu bytes), %zu B/probe on GPU "
                    "(%zu bytes)\n",
                    visibility::kBytesPerProbe, v["visibility_bytes"].get<size_t>(),
                    probes == 0 ? size_t(0) : v["visibility_gpu_bytes"].get<size_t>() / probes,
                    v["visibility_gpu_bytes"].get<size_t>());
        } else {
            appendf(out, "    visibility: no\n");
        }
    }
    return out;
}

} // namespace

Result<std::string> formatInfo(const PvolFile& file, std::string_view source, uint64_t file_bytes,
                               bool json) {
    try {
        // What describe() assumes (brick levels within max level, sizes that agree) is what
        // validateVolume checks; a file from decodePvol or readPvol always passes.
        for (size_t i = 0; i < file.volumes.size(); ++i) {
            if (Result<void> valid = validateVolume(file.volumes[i]); !valid) {
                return makeError(valid.error().code, std::string(source) + ": volume " +
                                                         std::to_string(i) + ": " +
                                                         valid.error().message);
            }
        }
        const nlohmann::json j = describe(file, source, file_bytes);
        return json ? jsonText(j, 2) + "\n" : formatText(j);
    } catch (const std::exception& e) {
        return makeError(ErrorCode::InvalidArgument,
                         std::string(source) + ": cannot describe the file: " + e.what());
    }
}

} // namespace probekit::cli
