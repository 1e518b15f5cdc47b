// `probekit info` and `probekit validate`: read a .pvol and describe or check it; `probekit info`
// also describes a glTF scene as the baker sees it.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "probekit/baker/scene_summary.hpp"
#include "probekit/formats/pvol.hpp"

namespace probekit::cli {
namespace {

nlohmann::json vec3Json(glm::vec3 v) {
    return nlohmann::json::array({v.x, v.y, v.z});
}

std::string formatted(const char* format, double value) {
    char text[64];
    std::snprintf(text, sizeof text, format, value);
    return text;
}

// "(x, y, z)" with %g.
std::string triple(const nlohmann::json& v) {
    return "(" + formatted("%g", v[0].get<double>()) + ", " + formatted("%g", v[1].get<double>()) +
           ", " + formatted("%g", v[2].get<double>()) + ")";
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
        ++per_level[b.level];
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

nlohmann::json describe(const PvolFile& file, const std::filesystem::path& path) {
    nlohmann::json j;
    j["file"] = path.string();
    j["file_bytes"] = std::filesystem::file_size(path);
    const BakeMetadata& m = file.metadata;
    nlohmann::json params = nlohmann::json::parse(m.parametersJson, nullptr, false);
    char hash[17];
    std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(m.sceneHash));
    j["metadata"] = {
        {"tool_version", m.toolVersion},
        {"method", m.method},
        {"parameters", params.is_discarded() ? nlohmann::json(m.parametersJson) : params},
        {"seed", m.seed},
        {"scene_hash", hash},
        // 0 in files baked since bake seconds left the file (README, "The .pvol format").
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

void printText(const nlohmann::json& j) {
    std::printf("%s: %llu bytes, %zu volume(s)\n", j["file"].get<std::string>().c_str(),
                j["file_bytes"].get<unsigned long long>(), j["volumes"].size());
    const auto& m = j["metadata"];
    // Bakes record no wall time (0) so that their files are reproducible; older files do.
    const double seconds = m["bake_seconds"].get<double>();
    const std::string took = seconds > 0.0 ? ", " + formatted("%.3f s", seconds) : "";
    std::printf("  baked by %s, method %s, seed %llu, scene hash %s%s\n",
                m["tool_version"].get<std::string>().c_str(),
                m["method"].get<std::string>().c_str(), m["seed"].get<unsigned long long>(),
                m["scene_hash"].get<std::string>().c_str(), took.c_str());
    std::printf("  parameters: %s\n", m["parameters"].dump().c_str());
    for (const auto& v : j["volumes"]) {
        const auto& r = v["resolution"];
        const auto& lo = v["bounds_min"];
        const auto& hi = v["bounds_max"];
        const bool bricked = v["layout"] == "bricked";
        if (bricked) {
            std::printf("  volume '%s': bricked, %ux%ux%u level-0 bricks, max level %u, L%d, %s\n",
                        v["name"].get<std::string>().c_str(), r[0].get<unsigned>(),
                        r[1].get<unsigned>(), r[2].get<unsigned>(), v["max_level"].get<unsigned>(),
                        v["sh_order"].get<int>(), v["format"].get<std::string>().c_str());
            std::string per_level;
            for (size_t level = 0; level < v["bricks_per_level"].size(); ++level) {
                per_level += (level == 0 ? "" : ", ") + std::string("level ") +
                             std::to_string(level) + ": " +
                             std::to_string(v["bricks_per_level"][level].get<size_t>());
            }
            std::printf("    bricks %zu (%s)\n", v["bricks"].get<size_t>(), per_level.c_str());
            const auto& cells = v["finest_cells"];
            const size_t visibility_gpu = v["visibility_gpu_bytes"].get<size_t>();
            const std::string visibility_term =
                visibility_gpu == 0 ? "" : " + visibility " + std::to_string(visibility_gpu);
            std::printf("    GPU bytes %zu (texels %zu + indirection %zu%s); dense at the finest "
                        "level (%ux%ux%u cells) %zu bytes: ratio %.3f\n",
                        v["gpu_bytes"].get<size_t>(), v["texel_bytes"].get<size_t>(),
                        v["indirection_bytes"].get<size_t>(), visibility_term.c_str(),
                        cells[0].get<unsigned>(), cells[1].get<unsigned>(),
                        cells[2].get<unsigned>(), v["dense_equivalent_bytes"].get<size_t>(),
                        v["gpu_to_dense_ratio"].get<double>());
        } else {
            std::printf("  volume '%s': %ux%ux%u %s probes, L%d, %s, %zu texel bytes\n",
                        v["name"].get<std::string>().c_str(), r[0].get<unsigned>(),
                        r[1].get<unsigned>(), r[2].get<unsigned>(),
                        v["position"].get<std::string>().c_str(), v["sh_order"].get<int>(),
                        v["format"].get<std::string>().c_str(), v["texel_bytes"].get<size_t>());
        }
        // Bricked: the spacing of the level-0 bricks (the grid is their grid).
        std::printf("    bounds (%g, %g, %g) .. (%g, %g, %g) m, %s (%g, %g, %g) m\n",
                    lo[0].get<double>(), lo[1].get<double>(), lo[2].get<double>(),
                    hi[0].get<double>(), hi[1].get<double>(), hi[2].get<double>(),
                    bricked ? "level-0 brick size" : "spacing", v["spacing"][0].get<double>(),
                    v["spacing"][1].get<double>(), v["spacing"][2].get<double>());
        std::printf("    probes %zu (valid %zu, invalid %zu), blend priority %d, fade %g m\n",
                    v["probes"].get<size_t>(), v["valid_probes"].get<size_t>(),
                    v["invalid_probes"].get<size_t>(), v["blend_priority"].get<int>(),
                    v["fade_distance"].get<double>());
        if (v["visibility"].get<bool>()) {
            const size_t probes = v["probes"].get<size_t>();
            std::printf("    visibility: yes, %zu B/probe on disk (%zu bytes), %zu B/probe on GPU "
                        "(%zu bytes)\n",
                        visibility::kBytesPerProbe, v["visibility_bytes"].get<size_t>(),
                        probes == 0 ? size_t(0) : v["visibility_gpu_bytes"].get<size_t>() / probes,
                        v["visibility_gpu_bytes"].get<size_t>());
        } else {
            std::printf("    visibility: no\n");
        }
    }
}

// ---- glTF scenes: what the baker sees (formats/CONVENTIONS.md gives the units) ----

bool isSceneFile(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext == ".gltf" || ext == ".glb";
}

const char* lightTypeName(LightType type) {
    constexpr const char* kNames[] = {"point", "spot", "directional"}; // LightType's order
    return kNames[size_t(type)];
}

nlohmann::json describeLight(const baker::LightSummary& l) {
    const bool directional = l.type == LightType::Directional;
    nlohmann::json j = {
        {"name", l.name},
        {"type", lightTypeName(l.type)},
        {"color", vec3Json(l.color)},
        {"gltf_intensity", l.gltfIntensity},
        {"gltf_unit", directional ? "lux" : "cd"},
        {"intensity", vec3Json(l.intensity)},
        {"unit", directional ? "W/m^2" : "W/sr"},
        {"range", l.range},
    };
    if (!directional) {
        j["position"] = vec3Json(l.position);
        j["power_w"] = vec3Json(l.power);
    }
    if (l.type != LightType::Point) {
        j["direction"] = vec3Json(l.direction);
    }
    return j;
}

nlohmann::json describeScene(const baker::SceneSummary& s) {
    nlohmann::json j;
    j["file"] = s.source;
    j["kind"] = "gltf";
    j["triangles"] = s.triangles;
    j["vertices"] = s.vertices;
    j["bounds"] = {{"min", vec3Json(s.bounds.min)},
                   {"max", vec3Json(s.bounds.max)},
                   {"size", vec3Json(s.bounds.size())}};
    j["materials"] = nlohmann::json::array();
    for (const baker::MaterialSummary& m : s.materials) {
        j["materials"].push_back({{"name", m.name},
                                  {"base_color", vec3Json(m.baseColor)},
                                  {"base_color_textured", m.baseColorTextured},
                                  {"emission", vec3Json(m.emission)},
                                  {"emission_textured", m.emissionTextured},
                                  {"triangles", m.triangles}});
    }
    j["lights"] = nlohmann::json::array();
    for (const baker::LightSummary& l : s.lights) {
        j["lights"].push_back(describeLight(l));
    }
    j["emitters"] = {{"triangles", s.emitters.triangles},
                     {"area_m2", s.emitters.area},
                     {"power_w", {s.emitters.power.x, s.emitters.power.y, s.emitters.power.z}}};
    j["environment_black"] = s.environmentBlack;
    j["warnings"] = s.warnings;
    return j;
}

void printLight(const nlohmann::json& l) {
    const std::string type = l["type"].get<std::string>();
    const double range = l["range"].get<double>();
    const std::string name = l["name"].get<std::string>();
    std::printf("    %s light '%s'", type.c_str(), name.c_str());
    if (type != "directional") {
        std::printf(" at %s m", triple(l["position"]).c_str());
    }
    if (type != "point") {
        std::printf(" shining along %s", triple(l["direction"]).c_str());
    }
    std::printf(": glTF intensity %g %s x colour %s\n", l["gltf_intensity"].get<double>(),
                l["gltf_unit"].get<std::string>().c_str(), triple(l["color"]).c_str());
    if (type == "directional") {
        std::printf("      = %s W/m^2 on a surface facing it (lux taken as W/m^2)\n",
                    triple(l["intensity"]).c_str());
        return;
    }
    std::printf("      = %s W/sr (candela taken as W/sr), power %s W (%s), range %s\n",
                triple(l["intensity"]).c_str(), triple(l["power_w"]).c_str(),
                type == "point" ? "4 pi I" : "I x the cone falloff's solid angle",
                range > 0.0 ? formatted("%g m", range).c_str() : "infinite");
}

void printSceneText(const nlohmann::json& j) {
    const auto& b = j["bounds"];
    std::printf("%s: glTF scene, %llu triangles, %llu vertices\n",
                j["file"].get<std::string>().c_str(), j["triangles"].get<unsigned long long>(),
                j["vertices"].get<unsigned long long>());
    std::printf("  bounds %s .. %s m, size %s m\n", triple(b["min"]).c_str(),
                triple(b["max"]).c_str(), triple(b["size"]).c_str());
    std::printf("  materials: %zu\n", j["materials"].size());
    for (const auto& m : j["materials"]) {
        std::printf("    '%s': base colour %s%s", m["name"].get<std::string>().c_str(),
                    triple(m["base_color"]).c_str(),
                    m["base_color_textured"].get<bool>() ? " x texture" : ", untextured");
        const auto& e = m["emission"];
        if (e[0].get<double>() > 0 || e[1].get<double>() > 0 || e[2].get<double>() > 0) {
            std::printf(", emissive %s W/(sr m^2)%s", triple(e).c_str(),
                        m["emission_textured"].get<bool>() ? " x texture" : "");
        }
        std::printf(", %llu triangles\n", m["triangles"].get<unsigned long long>());
    }
    std::printf("  lights: %zu\n", j["lights"].size());
    for (const auto& l : j["lights"]) {
        printLight(l);
    }
    const auto& em = j["emitters"];
    std::printf("  emitters: %llu emissive triangles", em["triangles"].get<unsigned long long>());
    if (em["triangles"].get<unsigned long long>() > 0) {
        std::printf(", area %g m^2, power %s W (2 pi x area x radiance: two-sided)",
                    em["area_m2"].get<double>(), triple(em["power_w"]).c_str());
    }
    std::printf("\n  environment: none in the file (a bake takes it from --env or the config's "
                "\"environment\"; black by default)\n");
    for (const auto& w : j["warnings"]) {
        std::printf("  warning: %s\n", w.get<std::string>().c_str());
    }
}

int infoScene(const std::string& path, bool json, const std::vector<std::string>& asset_roots) {
    baker::LoadOptions load_options;
    load_options.assetRoots.assign(asset_roots.begin(), asset_roots.end());
    Result<baker::Scene> scene = baker::loadGltf(path, load_options);
    if (!scene) {
        std::fprintf(stderr, "probekit info: %s\n", scene.error().message.c_str());
        return kExitFailure;
    }
    const nlohmann::json j = describeScene(baker::summarizeScene(scene.value()));
    if (json) {
        std::printf("%s\n", j.dump(2).c_str());
    } else {
        printSceneText(j);
    }
    return kExitOk;
}

} // namespace

void addInfoCommand(CLI::App& app, Command& selected) {
    struct Options {
        std::string file;
        bool json = false;
        std::vector<std::string> assetRoots;
    };
    auto options = std::make_shared<Options>();
    CLI::App* cmd = app.add_subcommand(
        "info", "Describe the volumes and bake metadata of a .pvol, or what the baker sees in a "
                "glTF scene (.gltf, .glb)");
    cmd->add_option("FILE", options->file, "the .pvol file or glTF scene")->required();
    cmd->add_flag("--json", options->json, "print one JSON object instead of text");
    addAssetRootOption(cmd, options->assetRoots);
    cmd->callback([options, &selected] {
        selected = [options] {
            if (isSceneFile(options->file)) {
                return infoScene(options->file, options->json, options->assetRoots);
            }
            Result<PvolFile> file = readPvol(options->file);
            if (!file) {
                std::fprintf(stderr, "probekit info: %s\n", file.error().message.c_str());
                return kExitFailure;
            }
            const nlohmann::json j = describe(file.value(), options->file);
            if (options->json) {
                std::printf("%s\n", j.dump(2).c_str());
            } else {
                printText(j);
            }
            return kExitOk;
        };
    });
}

void addValidateCommand(CLI::App& app, Command& selected) {
    auto file_path = std::make_shared<std::string>();
    CLI::App* cmd = app.add_subcommand(
        "validate", "Check a .pvol (header, checksum, every field); exit 0 when valid, 1 with "
                    "the reason otherwise");
    cmd->add_option("FILE", *file_path, "the .pvol file")->required();
    cmd->callback([file_path, &selected] {
        selected = [file_path] {
            Result<PvolFile> file = readPvol(*file_path);
            if (!file) {
                std::fprintf(stderr, "probekit validate: %s\n", file.error().message.c_str());
                return kExitFailure;
            }
            std::printf("%s: valid (%zu volume(s))\n", file_path->c_str(),
                        file.value().volumes.size());
            return kExitOk;
        };
    });
}

} // namespace probekit::cli
