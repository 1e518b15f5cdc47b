// Bake configuration: one table per config struct (key, member, admitted values, unit, help,
// flag) that parses JSON into BakeConfig with errors naming the file and the field, describes a
// BakeConfig as JSON, validates a BakeConfig built in code and lists the settings for the
// command line (settings.hpp).
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <span>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "probekit/baker/bake.hpp"
#include "probekit/baker/config.hpp"
#include "probekit/baker/settings.hpp"
#include "probekit/formats/file_io.hpp"
#include "probekit/formats/json_nesting.hpp"

namespace probekit::baker {

std::string_view toString(Method method) {
    switch (method) {
    case Method::Path:
        return "path";
    case Method::Vpl:
        return "vpl";
    case Method::Lpv:
        return "lpv";
    }
    return "unknown";
}

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

std::string_view toString(LightMode mode) {
    switch (mode) {
    case LightMode::Baked:
        return "baked";
    case LightMode::Indirect:
        return "indirect";
    case LightMode::None:
        return "none";
    }
    return "unknown";
}

std::string_view toString(LpvDirect direct) {
    return direct == LpvDirect::Traced ? "traced" : "propagated";
}

namespace {

using Json = nlohmann::json;

// Every value of each enum a setting chooses, in the order error messages list them; the names
// are the toString functions'.
constexpr std::array<Method, 3> enumValues(Method) {
    return {Method::Path, Method::Vpl, Method::Lpv};
}
constexpr std::array<VplClamp, 3> enumValues(VplClamp) {
    return {VplClamp::None, VplClamp::Distance, VplClamp::Spherical};
}
constexpr std::array<VplSampling, 3> enumValues(VplSampling) {
    return {VplSampling::Random, VplSampling::Stratified, VplSampling::Jittered};
}
constexpr std::array<LightMode, 3> enumValues(LightMode) {
    return {LightMode::Baked, LightMode::Indirect, LightMode::None};
}
constexpr std::array<LpvDirect, 2> enumValues(LpvDirect) {
    return {LpvDirect::Traced, LpvDirect::Propagated};
}
constexpr std::array<grid::PositionMode, 2> enumValues(grid::PositionMode) {
    return {grid::PositionMode::Center, grid::PositionMode::Corner};
}
constexpr std::array<Storage, 2> enumValues(Storage) {
    return {Storage::Float32, Storage::Float16};
}
constexpr std::array<VolumeLayout, 2> enumValues(VolumeLayout) {
    return {VolumeLayout::Dense, VolumeLayout::Bricked};
}
std::string_view toString(BoundsMode mode) {
    switch (mode) {
    case BoundsMode::Custom:
        return "custom";
    case BoundsMode::AutoWorld:
        return "auto-world";
    case BoundsMode::AutoLocal:
        return "auto-local";
    }
    return "unknown";
}
constexpr std::array<BoundsMode, 3> enumValues(BoundsMode) {
    return {BoundsMode::Custom, BoundsMode::AutoWorld, BoundsMode::AutoLocal};
}
std::string_view toString(EnvironmentConfig::Type type) {
    switch (type) {
    case EnvironmentConfig::Type::Black:
        return "black";
    case EnvironmentConfig::Type::Constant:
        return "constant";
    case EnvironmentConfig::Type::LatLong:
        return "latlong";
    }
    return "unknown";
}
constexpr std::array<EnvironmentConfig::Type, 3> enumValues(EnvironmentConfig::Type) {
    return {EnvironmentConfig::Type::Black, EnvironmentConfig::Type::Constant,
            EnvironmentConfig::Type::LatLong};
}

template <class E>
std::vector<std::string> enumNames() {
    std::vector<std::string> names;
    for (E e : enumValues(E{})) {
        names.emplace_back(toString(e));
    }
    return names;
}

std::string joinList(const std::vector<std::string>& items, const char* separator = ", ") {
    std::string out;
    for (const std::string& i : items) {
        out += (out.empty() ? "" : separator) + i;
    }
    return out;
}

std::string numberText(double d) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%g", d);
    return buffer;
}

// ---- What values a setting admits ----

enum class Kind : uint8_t {
    Whole,  // a JSON integer within [wholeLo, wholeHi]
    Number, // a finite JSON number within lo..hi (ends open or closed)
    Flag,   // true or false
    Choice, // one of `names`
};

struct Admits {
    Kind kind = Kind::Number;
    int64_t wholeLo = 0;
    uint64_t wholeHi = std::numeric_limits<uint64_t>::max();
    double lo = -std::numeric_limits<double>::infinity();
    double hi = std::numeric_limits<double>::infinity();
    bool loOpen = false;
    bool hiOpen = false;
    bool powerOfTwo = false;
    bool autoValue = false; // the string "auto" leaves an optional setting unset (automatic)
    std::vector<std::string> names;
    std::string note; // why the range is what it is, said with a range error

    Admits orAuto() && {
        autoValue = true;
        return std::move(*this);
    }
    Admits because(std::string why) && {
        note = std::move(why);
        return std::move(*this);
    }
    Admits powersOfTwo() && {
        powerOfTwo = true;
        return std::move(*this);
    }

    std::string rangeText() const {
        if (kind == Kind::Whole) {
            return std::to_string(wholeLo) + ".." + std::to_string(wholeHi);
        }
        if (hi == std::numeric_limits<double>::infinity()) {
            return (loOpen ? "> " : ">= ") + numberText(lo);
        }
        return std::string("in ") + (loOpen ? "(" : "[") + numberText(lo) + ", " + numberText(hi) +
               (hiOpen ? ")" : "]");
    }

    const char* typeName() const {
        switch (kind) {
        case Kind::Whole:
            return "INT";
        case Kind::Number:
            return "NUMBER";
        case Kind::Flag:
            return "BOOL";
        case Kind::Choice:
            return "NAME";
        }
        return "VALUE";
    }

