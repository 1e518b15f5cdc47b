// Bake configuration: JSON -> BakeConfig with errors that name the file and the field.
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "probekit/baker/bake.hpp"

namespace probekit::baker {
namespace {

using Json = nlohmann::json;

// Thrown inside this file only, turned into a Result at parseBakeConfig's boundary.
struct ConfigError {
    std::string message;
};

class Reader {
public:
    explicit Reader(std::string_view source) : m_source(source) {}

    [[noreturn]] void fail(const std::string& path, const std::string& what) const {
        throw ConfigError{m_source + ": " + path + ": " + what};
    }

    void checkKeys(const Json& object, const std::string& path,
                   std::initializer_list<const char*> allowed) const {
        if (!object.is_object()) {
            fail(path.empty() ? "(top level)" : path, "must be a JSON object");
        }
        std::set<std::string> known(allowed.begin(), allowed.end());
        for (const auto& [key, value] : object.items()) {
            if (!known.count(key)) {
                fail(join(path, key), "unknown field (known: " + list(allowed) + ")");
            }
        }
    }

    double number(const Json& v, const std::string& path) const {
        if (!v.is_number()) {
            fail(path, "must be a number");
        }
        const double d = v.get<double>();
        if (!std::isfinite(d)) {
            fail(path, "must be finite");
        }
        return d;
    }

    double positive(const Json& v, const std::string& path) const {
        const double d = number(v, path);
        if (!(d > 0.0)) {
            fail(path, "must be > 0 (got " + v.dump() + ")");
        }
        return d;
    }

    uint64_t unsignedInt(const Json& v, const std::string& path, uint64_t lo, uint64_t hi) const {
        if (!v.is_number_integer() && !v.is_number_unsigned()) {
            fail(path, "must be a whole number");
        }
        if (v.is_number_integer() && v.get<int64_t>() < 0) {
            fail(path, "must be >= " + std::to_string(lo) + " (got " + v.dump() + ")");
        }
        const uint64_t u = v.get<uint64_t>();
        if (u < lo || u > hi) {
            fail(path, "must be in " + std::to_string(lo) + ".." + std::to_string(hi) + " (got " +
                           v.dump() + ")");
        }
        return u;
    }

    glm::vec3 vec3(const Json& v, const std::string& path) const {
        if (!v.is_array() || v.size() != 3) {
            fail(path, "must be an array of 3 numbers");
        }
        return glm::vec3(float(number(v[0], path + "[0]")), float(number(v[1], path + "[1]")),
                         float(number(v[2], path + "[2]")));
    }

    std::string string(const Json& v, const std::string& path) const {
        if (!v.is_string()) {
            fail(path, "must be a string");
        }
        return v.get<std::string>();
    }

    std::string choice(const Json& v, const std::string& path,
                       std::initializer_list<const char*> allowed) const {
        const std::string s = string(v, path);
        for (const char* a : allowed) {
            if (s == a) {
                return s;
            }
        }
        fail(path, "\"" + s + "\" is not one of " + list(allowed));
    }

