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
#include "info_format.hpp"
#include "probekit/baker/scene_summary.hpp"
#include "probekit/formats/pvol.hpp"
#include "terminal_text.hpp"

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
    const std::string name = terminalText(l["name"].get<std::string>());
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
                terminalText(j["file"].get<std::string>()).c_str(),
                j["triangles"].get<unsigned long long>(), j["vertices"].get<unsigned long long>());
    std::printf("  bounds %s .. %s m, size %s m\n", triple(b["min"]).c_str(),
                triple(b["max"]).c_str(), triple(b["size"]).c_str());
    std::printf("  materials: %zu\n", j["materials"].size());
    for (const auto& m : j["materials"]) {
        std::printf("    '%s': base colour %s%s",
                    terminalText(m["name"].get<std::string>()).c_str(),
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
        std::printf("  warning: %s\n", terminalText(w.get<std::string>()).c_str());
    }
}

int infoScene(const std::string& path, bool json, const std::vector<std::string>& asset_roots) {
    baker::LoadOptions load_options;
    load_options.assetRoots.assign(asset_roots.begin(), asset_roots.end());
    Result<baker::Scene> scene = baker::loadGltf(path, load_options);
    if (!scene) {
        printError("info", scene.error().message);
        return kExitFailure;
    }
    const nlohmann::json j = describeScene(baker::summarizeScene(scene.value()));
    if (json) {
        std::printf("%s\n", jsonText(j, 2).c_str());
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
                printError("info", file.error().message);
                return kExitFailure;
            }
            // readPvol has checked that the file is exactly its header and payload.
            std::error_code error;
            const uintmax_t bytes = std::filesystem::file_size(options->file, error);
            Result<std::string> text =
                formatInfo(file.value(), options->file, error ? 0 : uint64_t(bytes), options->json);
            if (!text) {
                printError("info", text.error().message);
                return kExitFailure;
            }
            std::fputs(text.value().c_str(), stdout);
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
                printError("validate", file.error().message);
                return kExitFailure;
            }
            std::printf("%s: valid (%zu volume(s))\n", terminalText(*file_path).c_str(),
                        file.value().volumes.size());
            return kExitOk;
        };
    });
}

} // namespace probekit::cli