    // For --help and bakeSettings().
    std::string text() const {
        std::string t;
        switch (kind) {
        case Kind::Whole:
            t = rangeText() + (powerOfTwo ? ", a power of two" : "");
            break;
        case Kind::Number:
            t = rangeText();
            if (t.rfind("in ", 0) == 0) {
                t = t.substr(3);
            }
            break;
        case Kind::Flag:
            t = "true or false";
            break;
        case Kind::Choice:
            return joinList(choiceNames());
        }
        return autoValue ? "auto or " + t : t;
    }

    // A choice's names, "auto" first when admitted.
    std::vector<std::string> choiceNames() const {
        std::vector<std::string> all;
        if (autoValue) {
            all.emplace_back("auto");
        }
        all.insert(all.end(), names.begin(), names.end());
        return all;
    }
};

Admits whole(int64_t lo, uint64_t hi) {
    Admits a;
    a.kind = Kind::Whole;
    a.wholeLo = lo;
    a.wholeHi = hi;
    return a;
}
Admits number(double lo, double hi, bool lo_open = false, bool hi_open = false) {
    Admits a;
    a.kind = Kind::Number;
    a.lo = lo;
    a.hi = hi;
    a.loOpen = lo_open;
    a.hiOpen = hi_open;
    return a;
}
Admits anyNumber() {
    return number(-std::numeric_limits<double>::infinity(), INFINITY);
}
Admits positive() {
    return number(0.0, INFINITY, true);
}
Admits nonNegative() {
    return number(0.0, INFINITY);
}
// Radiance and its scales: kMaxEmission (scene.hpp) at most, far above any real light (the
// sun's disc is about 2e7 W/(sr m^2)), so that the bake's float sums stay finite.
Admits emission() {
    return number(0.0, kMaxEmission);
}
Admits flag() {
    Admits a;
    a.kind = Kind::Flag;
    return a;
}
Admits choice(std::vector<std::string> names) {
    Admits a;
    a.kind = Kind::Choice;
    a.names = std::move(names);
    return a;
}
template <class E>
Admits choiceOf() {
    return choice(enumNames<E>());
}
Admits onOff() {
    return choice({"on", "off"});
}

// ---- Checking values against what they admit ----

// Thrown inside this file only, turned into a Result at each public function's boundary.
struct ConfigError {
    std::string message;
};

class Reader {
public:
    explicit Reader(std::string_view source) : m_source(source) {}

    [[noreturn]] void fail(const std::string& path, const std::string& what) const {
        throw ConfigError{(m_source.empty() ? "" : m_source + ": ") + path + ": " + what};
    }

    void checkKeys(const Json& object, const std::string& path,
                   const std::vector<std::string>& allowed) const {
        if (!object.is_object()) {
            fail(path.empty() ? "(top level)" : path, "must be a JSON object");
        }
        const std::set<std::string> known(allowed.begin(), allowed.end());
        for (const auto& [key, value] : object.items()) {
            if (!known.count(key)) {
                fail(join(path, key), "unknown field (known: " + joinList(allowed) + ")");
            }
        }
    }

    // `v` checked against `a`: the value to store (a number, bool or string), or null for
    // "auto" when `a` admits it.
    Json check(const Admits& a, const Json& v, const std::string& path) const {
        // "auto" when admitted; any other string is a choice's name or an error.
        if (a.autoValue && v.is_string() && (a.kind != Kind::Choice || v == "auto")) {
            if (v.get<std::string>() != "auto") {
                fail(path, "\"" + v.get<std::string>() + "\" is not one of auto");
            }
            return nullptr;
        }
        switch (a.kind) {
        case Kind::Whole:
            return checkWhole(a, v, path);
        case Kind::Number:
            return checkNumber(a, v, path);
        case Kind::Flag:
            if (!v.is_boolean()) {
                fail(path, "must be true or false");
            }
            return v;
        case Kind::Choice:
            return checkChoice(a.choiceNames(), v, path);
        }
        return v;
    }