    static std::string join(const std::string& path, const std::string& key) {
        return path.empty() ? key : path + "." + key;
    }

private:
    static std::string list(std::initializer_list<const char*> items) {
        std::string out;
        for (const char* i : items) {
            out += (out.empty() ? "" : ", ") + std::string(i);
        }
        return out;
    }
    std::string m_source;
};

BoundsConfig parseBounds(const Reader& r, const Json& j, const std::string& path) {
    r.checkKeys(j, path, {"mode", "center", "size", "min", "max", "nodes", "node", "padding"});
    BoundsConfig b;
    if (!j.contains("mode")) {
        r.fail(path + ".mode", "missing (custom, auto-world or auto-local)");
    }
    const std::string mode =
        r.choice(j["mode"], path + ".mode", {"custom", "auto-world", "auto-local"});
    if (j.contains("padding")) {
        b.padding = float(r.number(j["padding"], path + ".padding"));
        if (b.padding < 0.0f) {
            r.fail(path + ".padding", "must be >= 0");
        }
    }
    if (mode == "custom") {
        b.mode = BoundsMode::Custom;
        const bool center_size = j.contains("center") || j.contains("size");
        const bool min_max = j.contains("min") || j.contains("max");
        if (center_size == min_max) {
            r.fail(path, "custom bounds need either center + size or min + max");
        }
        if (center_size) {
            if (!j.contains("center") || !j.contains("size")) {
                r.fail(path, "custom bounds need both center and size");
            }
            const glm::vec3 c = r.vec3(j["center"], path + ".center");
            const glm::vec3 s = r.vec3(j["size"], path + ".size");
            for (int a = 0; a < 3; ++a) {
                if (!(s[a] > 0.0f)) {
                    r.fail(path + ".size[" + std::to_string(a) + "]",
                           "must be > 0 (got " + std::to_string(s[a]) + ")");
                }
            }
            b.min = c - 0.5f * s;
            b.max = c + 0.5f * s;
        } else {
            if (!j.contains("min") || !j.contains("max")) {
                r.fail(path, "custom bounds need both min and max");
            }
            b.min = r.vec3(j["min"], path + ".min");
            b.max = r.vec3(j["max"], path + ".max");
            for (int a = 0; a < 3; ++a) {
                if (!(b.max[a] > b.min[a])) {
                    r.fail(path + ".max[" + std::to_string(a) + "]",
                           "must be greater than min (zero-size or inverted bounds)");
                }
            }
        }
    } else if (mode == "auto-world") {
        b.mode = BoundsMode::AutoWorld;
        if (j.contains("nodes")) {
            if (!j["nodes"].is_array()) {
                r.fail(path + ".nodes", "must be an array of node names or indices");
            }
            for (size_t i = 0; i < j["nodes"].size(); ++i) {
                const Json& n = j["nodes"][i];
                b.nodes.push_back(n.is_number_unsigned() || n.is_number_integer()
                                      ? std::to_string(r.unsignedInt(n, path, 0, 1u << 30))
                                      : r.string(n, path + ".nodes[" + std::to_string(i) + "]"));
            }
        }
    } else {
        b.mode = BoundsMode::AutoLocal;
        if (!j.contains("node")) {
            r.fail(path + ".node", "missing (auto-local bounds follow one node)");
        }
        const Json& n = j["node"];
        b.node = n.is_number() ? std::to_string(r.unsignedInt(n, path + ".node", 0, 1u << 30))
                               : r.string(n, path + ".node");
    }
    return b;
}

VolumeConfig parseVolume(const Reader& r, const Json& j, const std::string& path) {
    r.checkKeys(j, path,
                {"name", "bounds", "resolution", "density", "max_resolution", "position", "format",
                 "sh_order", "blend_priority", "fade_distance", "layout", "levels",
                 "refine_error"});
    VolumeConfig v;
    if (j.contains("name")) {
        v.name = r.string(j["name"], path + ".name");
    }
    if (j.contains("bounds")) {
        v.bounds = parseBounds(r, j["bounds"], path + ".bounds");
    }
    if (j.contains("resolution")) {
        const Json& res = j["resolution"];
        if (res.is_string()) {
            r.choice(res, path + ".resolution", {"auto"});
        } else {
            if (!res.is_array() || res.size() != 3) {
                r.fail(path + ".resolution", "must be \"auto\" or an array of 3 powers of two");
            }
            glm::uvec3 value;
            for (int a = 0; a < 3; ++a) {
                const std::string p = path + ".resolution[" + std::to_string(a) + "]";
                value[a] = uint32_t(r.unsignedInt(res[a], p, 1, grid::kMaxResolution));
                if (!grid::isPowerOfTwo(value[a])) {
                    r.fail(p, std::to_string(value[a]) + " is not a power of two (1, 2, 4 .. 256)");
                }
            }
            v.resolution = value;
        }
    }
    if (j.contains("density")) {
        v.density = float(r.positive(j["density"], path + ".density"));
    }
    if (j.contains("max_resolution")) {
        v.maxResolution = uint32_t(
            r.unsignedInt(j["max_resolution"], path + ".max_resolution", 1, grid::kMaxResolution));
        if (!grid::isPowerOfTwo(v.maxResolution)) {
            r.fail(path + ".max_resolution", "must be a power of two");
        }
    }
    if (j.contains("position")) {
        v.position = r.choice(j["position"], path + ".position", {"center", "corner"}) == "corner"
                         ? grid::PositionMode::Corner
                         : grid::PositionMode::Center;
    }
    if (j.contains("format")) {
        v.storage = r.choice(j["format"], path + ".format", {"float", "half"}) == "float"
                        ? Storage::Float32
                        : Storage::Float16;
    }
    if (j.contains("sh_order")) {
        v.shOrder = r.unsignedInt(j["sh_order"], path + ".sh_order", 1, 2) == 1 ? sh::Order::L1
                                                                                : sh::Order::L2;
    }
    if (j.contains("blend_priority")) {
        const Json& p = j["blend_priority"];
        if (!p.is_number_integer()) {
            r.fail(path + ".blend_priority", "must be a whole number");
        }
        v.blendPriority = p.get<int32_t>();
    }
    if (j.contains("fade_distance")) {
        v.fadeDistance = float(r.number(j["fade_distance"], path + ".fade_distance"));
        if (v.fadeDistance < 0.0f) {
            r.fail(path + ".fade_distance", "must be >= 0");
        }
    }
    if (j.contains("layout")) {
        v.layout = r.choice(j["layout"], path + ".layout", {"dense", "bricked"}) == "bricked"
                       ? VolumeLayout::Bricked
                       : VolumeLayout::Dense;
    }
    if (j.contains("levels")) {
        v.maxLevel = uint32_t(r.unsignedInt(j["levels"], path + ".levels", 0, brick::kMaxLevel));
    }
    if (j.contains("refine_error")) {
        v.refineError = float(r.positive(j["refine_error"], path + ".refine_error"));
    }
    if (v.layout == VolumeLayout::Bricked && v.position == grid::PositionMode::Corner) {
        r.fail(path + ".position",
               "bricked volumes place probes on brick corners themselves; omit \"position\"");
    }
    return v;
}

EnvironmentConfig parseEnvironment(const Reader& r, const Json& j, const std::string& path,
                                   const std::filesystem::path& base_dir) {
    r.checkKeys(j, path, {"type", "radiance", "file", "intensity", "rotation_deg"});
    EnvironmentConfig e;
    if (!j.contains("type")) {
        r.fail(path + ".type", "missing (black, constant or latlong)");
    }
    const std::string type = r.choice(j["type"], path + ".type", {"black", "constant", "latlong"});
    if (j.contains("intensity")) {
        e.intensity = float(r.number(j["intensity"], path + ".intensity"));
        if (e.intensity < 0.0f) {
            r.fail(path + ".intensity", "must be >= 0");
        }
    }
    if (j.contains("rotation_deg")) {
        e.rotationDeg = float(r.number(j["rotation_deg"], path + ".rotation_deg"));
    }
    if (type == "constant") {
        e.type = EnvironmentConfig::Type::Constant;
        if (!j.contains("radiance")) {
            r.fail(path + ".radiance", "missing for a constant environment");
        }
        e.radiance = r.vec3(j["radiance"], path + ".radiance");
        for (int c = 0; c < 3; ++c) {
            if (e.radiance[c] < 0.0f) {
                r.fail(path + ".radiance[" + std::to_string(c) + "]", "must be >= 0");
            }
        }
    } else if (type == "latlong") {
        e.type = EnvironmentConfig::Type::LatLong;
        if (!j.contains("file")) {
            r.fail(path + ".file", "missing for a latlong environment");
        }
        e.file = r.string(j["file"], path + ".file");
        if (e.file.is_relative() && !base_dir.empty()) {
            e.file = base_dir / e.file;
        }
    }
    return e;
}

VplConfig parseVpl(const Reader& r, const Json& j, const std::string& path) {
    r.checkKeys(j, path,
                {"count", "bounces", "direct_samples", "sampling", "clamp", "clamp_distance",
                 "near_field", "shadows", "cut_error"});
    VplConfig v;
    if (j.contains("count")) {
        const Json& n = j["count"];
        if (n.is_string()) {
            r.choice(n, path + ".count", {"auto"});
        } else {
            v.count = uint32_t(r.unsignedInt(n, path + ".count", 1, 1u << 24));
        }
    }
    if (j.contains("bounces")) {
        v.bounces = uint32_t(r.unsignedInt(j["bounces"], path + ".bounces", 1, 1024));
    }
    if (j.contains("direct_samples")) {
        v.directSamples =
            uint32_t(r.unsignedInt(j["direct_samples"], path + ".direct_samples", 1, 1u << 24));
    }
    if (j.contains("sampling")) {
        const std::string s =
            r.choice(j["sampling"], path + ".sampling", {"random", "stratified", "jittered"});
        v.sampling = s == "random"     ? VplSampling::Random
                     : s == "jittered" ? VplSampling::Jittered
                                       : VplSampling::Stratified;
    }
    if (j.contains("clamp")) {
        const std::string s =
            r.choice(j["clamp"], path + ".clamp", {"none", "distance", "spherical"});
        v.clamp = s == "none"       ? VplClamp::None
                  : s == "distance" ? VplClamp::Distance
                                    : VplClamp::Spherical;
    }
    if (j.contains("clamp_distance")) {
        const Json& d = j["clamp_distance"];
        if (d.is_string()) {
            r.choice(d, path + ".clamp_distance", {"auto"});
        } else {
            v.clampDistance = float(r.positive(d, path + ".clamp_distance"));
        }
    }
    if (j.contains("near_field")) {
        const Json& d = j["near_field"];
        if (d.is_string()) {
            r.choice(d, path + ".near_field", {"auto"});
        } else {
            v.nearField = float(r.number(d, path + ".near_field"));
            if (*v.nearField < 0.0f) {
                r.fail(path + ".near_field", "must be >= 0 (0 turns it off)");
            }
        }
    }
    if (j.contains("shadows")) {
        v.shadows = r.choice(j["shadows"], path + ".shadows", {"on", "off"}) == "on";
    }
    if (j.contains("cut_error")) {
        const double e = r.number(j["cut_error"], path + ".cut_error");
        if (e < 0.0 || e >= 1.0) {
            r.fail(path + ".cut_error", "must be in [0, 1) (0 gathers every VPL)");
        }
        v.cutError = float(e);
    }
    return v;
}

LpvConfig parseLpv(const Reader& r, const Json& j, const std::string& path) {
    r.checkKeys(j, path,
                {"grid", "cascades", "cascade_ratio", "iterations", "propagation_weight",
                 "fade_cells", "occlusion", "direct", "direct_samples", "vpl_count", "intensity"});
    LpvConfig l;
    if (j.contains("grid")) {
        l.grid = uint32_t(r.unsignedInt(j["grid"], path + ".grid", 4, 256));
    }
    if (j.contains("cascades")) {
        l.cascades = uint32_t(r.unsignedInt(j["cascades"], path + ".cascades", 1, 4));
    }
    if (j.contains("cascade_ratio")) {
        const double ratio = r.number(j["cascade_ratio"], path + ".cascade_ratio");
        if (ratio < 1.25 || ratio > 4.0) {
            r.fail(path + ".cascade_ratio",
                   "must be in [1.25, 4] (got " + j["cascade_ratio"].dump() + ")");
        }
        l.cascadeRatio = float(ratio);
    }
    if (j.contains("iterations")) {
        const Json& n = j["iterations"];
        if (n.is_string()) {
            r.choice(n, path + ".iterations", {"auto"});
        } else {
            l.iterations = uint32_t(r.unsignedInt(n, path + ".iterations", 1, 4096));
        }
    }
    if (j.contains("propagation_weight")) {
        const double w = r.positive(j["propagation_weight"], path + ".propagation_weight");
        if (w > 1.0) {
            r.fail(path + ".propagation_weight", "must be in (0, 1] (1 passes all light on)");
        }
        l.propagationWeight = float(w);
    }
    if (j.contains("fade_cells")) {
        const double f = r.number(j["fade_cells"], path + ".fade_cells");
        if (f < 0.0 || f > 64.0) {
            r.fail(path + ".fade_cells", "must be in [0, 64]");
        }
        l.fadeCells = float(f);
    }
    if (j.contains("occlusion")) {
        l.occlusion = r.choice(j["occlusion"], path + ".occlusion", {"on", "off"}) == "on";
    }
    if (j.contains("direct")) {
        l.direct = r.choice(j["direct"], path + ".direct", {"traced", "propagated"}) == "traced"
                       ? LpvDirect::Traced
                       : LpvDirect::Propagated;
    }
    if (j.contains("direct_samples")) {
        l.directSamples =
            uint32_t(r.unsignedInt(j["direct_samples"], path + ".direct_samples", 1, 1u << 24));
    }
    if (j.contains("vpl_count")) {
        l.vplCount = uint32_t(r.unsignedInt(j["vpl_count"], path + ".vpl_count", 1, 1u << 24));
    }
    if (j.contains("intensity")) {
        l.intensity = float(r.number(j["intensity"], path + ".intensity"));
        if (l.intensity < 0.0f) {
            r.fail(path + ".intensity", "must be >= 0");
        }
    }
    return l;
}

BakeConfig parseTop(const Reader& r, const Json& j, const std::filesystem::path& base_dir) {
    r.checkKeys(j, "",
                {"method", "seed", "path", "vpl", "lpv", "environment", "volumes", "validity",
                 "max_memory_mb", "target_error"});
    BakeConfig c;
    if (j.contains("method")) {
        c.method = r.choice(j["method"], "method", {"path", "vpl", "lpv"});
    }
    if (j.contains("seed")) {
        c.seed = r.unsignedInt(j["seed"], "seed", 0, UINT64_MAX);
    }
    if (j.contains("path")) {
        const Json& p = j["path"];
        r.checkKeys(p, "path", {"samples", "max_bounces"});
        if (p.contains("samples")) {
            c.path.samples = uint32_t(r.unsignedInt(p["samples"], "path.samples", 1, 1u << 24));
        }
        if (p.contains("max_bounces")) {
            c.path.maxBounces =
                uint32_t(r.unsignedInt(p["max_bounces"], "path.max_bounces", 0, 1024));
        }
    }
    if (j.contains("vpl")) {
        c.vpl = parseVpl(r, j["vpl"], "vpl");
    }
    if (j.contains("lpv")) {
        c.lpv = parseLpv(r, j["lpv"], "lpv");
    }
    if (j.contains("environment")) {
        c.environment = parseEnvironment(r, j["environment"], "environment", base_dir);
    }
    if (j.contains("validity")) {
        const Json& v = j["validity"];
        r.checkKeys(v, "validity", {"backface_threshold", "dilate", "nudge", "visibility"});
        if (v.contains("backface_threshold")) {
            const double t = r.number(v["backface_threshold"], "validity.backface_threshold");
            if (t < 0.0 || t > 1.0) {
                r.fail("validity.backface_threshold", "must be in [0, 1]");
            }
            c.backfaceThreshold = float(t);
        }
        if (v.contains("dilate")) {
            if (!v["dilate"].is_boolean()) {
                r.fail("validity.dilate", "must be true or false");
            }
            c.dilate = v["dilate"].get<bool>();
        }
        if (v.contains("nudge")) {
            if (!v["nudge"].is_boolean()) {
                r.fail("validity.nudge", "must be true or false");
            }
            c.nudge = v["nudge"].get<bool>();
        }
        if (v.contains("visibility")) {
            if (!v["visibility"].is_boolean()) {
                r.fail("validity.visibility", "must be true or false");
            }
            c.visibility = v["visibility"].get<bool>();
        }
    }
    if (j.contains("target_error")) {
        const double t = r.number(j["target_error"], "target_error");
        if (!(t > 0.0 && t < 1.0)) {
            r.fail("target_error", "must be in (0, 1) (a relative RMS error, e.g. 0.05)");
        }
        c.targetError = t;
    }
    if (j.contains("max_memory_mb")) {
        c.maxMemoryBytes = r.unsignedInt(j["max_memory_mb"], "max_memory_mb", 1, 1u << 30) << 20;
    }
    if (j.contains("volumes")) {
        const Json& vols = j["volumes"];
        if (!vols.is_array()) {
            r.fail("volumes", "must be an array of volume objects");
        }
        std::set<std::string> names;
        for (size_t i = 0; i < vols.size(); ++i) {
            const std::string path = "volumes[" + std::to_string(i) + "]";
            VolumeConfig v = parseVolume(r, vols[i], path);
            if (!vols[i].contains("name")) {
                v.name = "volume" + std::to_string(i);
            }
            if (!names.insert(v.name).second) {
                r.fail(path + ".name", "\"" + v.name + "\" is used by an earlier volume");
            }
            c.volumes.push_back(std::move(v));
        }
    }
    return c;
}

const char* boundsModeName(BoundsMode m) {
    switch (m) {
    case BoundsMode::Custom:
        return "custom";
    case BoundsMode::AutoWorld:
        return "auto-world";
    case BoundsMode::AutoLocal:
        return "auto-local";
    }
    return "unknown";
}

} // namespace

std::string_view toString(VplClamp clamp) {
    switch (clamp) {
    case VplClamp::None:
        return "none";
    case VplClamp::Distance:
        return "distance";
    case VplClamp::Spherical:
        return "spherical";
    }
    return "unknown";
}

std::string_view toString(VplSampling sampling) {
    switch (sampling) {
    case VplSampling::Random:
        return "random";
    case VplSampling::Stratified:
        return "stratified";
    case VplSampling::Jittered:
        return "jittered";
    }
    return "unknown";
}

std::string_view toString(LpvDirect direct) {
    return direct == LpvDirect::Traced ? "traced" : "propagated";
}

Result<BakeConfig> parseBakeConfig(std::string_view json_text, std::string_view source,
                                   const std::filesystem::path& base_dir) {
    Json j;
    try {
        j = Json::parse(json_text);
    } catch (const Json::parse_error& e) {
        return makeError(ErrorCode::InvalidArgument,
                         std::string(source) + ": not valid JSON: " + e.what());
    }
    try {
        return parseTop(Reader(source), j, base_dir);
    } catch (const ConfigError& e) {
        return makeError(ErrorCode::InvalidArgument, e.message);
    } catch (const Json::exception& e) {
        return makeError(ErrorCode::InvalidArgument, std::string(source) + ": " + e.what());
    }
}

Result<BakeConfig> loadBakeConfig(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        return makeError(ErrorCode::Io, path.string() + ": cannot open config file");
    }
    std::stringstream text;
    text << in.rdbuf();
    return parseBakeConfig(text.str(), path.string(), path.parent_path());
}