    double number(const Json& v, const std::string& path) const {
        return checkNumber(anyNumber(), v, path).get<double>();
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

    std::string checkChoice(const std::vector<std::string>& names, const Json& v,
                            const std::string& path) const {
        const std::string s = string(v, path);
        for (const std::string& n : names) {
            if (s == n) {
                return s;
            }
        }
        fail(path, "\"" + s + "\" is not one of " + joinList(names));
    }

    static std::string join(const std::string& path, std::string_view key) {
        return path.empty() ? std::string(key) : path + "." + std::string(key);
    }

private:
    Json checkWhole(const Admits& a, const Json& v, const std::string& path) const {
        if (!v.is_number_integer()) {
            fail(path, "must be a whole number");
        }
        if (!v.is_number_unsigned()) { // negative
            const int64_t s = v.get<int64_t>();
            if (s < a.wholeLo) {
                fail(path, (a.wholeLo >= 0 ? "must be >= " + std::to_string(a.wholeLo)
                                           : "must be in " + a.rangeText()) +
                               " (got " + v.dump() + ")");
            }
            return v;
        }
        const uint64_t u = v.get<uint64_t>();
        if ((a.wholeLo > 0 && u < uint64_t(a.wholeLo)) || u > a.wholeHi) {
            fail(path, "must be in " + a.rangeText() + " (got " + v.dump() + ")");
        }
        if (a.powerOfTwo && (u & (u - 1)) != 0) {
            fail(path, "must be a power of two");
        }
        return v;
    }

    Json checkNumber(const Admits& a, const Json& v, const std::string& path) const {
        if (!v.is_number()) {
            fail(path, "must be a number");
        }
        const double d = v.get<double>();
        if (!std::isfinite(d)) {
            fail(path, "must be finite");
        }
        // Number settings are stored in floats (target_error, a double, lies in (0, 1)).
        if (std::fabs(d) > double(std::numeric_limits<float>::max())) {
            fail(path, "must be finite as a 32-bit float, |x| <= 3.4e38 (got " + v.dump() + ")");
        }
        // The range holds for the value as stored: 0.9999999999999999 is below 1 as a double
        // but rounds to 1 as a float, and 1e-50 rounds to 0.
        const double stored = double(float(d));
        const auto inRange = [&a](double x) {
            return (a.loOpen ? x > a.lo : x >= a.lo) && (a.hiOpen ? x < a.hi : x <= a.hi);
        };
        if (!inRange(d) || !inRange(stored)) {
            const std::string rounded =
                inRange(d) ? ", which is " + numberText(stored) + " as a 32-bit float" : "";
            fail(path, "must be " + a.rangeText() + " (got " + v.dump() + rounded +
                           (a.note.empty() ? "" : "; " + a.note) + ")");
        }
        return d;
    }

    std::string m_source;
};

// ---- One table per config struct ----

// A JSON value to and from a member of each type a setting can have.
template <class M>
Json toJson(const M& m) {
    if constexpr (std::is_enum_v<M>) {
        return std::string(toString(m));
    } else {
        return m;
    }
}
template <class M>
Json toJson(const std::optional<M>& m) {
    return m ? toJson(*m) : Json(nullptr);
}
template <class M>
void fromJson(const Json& j, M& m) {
    if constexpr (std::is_enum_v<M>) {
        for (M e : enumValues(M{})) {
            if (toString(e) == j.get<std::string>()) {
                m = e;
            }
        }
    } else {
        m = j.get<M>();
    }
}
template <class M>
void fromJson(const Json& j, std::optional<M>& m) {
    if (j.is_null()) {
        m.reset();
    } else {
        fromJson(j, m.emplace());
    }
}

template <class T>
struct Field {
    std::string_view key;
    Admits admits;
    std::string_view unit;
    std::string_view help;
    std::string_view flag;                    // `probekit bake` flag, or empty
    std::function<Json(const T&)> get;        // null: an optional setting left unset
    std::function<void(T&, const Json&)> set; // from a checked value (null: unset)
    std::function<bool(const T&)> shown = {}; // describeConfig writes it only when this holds
};

template <class T, class M>
Field<T> field(std::string_view key, M T::*member, Admits admits, std::string_view unit,
               std::string_view help, std::string_view flag = {}) {
    return Field<T>{key,
                    std::move(admits),
                    unit,
                    help,
                    flag,
                    [member](const T& t) { return toJson(t.*member); },
                    [member](T& t, const Json& j) { fromJson(j, t.*member); }};
}

// "on"/"off" for a bool member.
template <class T>
Field<T> onOffField(std::string_view key, bool T::*member, std::string_view help,
                    std::string_view flag = {}) {
    return Field<T>{key,
                    onOff(),
                    "",
                    help,
                    flag,
                    [member](const T& t) { return Json(t.*member ? "on" : "off"); },
                    [member](T& t, const Json& j) { t.*member = j.get<std::string>() == "on"; }};
}

template <class T>
Field<T> shownWhen(Field<T> f, std::function<bool(const T&)> when) {
    f.shown = std::move(when);
    return f;
}

const std::vector<Field<BakeConfig>>& topFields() {
    static const std::vector<Field<BakeConfig>> fields = {
        field("method", &BakeConfig::method, choiceOf<Method>(), "",
              "lighting method: path-traced reference, instant radiosity or light propagation "
              "volumes",
              "--method"),
        field("seed", &BakeConfig::seed, whole(0, UINT64_MAX), "", "random seed", "--seed"),
        field("scale", &BakeConfig::scale, positive(), "m/unit",
              "metres per scene unit (0.01: the file is in centimetres, 0.0254: inches, 0.001: "
              "millimetres)",
              "--scale"),
        {"max_memory_mb", whole(1, 1u << 30), "MiB",
         "dense volumes: the bake's working memory; bricked: their GPU bytes", "--max-memory",
         [](const BakeConfig& c) { return Json(c.maxMemoryBytes >> 20); },
         [](BakeConfig& c, const Json& j) { c.maxMemoryBytes = j.get<uint64_t>() << 20; }},
        field("target_error", &BakeConfig::targetError,
              number(0.0, 1.0, true, true).because("a relative RMS error, e.g. 0.05"), "",
              "choose density, refinement, SH order and samples for this relative RMS "
              "irradiance error",
              "--target-error"),
        field("dering", &BakeConfig::dering, flag(), "",
              "window each stored probe's SH so its irradiance is >= 0 for every normal",
              "--dering"),
    };
    return fields;
}

const std::vector<Field<PathConfig>>& pathFields() {
    static const std::vector<Field<PathConfig>> fields = {
        field("samples", &PathConfig::samples, whole(1, 1u << 24), "",
              "path: directions per probe"),
        field("max_bounces", &PathConfig::maxBounces, whole(0, 1024), "", "path: maximum bounces",
              "--bounces"),
        field("noise_target", &PathConfig::noiseTarget,
              number(0.0, 1.0, false, true).because("0 turns adaptive sampling off"), "",
              "adaptive sampling: trace each probe until its estimated relative noise is at most "
              "this (the samples setting becomes the minimum; every method)",
              "--noise-target"),
        field("max_samples", &PathConfig::maxSamples, whole(1, 1u << 24), "",
              "adaptive sampling: most directions per probe", "--max-samples"),
        field("noise_floor", &PathConfig::noiseFloor, nonNegative(), "W/m^2",
              "adaptive sampling: a probe darker than this (RMS irradiance over the axis normals) "
              "has its noise measured against it (--target-error sets it)"),
        field("shadow_rays", &PathConfig::shadowRays, whole(0, 1u << 16), "",
              "expected shadow rays to punctual lights per path vertex (0: one to every light)",
              "--shadow-rays"),
        field("roulette_weight", &PathConfig::rouletteWeight,
              number(0.0, 1.0, true, false).because("a window of 0 never ends a path"), "",
              "Russian roulette: a path below this throughput survives with probability "
              "throughput / this"),
    };
    return fields;
}

const std::vector<Field<VplConfig>>& vplFields() {
    static const std::vector<Field<VplConfig>> fields = {
        field("count", &VplConfig::count, whole(1, 1u << 24).orAuto(), "",
              "vpl: VPLs to place (auto: from the scene's area and the probe spacing)",
              "--vpl-count"),
        field("bounces", &VplConfig::bounces, whole(1, 1024), "", "vpl: reflections per light path",
              "--vpl-bounces"),
        field("direct_samples", &VplConfig::directSamples, whole(1, 1u << 24), "",
              "vpl: directions per probe for the direct light"),
        field("sampling", &VplConfig::sampling, choiceOf<VplSampling>(), "",
              "vpl: light-path sampling", "--vpl-sampling"),
        field("clamp", &VplConfig::clamp, choiceOf<VplClamp>(), "", "vpl: near-VPL clamping",
              "--vpl-clamp"),
        field("clamp_distance", &VplConfig::clampDistance, positive().orAuto(), "m",
              "vpl: clamp distance or sphere radius (auto: 2 sqrt(area / (pi count)))"),
        field("near_field", &VplConfig::nearField, nonNegative().orAuto().because("0 turns it off"),
              "m", "vpl: surfaces nearer than this are path-traced (auto: 2 x clamp distance)"),
        onOffField("shadows", &VplConfig::shadows, "vpl: visibility of VPLs at probes",
                   "--vpl-shadows"),
        field("cut_error", &VplConfig::cutError,
              number(0.0, 1.0, false, true).because("0 gathers every VPL"), "",
              "vpl: lightcut error bound, fraction of the probe's irradiance"),
    };
    return fields;
}

const std::vector<Field<LpvConfig>>& lpvFields() {
    static const std::vector<Field<LpvConfig>> fields = {
        field("grid", &LpvConfig::grid, whole(4, 256), "",
              "lpv: cells along the longest axis of a cascade", "--lpv-grid"),
        field("cascades", &LpvConfig::cascades, whole(1, 4), "", "lpv: nested grids per volume",
              "--lpv-cascades"),
        field("cascade_ratio", &LpvConfig::cascadeRatio, number(1.25, 4.0), "",
              "lpv: cell size of a cascade / that of the next finer one"),
        field("iterations", &LpvConfig::iterations, whole(1, 4096).orAuto(), "",
              "lpv: propagation steps (auto: the grid size)", "--lpv-iterations"),
        field("propagation_weight", &LpvConfig::propagationWeight,
              number(0.0, 1.0, true).because("1 passes all light on"), "",
              "lpv: fraction of the flux a step passes on"),
        field("fade_cells", &LpvConfig::fadeCells, number(0.0, 64.0), "cells",
              "lpv: cells over which a finer cascade blends into the next"),
        onOffField("occlusion", &LpvConfig::occlusion, "lpv: geometry volume", "--lpv-occlusion"),
        field("direct", &LpvConfig::direct, choiceOf<LpvDirect>(), "",
              "lpv: direct light traced or propagated", "--lpv-direct"),
        field("direct_samples", &LpvConfig::directSamples, whole(1, 1u << 24), "",
              "lpv: directions per probe for the traced direct light"),
        field("vpl_count", &LpvConfig::vplCount, whole(1, 1u << 24), "", "lpv: VPLs injected"),
        field("intensity", &LpvConfig::intensity, nonNegative(), "",
              "lpv: scale of the propagated light (1 = physical)"),
    };
    return fields;
}

const std::vector<Field<BakeConfig>>& validityFields() {
    static const std::vector<Field<BakeConfig>> fields = {
        field("backface_threshold", &BakeConfig::backfaceThreshold, number(0.0, 1.0), "",
              "a probe is invalid when more of its rays than this hit back faces"),
        field("dilate", &BakeConfig::dilate, flag(), "", "fill invalid probes from valid ones"),
        field("nudge", &BakeConfig::nudge, flag(), "",
              "bricked: bake invalid box-face probes again just inside the box"),
        field("relocate", &BakeConfig::relocate, flag(), "",
              "dense: bake probes inside geometry at the nearest free point within a cell"),
        field("visibility", &BakeConfig::visibility, flag(), "",
              "store per-probe visibility so interpolation does not leak through walls"),
    };
    return fields;
}

const std::vector<Field<EnvironmentConfig>>& environmentFields() {
    using Type = EnvironmentConfig::Type;
    static const std::vector<Field<EnvironmentConfig>> fields = {
        shownWhen(field("intensity", &EnvironmentConfig::intensity, emission(), "",
                        "environment: radiance scale"),
                  {[](const EnvironmentConfig& e) { return e.type != Type::Black; }}),
        shownWhen(field("rotation_deg", &EnvironmentConfig::rotationDeg, anyNumber(), "degrees",
                        "environment: rotation of a lat-long image about +Y"),
                  {[](const EnvironmentConfig& e) { return e.type == Type::LatLong; }}),
    };
    return fields;
}

const std::vector<Field<LightModesConfig>>& lightsFields() {
    static const std::vector<Field<LightModesConfig>> fields = {
        field("mode", &LightModesConfig::punctual, choiceOf<LightMode>(), "",
              "punctual lights: baked (direct and bounced), indirect (bounced only: the engine "
              "shades their direct light) or none",
              "--light-mode"),
        field("emissive", &LightModesConfig::emissive, choiceOf<LightMode>(), "",
              "emissive surfaces: baked, indirect or none", "--emissive-mode"),
        field("environment", &LightModesConfig::environment, choiceOf<LightMode>(), "",
              "the environment: baked, indirect or none", "--environment-mode"),
    };
    return fields;
}

const std::vector<Field<BoundsConfig>>& boundsFields() {
    static const std::vector<Field<BoundsConfig>> fields = {
        field("padding", &BoundsConfig::padding, nonNegative().orAuto(), "m",
              "volume bounds: metres added on every side (auto: grow around a closed object)",
              "--padding"),
    };
    return fields;
}

const std::vector<Field<VolumeConfig>>& volumeFields() {
    const auto automatic = [](const VolumeConfig& v) { return !v.resolution; };
    // Bricked settings are shown for an automatic layout too: it may become bricked.
    const auto bricked = [](const VolumeConfig& v) { return v.layout != VolumeLayout::Dense; };
    static const std::vector<Field<VolumeConfig>> fields = {
        shownWhen(field("density", &VolumeConfig::density, positive(), "probes/m",
                        "automatic resolution: probes per metre", "--density"),
                  {automatic}),
        shownWhen(field("max_resolution", &VolumeConfig::maxResolution,
                        whole(1, grid::kMaxResolution).powersOfTwo(), "",
                        "automatic resolution: cap per axis", "--max-resolution"),
                  {automatic}),
        shownWhen(field("max_probes", &VolumeConfig::maxProbes, whole(8, 1u << 24).orAuto(), "",
                        "automatic resolution: most probes (bricked: level-0 probes); past it "
                        "the finest axis is halved (auto: 32768 dense, 131072 bricked)",
                        "--max-probes"),
                  {automatic}),
        field("position", &VolumeConfig::position, choiceOf<grid::PositionMode>(), "",
              "probe placement", "--position"),
        field("format", &VolumeConfig::storage, choiceOf<Storage>(), "", "texel storage",
              "--format"),
        {"sh_order", whole(1, 2), "", "SH order", "--sh-order",
         [](const VolumeConfig& v) { return Json(int(v.shOrder)); },
         [](VolumeConfig& v, const Json& j) {
             v.shOrder = j.get<int>() == 1 ? sh::Order::L1 : sh::Order::L2;
         }},
        field("blend_priority", &VolumeConfig::blendPriority,
              whole(std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max()), "",
              "overlapping volumes: the higher priority wins"),
        field("fade_distance", &VolumeConfig::fadeDistance, nonNegative(), "m",
              "blend into lower-priority volumes over this distance inside the bounds"),
        field("layout", &VolumeConfig::layout, choiceOf<VolumeLayout>().orAuto(), "",
              "dense grid or bricked (adaptive; auto: bricked where a dense grid at the "
              "density would pass 32768 probes)",
              "--layout"),
        shownWhen(field("levels", &VolumeConfig::maxLevel, whole(0, brick::kMaxLevel), "",
                        "bricked: finer levels over level 0"),
                  {bricked}),
        shownWhen(field("refine_error", &VolumeConfig::refineError, positive(), "",
                        "bricked: disagreement that refines an octant, fraction of RMS "
                        "irradiance"),
                  {bricked}),
    };
    return fields;
}

// The keys each object of the config holds besides its table's scalar fields: sections and
// values with structure of their own, parsed by hand. With the tables, the config's whole
// vocabulary (configVocabulary, from which tools/fuzz.sh writes the fuzz dictionary).
constexpr std::array<const char*, 7> kTopSections = {"path",    "vpl",      "lpv",   "environment",
                                                     "volumes", "validity", "lights"};
constexpr std::array<const char*, 1> kLightsKeys = {"per_light"};
constexpr std::array<const char*, 3> kVolumeKeys = {"name", "bounds", "resolution"};
constexpr std::array<const char*, 3> kEnvironmentKeys = {"type", "radiance", "file"};
constexpr std::array<const char*, 7> kBoundsKeys = {"mode", "center", "size", "min",
                                                    "max",  "nodes",  "node"};

template <class T>
std::vector<std::string> keysOf(const std::vector<Field<T>>& fields,
                                std::span<const char* const> others) {
    std::vector<std::string> keys;
    for (const Field<T>& f : fields) {
        keys.emplace_back(f.key);
    }
    keys.insert(keys.end(), others.begin(), others.end());
    return keys;
}

// The table's fields present in `j` into `out`. `j` may hold only the table's keys and
// `others` (parsed by the caller).
template <class T>
void readFields(const Reader& r, const Json& j, const std::string& path,
                const std::vector<Field<T>>& fields, T& out,
                std::span<const char* const> others = {}) {
    r.checkKeys(j, path, keysOf(fields, others));
    for (const Field<T>& f : fields) {
        const std::string key(f.key);
        if (j.contains(key)) {
            f.set(out, r.check(f.admits, j[key], Reader::join(path, f.key)));
        }
    }
}

template <class T>
void writeFields(Json& out, const std::vector<Field<T>>& fields, const T& in) {
    for (const Field<T>& f : fields) {
        if (f.shown && !f.shown(in)) {
            continue;
        }
        Json v = f.get(in);
        if (!v.is_null()) {
            out[std::string(f.key)] = std::move(v);
        } else if (f.admits.autoValue) {
            out[std::string(f.key)] = "auto";
        }
    }
}

template <class T>
void checkFields(const Reader& r, const std::string& path, const std::vector<Field<T>>& fields,
                 const T& in) {
    for (const Field<T>& f : fields) {
        const Json v = f.get(in);
        if (!v.is_null()) {
            r.check(f.admits, v, Reader::join(path, f.key));
        }
    }
}

// ---- The structured parts: bounds, resolution, environment, volumes ----

// Checks of a parsed or built volume that involve more than one field.
void checkVolume(const Reader& r, const VolumeConfig& v, const std::string& path) {
    if (v.bounds.mode == BoundsMode::Custom) {
        for (int a = 0; a < 3; ++a) {
            if (!(v.bounds.max[a] > v.bounds.min[a])) {
                r.fail(path + ".bounds.max[" + std::to_string(a) + "]",
                       "must be greater than min (zero-size or inverted bounds)");
            }
        }
    }
    if (v.resolution) {
        for (int a = 0; a < 3; ++a) {
            const std::string p = path + ".resolution[" + std::to_string(a) + "]";
            const uint32_t n = (*v.resolution)[a];
            r.check(whole(1, grid::kMaxResolution), n, p);
            if (!grid::isPowerOfTwo(n)) {
                r.fail(p, std::to_string(n) + " is not a power of two (1, 2, 4 .. 256)");
            }
        }
    }
    if (v.layout == VolumeLayout::Bricked && v.position == grid::PositionMode::Corner) {
        r.fail(path + ".position",
               "bricked volumes place probes on brick corners themselves; omit \"position\"");
    }
}

std::string nodeName(const Reader& r, const Json& n, const std::string& path) {
    return n.is_number() ? std::to_string(r.check(whole(0, 1u << 30), n, path).get<uint64_t>())
                         : r.string(n, path);
}

BoundsConfig parseBounds(const Reader& r, const Json& j, const std::string& path) {
    BoundsConfig b;
    readFields(r, j, path, boundsFields(), b, kBoundsKeys);
    if (!j.contains("mode")) {
        r.fail(path + ".mode", "missing (custom, auto-world or auto-local)");
    }
    fromJson(r.check(choiceOf<BoundsMode>(), j["mode"], path + ".mode"), b.mode);
    if (b.mode == BoundsMode::Custom) {
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
        }
    } else if (b.mode == BoundsMode::AutoWorld) {
        if (j.contains("nodes")) {
            if (!j["nodes"].is_array()) {
                r.fail(path + ".nodes", "must be an array of node names or indices");
            }
            for (size_t i = 0; i < j["nodes"].size(); ++i) {
                b.nodes.push_back(
                    nodeName(r, j["nodes"][i], path + ".nodes[" + std::to_string(i) + "]"));
            }
        }
    } else {
        if (!j.contains("node")) {
            r.fail(path + ".node", "missing (auto-local bounds follow one node)");
        }
        b.node = nodeName(r, j["node"], path + ".node");
    }
    return b;
}

Json describeBounds(const BoundsConfig& b) {
    Json j = {{"mode", std::string(toString(b.mode))}};
    writeFields(j, boundsFields(), b);
    if (b.mode == BoundsMode::Custom) {
        j["min"] = {b.min.x, b.min.y, b.min.z};
        j["max"] = {b.max.x, b.max.y, b.max.z};
    } else if (b.mode == BoundsMode::AutoWorld && !b.nodes.empty()) {
        j["nodes"] = b.nodes;
    } else if (b.mode == BoundsMode::AutoLocal) {
        j["node"] = b.node;
    }
    return j;
}

VolumeConfig parseVolume(const Reader& r, const Json& j, const std::string& path) {
    VolumeConfig v;
    readFields(r, j, path, volumeFields(), v, kVolumeKeys);
    if (j.contains("name")) {
        v.name = r.string(j["name"], path + ".name");
    }
    if (j.contains("bounds")) {
        v.bounds = parseBounds(r, j["bounds"], path + ".bounds");
    }
    if (j.contains("resolution")) {
        const Json& res = j["resolution"];
        if (res.is_string()) {
            r.checkChoice({"auto"}, res, path + ".resolution");
        } else {
            if (!res.is_array() || res.size() != 3) {
                r.fail(path + ".resolution", "must be \"auto\" or an array of 3 powers of two");
            }
            glm::uvec3 value;
            for (int a = 0; a < 3; ++a) {
                const std::string p = path + ".resolution[" + std::to_string(a) + "]";
                value[a] =
                    uint32_t(r.check(whole(1, grid::kMaxResolution), res[a], p).get<uint64_t>());
            }
            v.resolution = value;
        }
    }
    checkVolume(r, v, path);
    return v;
}

Json describeVolume(const VolumeConfig& v) {
    Json j = {{"name", v.name}, {"bounds", describeBounds(v.bounds)}};
    writeFields(j, volumeFields(), v);
    if (v.resolution) {
        j["resolution"] = {v.resolution->x, v.resolution->y, v.resolution->z};
    } else {
        j["resolution"] = "auto";
    }
    return j;
}

void checkEnvironment(const Reader& r, const EnvironmentConfig& e, const std::string& path) {
    if (e.type == EnvironmentConfig::Type::Constant) {
        for (int c = 0; c < 3; ++c) {
            r.check(emission(), e.radiance[c], path + ".radiance[" + std::to_string(c) + "]");
        }
    }
}

EnvironmentConfig parseEnvironment(const Reader& r, const Json& j, const std::string& path,
                                   const std::filesystem::path& base_dir) {
    EnvironmentConfig e;
    readFields(r, j, path, environmentFields(), e, kEnvironmentKeys);
    if (!j.contains("type")) {
        r.fail(path + ".type", "missing (black, constant or latlong)");
    }
    fromJson(r.check(choiceOf<EnvironmentConfig::Type>(), j["type"], path + ".type"), e.type);
    if (e.type == EnvironmentConfig::Type::Constant) {
        if (!j.contains("radiance")) {
            r.fail(path + ".radiance", "missing for a constant environment");
        }
        e.radiance = r.vec3(j["radiance"], path + ".radiance");
    } else if (e.type == EnvironmentConfig::Type::LatLong) {
        if (!j.contains("file")) {
            r.fail(path + ".file", "missing for a latlong environment");
        }
        e.file = r.string(j["file"], path + ".file");
        if (e.file.is_relative() && !base_dir.empty()) {
            e.file = base_dir / e.file;
        }
    }
    checkEnvironment(r, e, path);
    return e;
}

Json describeEnvironment(const EnvironmentConfig& e) {
    Json j = {{"type", std::string(toString(e.type))}};
    writeFields(j, environmentFields(), e);
    if (e.type == EnvironmentConfig::Type::Constant) {
        j["radiance"] = {e.radiance.x, e.radiance.y, e.radiance.z};
    } else if (e.type == EnvironmentConfig::Type::LatLong) {
        j["file"] = e.file.string();
    }
    return j;
}

// "lights": the table's fields and "per_light", an object from light name or index to mode.
LightModesConfig parseLights(const Reader& r, const Json& j) {
    LightModesConfig l;
    readFields(r, j, "lights", lightsFields(), l, kLightsKeys);
    if (j.contains("per_light")) {
        const Json& per = j["per_light"];
        if (!per.is_object()) {
            r.fail("lights.per_light", "must be an object from light name or index to mode");
        }
        for (const auto& [key, value] : per.items()) {
            const std::string path = "lights.per_light." + key;
            LightMode mode = LightMode::Baked;
            fromJson(r.check(choiceOf<LightMode>(), value, path), mode);
            l.perLight.emplace_back(key, mode);
        }
    }
    return l;
}

Json describeLights(const LightModesConfig& l) {
    Json j = Json::object();
    writeFields(j, lightsFields(), l);
    if (!l.perLight.empty()) {
        Json per = Json::object();
        for (const auto& [key, mode] : l.perLight) {
            per[key] = std::string(toString(mode));
        }
        j["per_light"] = per;
    }
    return j;
}

BakeConfig parseTop(const Reader& r, const Json& j, const std::filesystem::path& base_dir) {
    BakeConfig c;
    readFields(r, j, "", topFields(), c, kTopSections);
    if (j.contains("path")) {
        readFields(r, j["path"], "path", pathFields(), c.path);
    }
    if (j.contains("vpl")) {
        readFields(r, j["vpl"], "vpl", vplFields(), c.vpl);
    }
    if (j.contains("lpv")) {
        readFields(r, j["lpv"], "lpv", lpvFields(), c.lpv);
    }
    if (j.contains("environment")) {
        c.environment = parseEnvironment(r, j["environment"], "environment", base_dir);
    }
    if (j.contains("validity")) {
        readFields(r, j["validity"], "validity", validityFields(), c);
    }
    if (j.contains("lights")) {
        c.lights = parseLights(r, j["lights"]);
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

// ---- Settings by path, for the command line ----

// One scalar setting of BakeConfig: its table row and where its struct lives in a BakeConfig.
struct Setting {
    SettingInfo info;
    Admits admits;
    std::function<void(BakeConfig&, const Json&)> set;
};

template <class T>
void addSettings(std::vector<Setting>& out, const std::string& prefix,
                 const std::vector<Field<T>>& fields,
                 std::function<void(BakeConfig&, const std::function<void(T&)>&)> each) {
    for (const Field<T>& f : fields) {
        SettingInfo info{prefix + std::string(f.key), std::string(f.flag), std::string(f.help),
                         std::string(f.unit),         f.admits.text(),     f.admits.typeName()};
        auto set = [each, setter = f.set](BakeConfig& c, const Json& j) {
            each(c, [&](T& t) { setter(t, j); });
        };
        out.push_back(Setting{std::move(info), f.admits, std::move(set)});
    }
}

const std::vector<Setting>& settings() {
    static const std::vector<Setting> all = [] {
        std::vector<Setting> s;
        using BakeEach = std::function<void(BakeConfig&, const std::function<void(BakeConfig&)>&)>;
        const BakeEach top = [](BakeConfig& c, const auto& f) { f(c); };
        addSettings<BakeConfig>(s, "", topFields(), top);
        addSettings<PathConfig>(s, "path.", pathFields(),
                                [](BakeConfig& c, const auto& f) { f(c.path); });
        addSettings<VplConfig>(s, "vpl.", vplFields(),
                               [](BakeConfig& c, const auto& f) { f(c.vpl); });
        addSettings<LpvConfig>(s, "lpv.", lpvFields(),
                               [](BakeConfig& c, const auto& f) { f(c.lpv); });
        addSettings<BakeConfig>(s, "validity.", validityFields(), top);
        addSettings<EnvironmentConfig>(s, "environment.", environmentFields(),
                                       [](BakeConfig& c, const auto& f) { f(c.environment); });
        addSettings<LightModesConfig>(s, "lights.", lightsFields(),
                                      [](BakeConfig& c, const auto& f) { f(c.lights); });
        addSettings<VolumeConfig>(s, "volumes[].", volumeFields(),
                                  [](BakeConfig& c, const auto& f) {
                                      for (VolumeConfig& v : c.volumes) {
                                          f(v);
                                      }
                                  });
        addSettings<BoundsConfig>(s, "volumes[].bounds.", boundsFields(),
                                  [](BakeConfig& c, const auto& f) {
                                      for (VolumeConfig& v : c.volumes) {
                                          f(v.bounds);
                                      }
                                  });
        return s;
    }();
    return all;
}

// A command-line value as JSON: numbers and true/false as such, anything else a string.
Json fromText(std::string_view text) {
    Result<Json> j = parseJsonText<Json>(text, "value");
    if (!j || j.value().is_null() || j.value().is_object() || j.value().is_array()) {
        return std::string(text);
    }
    return std::move(j).value();
}

template <class F>
Result<void> guarded(F&& f) {
    try {
        f();
        return {};
    } catch (const ConfigError& e) {
        return makeError(ErrorCode::InvalidArgument, e.message);
    } catch (const Json::exception& e) {
        return makeError(ErrorCode::InvalidArgument, e.what());
    }
}

Result<const Setting*> findSetting(std::string_view path) {
    for (const Setting& s : settings()) {
        if (s.info.path == path) {
            return &s;
        }
    }
    return makeError(ErrorCode::InvalidArgument, std::string(path) + ": no such setting");
}

} // namespace

const std::vector<SettingInfo>& bakeSettings() {
    static const std::vector<SettingInfo> infos = [] {
        std::vector<SettingInfo> out;
        for (const Setting& s : settings()) {
            out.push_back(s.info);
        }
        return out;
    }();
    return infos;
}

Result<void> checkBakeSetting(std::string_view path, std::string_view text,
                              std::string_view source) {
    Result<const Setting*> s = findSetting(path);
    if (!s) {
        return s.error();
    }
    return guarded(
        [&] { Reader(source).check(s.value()->admits, fromText(text), std::string(path)); });
}

Result<void> setBakeSetting(BakeConfig& config, std::string_view path, std::string_view text,
                            std::string_view source) {
    Result<const Setting*> s = findSetting(path);
    if (!s) {
        return s.error();
    }
    return guarded([&] {
        const Json value =
            Reader(source).check(s.value()->admits, fromText(text), std::string(path));
        s.value()->set(config, value);
    });
}

std::vector<std::string> configVocabulary() {
    std::set<std::string> words;
    for (const Setting& s : settings()) {
        const std::string& path = s.info.path;
        const size_t dot = path.rfind('.');
        words.insert(dot == std::string::npos ? path : path.substr(dot + 1));
        words.insert(s.admits.names.begin(), s.admits.names.end());
        if (s.admits.autoValue) {
            words.insert("auto");
        }
    }
    for (const auto& keys :
         {std::span<const char* const>(kTopSections), std::span<const char* const>(kVolumeKeys),
          std::span<const char* const>(kEnvironmentKeys), std::span<const char* const>(kBoundsKeys),
          std::span<const char* const>(kLightsKeys)}) {
        words.insert(keys.begin(), keys.end());
    }
    for (const std::string& name : enumNames<BoundsMode>()) {
        words.insert(name);
    }
    for (const std::string& name : enumNames<EnvironmentConfig::Type>()) {
        words.insert(name);
    }
    return {words.begin(), words.end()};
}

Result<void> validateBakeConfig(const BakeConfig& c) {
    return guarded([&] {
        const Reader r("bake config");
        checkFields(r, "", topFields(), c);
        checkFields(r, "path", pathFields(), c.path);
        checkFields(r, "vpl", vplFields(), c.vpl);
        checkFields(r, "lpv", lpvFields(), c.lpv);
        checkFields(r, "validity", validityFields(), c);
        checkFields(r, "environment", environmentFields(), c.environment);
        r.check(choiceOf<EnvironmentConfig::Type>(), std::string(toString(c.environment.type)),
                "environment.type");
        checkEnvironment(r, c.environment, "environment");
        checkFields(r, "lights", lightsFields(), c.lights);
        for (const auto& [key, mode] : c.lights.perLight) {
            r.check(choiceOf<LightMode>(), std::string(toString(mode)), "lights.per_light." + key);
        }
        std::set<std::string> names;
        for (size_t i = 0; i < c.volumes.size(); ++i) {
            const std::string path = "volumes[" + std::to_string(i) + "]";
            const VolumeConfig& v = c.volumes[i];
            checkFields(r, path, volumeFields(), v);
            checkFields(r, path + ".bounds", boundsFields(), v.bounds);
            r.check(choiceOf<BoundsMode>(), std::string(toString(v.bounds.mode)),
                    path + ".bounds.mode");
            checkVolume(r, v, path);
            if (!names.insert(v.name).second) {
                r.fail(path + ".name", "\"" + v.name + "\" is used by an earlier volume");
            }
        }
    });
}

Result<BakeConfig> parseBakeConfig(std::string_view json_text, std::string_view source,
                                   const std::filesystem::path& base_dir) {
    Result<Json> j = parseJsonText<Json>(json_text, source);
    if (!j) {
        return j.error();
    }
    try {
        return parseTop(Reader(source), j.value(), base_dir);
    } catch (const ConfigError& e) {
        return makeError(ErrorCode::InvalidArgument, e.message);
    } catch (const Json::exception& e) {
        return makeError(ErrorCode::InvalidArgument, std::string(source) + ": " + e.what());
    }
}

Result<BakeConfig> loadBakeConfig(const std::filesystem::path& path) {
    Result<std::string> text = readRegularFile(path, kMaxConfigBytes, "config file");
    if (!text) {
        return text.error();
    }
    return parseBakeConfig(text.value(), path.string(), path.parent_path());
}

std::string describeConfig(const BakeConfig& c) {
    Json j;
    writeFields(j, topFields(), c);
    writeFields(j["path"], pathFields(), c.path);
    if (c.method == Method::Vpl) {
        writeFields(j["vpl"], vplFields(), c.vpl);
    }
    if (c.method == Method::Lpv) {
        writeFields(j["lpv"], lpvFields(), c.lpv);
    }
    j["environment"] = describeEnvironment(c.environment);
    j["lights"] = describeLights(c.lights);
    writeFields(j["validity"], validityFields(), c);
    j["volumes"] = Json::array();
    for (const VolumeConfig& v : c.volumes) {
        j["volumes"].push_back(describeVolume(v));
    }
    // A config built in code (or an --env path) may hold bytes that are not UTF-8; dump() would
    // throw on them, inside bake(). They are recorded as U+FFFD instead.
    return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

Result<Environment> makeEnvironment(const EnvironmentConfig& config, uint64_t max_bytes) {
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
        return loadLatLongEnvironment(config.file, config.intensity, config.rotationDeg, max_bytes);
    }
    return env;
}

} // namespace probekit::baker