std::string describeConfig(const BakeConfig& c) {
    Json j;
    j["method"] = c.method;
    j["seed"] = c.seed;
    j["path"] = {{"samples", c.path.samples}, {"max_bounces", c.path.maxBounces}};
    if (c.method == "vpl") {
        const VplConfig& v = c.vpl;
        j["vpl"] = {{"bounces", v.bounces},
                    {"direct_samples", v.directSamples},
                    {"sampling", std::string(toString(v.sampling))},
                    {"clamp", std::string(toString(v.clamp))},
                    {"shadows", v.shadows ? "on" : "off"},
                    {"cut_error", v.cutError}};
        j["vpl"]["count"] = v.count ? Json(*v.count) : Json("auto");
        j["vpl"]["clamp_distance"] = v.clampDistance ? Json(*v.clampDistance) : Json("auto");
        j["vpl"]["near_field"] = v.nearField ? Json(*v.nearField) : Json("auto");
    }
    if (c.method == "lpv") {
        const LpvConfig& l = c.lpv;
        j["lpv"] = {{"grid", l.grid},
                    {"cascades", l.cascades},
                    {"cascade_ratio", l.cascadeRatio},
                    {"propagation_weight", l.propagationWeight},
                    {"fade_cells", l.fadeCells},
                    {"occlusion", l.occlusion ? "on" : "off"},
                    {"direct", std::string(toString(l.direct))},
                    {"direct_samples", l.directSamples},
                    {"vpl_count", l.vplCount},
                    {"intensity", l.intensity}};
        j["lpv"]["iterations"] = l.iterations ? Json(*l.iterations) : Json("auto");
    }
    switch (c.environment.type) {
    case EnvironmentConfig::Type::Black:
        j["environment"] = {{"type", "black"}};
        break;
    case EnvironmentConfig::Type::Constant:
        j["environment"] = {
            {"type", "constant"},
            {"radiance",
             {c.environment.radiance.x, c.environment.radiance.y, c.environment.radiance.z}},
            {"intensity", c.environment.intensity}};
        break;
    case EnvironmentConfig::Type::LatLong:
        j["environment"] = {{"type", "latlong"},
                            {"file", c.environment.file.string()},
                            {"intensity", c.environment.intensity},
                            {"rotation_deg", c.environment.rotationDeg}};
        break;
    }
    j["validity"] = {{"backface_threshold", c.backfaceThreshold},
                     {"dilate", c.dilate},
                     {"nudge", c.nudge},
                     {"visibility", c.visibility}};
    j["max_memory_mb"] = c.maxMemoryBytes >> 20;
    if (c.targetError) {
        j["target_error"] = *c.targetError;
    }
    j["volumes"] = Json::array();
    for (const VolumeConfig& v : c.volumes) {
        Json jv = {
            {"name", v.name},
            {"bounds", {{"mode", boundsModeName(v.bounds.mode)}, {"padding", v.bounds.padding}}},
            {"position", std::string(grid::toString(v.position))},
            {"format", std::string(toString(v.storage))},
            {"sh_order", int(v.shOrder)},
            {"blend_priority", v.blendPriority},
            {"fade_distance", v.fadeDistance},
            {"layout", std::string(toString(v.layout))}};
        if (v.layout == VolumeLayout::Bricked) {
            jv["levels"] = v.maxLevel;
            jv["refine_error"] = v.refineError;
        }
        if (v.bounds.mode == BoundsMode::Custom) {
            jv["bounds"]["min"] = {v.bounds.min.x, v.bounds.min.y, v.bounds.min.z};
            jv["bounds"]["max"] = {v.bounds.max.x, v.bounds.max.y, v.bounds.max.z};
        } else if (v.bounds.mode == BoundsMode::AutoWorld && !v.bounds.nodes.empty()) {
            jv["bounds"]["nodes"] = v.bounds.nodes;
        } else if (v.bounds.mode == BoundsMode::AutoLocal) {
            jv["bounds"]["node"] = v.bounds.node;
        }
        if (v.resolution) {
            jv["resolution"] = {v.resolution->x, v.resolution->y, v.resolution->z};
        } else {
            jv["resolution"] = "auto";
            if (v.density) {
                jv["density"] = *v.density;
            }
            jv["max_resolution"] = v.maxResolution;
        }
        j["volumes"].push_back(jv);
    }
    return j.dump();
}

Result<Environment> makeEnvironment(const EnvironmentConfig& config) {
    Environment env;
    switch (config.type) {
    case EnvironmentConfig::Type::Black:
        env.constant = glm::vec3(0.0f);
        return env;
    case EnvironmentConfig::Type::Constant:
        env.constant = config.radiance;
        env.intensity = config.intensity;
        env.rotationDeg = config.rotationDeg;
        return env;
    case EnvironmentConfig::Type::LatLong:
        return loadLatLongEnvironment(config.file, config.intensity, config.rotationDeg);
    }
    return env;
}

} // namespace probekit::baker
