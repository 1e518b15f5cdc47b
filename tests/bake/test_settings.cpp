// The settings table (settings.hpp): the config file, the command line, describeConfig and
// validateBakeConfig agree on every setting because they read one table, and these tests hold
// them to it: every setting parses from the config, sets from its command-line text with the
// same error the config gives, round-trips through describeConfig, and is documented in the
// baking guide (docs/baking.md); a config built in code is validated by bake() in every build
// type.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bake_test_support.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/settings.hpp"

using namespace probekit;
using namespace probekit::baker;
using Json = nlohmann::json;

namespace {

// The config JSON holding `value` at a setting's path ("lpv.grid", "volumes[].density").
Json configWith(const std::string& path, const Json& value) {
    std::string p = path;
    const bool per_volume = p.rfind("volumes[].", 0) == 0;
    if (per_volume) {
        p = p.substr(10);
    }
    Json leaf = value;
    for (size_t dot = p.rfind('.'); dot != std::string::npos; dot = p.rfind('.')) {
        leaf = Json{{p.substr(dot + 1), leaf}};
        p = p.substr(0, dot);
    }
    leaf = Json{{p, leaf}};
    if (per_volume) {
        if (leaf.contains("bounds")) {
            leaf["bounds"]["mode"] = "auto-world";
        }
        return Json{{"volumes", Json::array({leaf})}};
    }
    return leaf;
}

// The value describeConfig writes for a setting (null when it writes none).
Json describedValue(const BakeConfig& c, const std::string& path) {
    Json j = Json::parse(describeConfig(c));
    std::string p = path;
    if (p.rfind("volumes[].", 0) == 0) {
        j = j["volumes"][0];
        p = p.substr(10);
    }
    for (size_t dot = p.find('.'); dot != std::string::npos; dot = p.find('.')) {
        j = j.value(p.substr(0, dot), Json::object());
        p = p.substr(dot + 1);
    }
    return j.value(p, Json());
}

// A config in which every setting is described: method vpl shows the vpl section; a second
// one with method lpv and a bricked volume with a lat-long sky shows the rest.
std::vector<BakeConfig> describedConfigs() {
    BakeConfig vpl;
    vpl.method = Method::Vpl;
    vpl.targetError = 0.05;
    vpl.volumes.push_back(VolumeConfig{});
    vpl.volumes[0].density = 3.0f;
    vpl.environment.type = EnvironmentConfig::Type::Constant;
    BakeConfig lpv = vpl;
    lpv.method = Method::Lpv;
    lpv.volumes[0].layout = VolumeLayout::Bricked;
    lpv.environment.type = EnvironmentConfig::Type::LatLong;
    lpv.environment.file = "sky.hdr";
    return {vpl, lpv};
}

TEST(Settings, EveryCommandLineTextRoundTripsThroughDescribeAndTheConfigFile) {
    size_t covered = 0;
    for (const SettingInfo& s : bakeSettings()) {
        SCOPED_TRACE(s.path);
        for (const BakeConfig& base : describedConfigs()) {
            const Json described = describedValue(base, s.path);
            if (described.is_null()) {
                continue;
            }
            // The described value, as a command line would write it, sets the same config.
            const std::string text =
                described.is_string() ? described.get<std::string>() : described.dump();
            BakeConfig set = base;
            ASSERT_TRUE(setBakeSetting(set, s.path, text).ok()) << text;
            EXPECT_EQ(describeConfig(set), describeConfig(base)) << text;
            ++covered;
            break;
        }
    }
    // Every setting is described by one of the two configs.
    EXPECT_EQ(covered, bakeSettings().size());
    // And the config file reads back what describeConfig wrote.
    for (const BakeConfig& base : describedConfigs()) {
        Result<BakeConfig> parsed = parseBakeConfig(describeConfig(base), "described.json");
        ASSERT_TRUE(parsed.ok()) << parsed.error().message;
        EXPECT_EQ(describeConfig(parsed.value()), describeConfig(base));
    }
}

TEST(Settings, TheCommandLineAndTheConfigFileRejectAValueWithTheSameMessage) {
    // Each setting gets a value of the wrong kind and, where it has a range, one outside it.
    for (const SettingInfo& s : bakeSettings()) {
        SCOPED_TRACE(s.path);
        std::vector<std::string> bad = {s.type == "NAME" ? "\"no-such-name\"" : "\"12abc\""};
        if (s.type == "INT" || s.type == "NUMBER") {
            bad.push_back("-1e40");
        }
        if (s.type == "BOOL") {
            bad.push_back("3");
        }
        for (const std::string& value : bad) {
            const Json json = Json::parse(value);
            const std::string text = json.is_string() ? json.get<std::string>() : value;
            Result<void> flag = checkBakeSetting(s.path, text, "--flag");
            Result<BakeConfig> file = parseBakeConfig(configWith(s.path, json).dump(), "bake.json");
            ASSERT_FALSE(flag.ok()) << text;
            ASSERT_FALSE(file.ok()) << value;
            const std::string flag_what = flag.error().message.substr(std::string("--flag").size());
            const std::string file_what =
                file.error().message.substr(file.error().message.find(": "));
            // The file names the path inside a volume ("volumes[0].density"), the flag the
            // setting ("volumes[].density"); what follows the path is the same.
            EXPECT_EQ(flag_what.substr(flag_what.find(": ", 2)),
                      file_what.substr(file_what.find(": ", 2)))
                << flag.error().message << " / " << file.error().message;
        }
    }
}

TEST(Settings, RangesAreCheckedAtTheirEnds) {
    struct Case {
        const char* path;
        const char* ok;
        const char* bad;
        const char* message;
    };
    const Case cases[] = {
        {"lpv.grid", "4", "3", "lpv.grid: must be in 4..256 (got 3)"},
        {"lpv.grid", "256", "257", "lpv.grid: must be in 4..256 (got 257)"},
        {"vpl.cut_error", "0", "1", "vpl.cut_error: must be in [0, 1) (got 1; 0 gathers"},
        {"lpv.propagation_weight", "1", "0", "must be in (0, 1] (got 0; 1 passes"},
        {"lpv.cascade_ratio", "1.25", "1.2", "lpv.cascade_ratio: must be in [1.25, 4] (got 1.2"},
        {"target_error", "0.5", "1", "target_error: must be in (0, 1) (got 1; a relative"},
        {"volumes[].density", "0.01", "0", "volumes[].density: must be > 0 (got 0)"},
        {"volumes[].max_resolution", "64", "48", "volumes[].max_resolution: must be a power"},
        {"volumes[].sh_order", "1", "3", "volumes[].sh_order: must be in 1..2 (got 3)"},
        {"vpl.count", "auto", "many", "vpl.count: \"many\" is not one of auto"},
        {"vpl.clamp", "none", "sphere", "vpl.clamp: \"sphere\" is not one of none, distance"},
        {"path.max_bounces", "0", "-1", "path.max_bounces: must be >= 0 (got -1)"},
        {"max_memory_mb", "1", "0", "max_memory_mb: must be in 1..1073741824 (got 0)"},
        {"validity.dilate", "false", "yes", "validity.dilate: must be true or false"},
        // Below the open end as a double, at it as the float the setting is stored in (found by
        // fuzz_config).
        {"path.noise_target", "0.99999994", "0.9999999999999999",
         "path.noise_target: must be in [0, 1) (got 0.9999999999999999, which is 1 as a 32-bit "
         "float"},
        {"lpv.propagation_weight", "1e-30", "1e-50", "which is 0 as a 32-bit float"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.path);
        EXPECT_TRUE(checkBakeSetting(c.path, c.ok).ok());
        Result<void> r = checkBakeSetting(c.path, c.bad);
        ASSERT_FALSE(r.ok());
        EXPECT_NE(r.error().message.find(c.message), std::string::npos) << r.error().message;
    }
    Result<void> unknown = checkBakeSetting("lpv.gird", "4");
    ASSERT_FALSE(unknown.ok());
    EXPECT_EQ(unknown.error().message, "lpv.gird: no such setting");
}

TEST(Settings, PerVolumeSettingsSetEveryVolume) {
    BakeConfig c;
    c.volumes.resize(3);
    ASSERT_TRUE(setBakeSetting(c, "volumes[].format", "float").ok());
    ASSERT_TRUE(setBakeSetting(c, "volumes[].bounds.padding", "0.25").ok());
    for (const VolumeConfig& v : c.volumes) {
        EXPECT_EQ(v.storage, Storage::Float32);
        EXPECT_EQ(v.bounds.padding, 0.25f);
    }
    ASSERT_TRUE(setBakeSetting(c, "vpl.near_field", "auto").ok());
    EXPECT_FALSE(c.vpl.nearField.has_value());
    ASSERT_TRUE(setBakeSetting(c, "vpl.near_field", "0.5").ok());
    EXPECT_EQ(c.vpl.nearField, 0.5f);
}

// Every key of a JSON object, at any depth.
void collectKeys(const Json& j, std::set<std::string>& keys) {
    if (j.is_object()) {
        for (const auto& [key, value] : j.items()) {
            keys.insert(key);
            collectKeys(value, keys);
        }
    } else if (j.is_array()) {
        for (const Json& e : j) {
            collectKeys(e, keys);
        }
    }
}

// The fuzz dictionary's source (configVocabulary) holds every key a config can hold, written
// out by describeConfig for configs that use every kind of bounds, environment and layout, and
// every name a setting admits, so tools/fuzz.sh never gives the fuzzer a stale dictionary.
TEST(Settings, TheConfigVocabularyHoldsEveryKeyAndName) {
    const std::vector<std::string> vocabulary = configVocabulary();
    const std::set<std::string> words(vocabulary.begin(), vocabulary.end());
    EXPECT_TRUE(std::is_sorted(vocabulary.begin(), vocabulary.end()));
    EXPECT_EQ(words.size(), vocabulary.size()) << "no word twice";

    const char* configs[] = {
        R"({"environment": {"type": "constant", "radiance": [1, 1, 1]},
            "volumes": [{"name": "a", "layout": "bricked", "resolution": [2, 2, 2],
                         "bounds": {"mode": "custom", "center": [0, 0, 0], "size": [1, 1, 1],
                                    "padding": 0.5}},
                        {"name": "b", "bounds": {"mode": "auto-world", "nodes": ["n"]}},
                        {"name": "c", "bounds": {"mode": "auto-local", "node": "n"}}]})",
        R"({"method": "vpl", "environment": {"type": "latlong", "file": "sky.hdr"},
            "volumes": [{"bounds": {"mode": "custom", "min": [0, 0, 0], "max": [1, 1, 1]}}]})",
    };
    std::set<std::string> keys;
    for (const char* text : configs) {
        Result<BakeConfig> c = parseBakeConfig(text, "vocabulary.json", "/nonexistent");
        ASSERT_TRUE(c.ok()) << c.error().message;
        collectKeys(Json::parse(text), keys);
        collectKeys(Json::parse(describeConfig(c.value())), keys);
    }
    for (const std::string& key : keys) {
        EXPECT_TRUE(words.count(key)) << "key '" << key << "' is missing from configVocabulary";
    }
    for (const SettingInfo& s : bakeSettings()) {
        EXPECT_TRUE(words.count(s.path.substr(s.path.rfind('.') + 1))) << s.path;
        if (s.type != "NAME") {
            continue;
        }
        std::stringstream names(s.admits.substr(s.admits.rfind("auto or ", 0) == 0 ? 8 : 0));
        for (std::string name; std::getline(names >> std::ws, name, ',');) {
            EXPECT_TRUE(words.count(name)) << s.path << " admits '" << name << "'";
        }
    }
}

// A config built in code gets the errors the config file would give, from bake() itself.
TEST(Settings, BakeValidatesAConfigBuiltInCode) {
    const Scene scene = test::openSky(glm::vec3(1.0f));
    struct Case {
        std::function<void(BakeConfig&)> edit;
        const char* message;
    };
    const Case cases[] = {
        {[](BakeConfig& c) { c.lpv.grid = 2; }, "bake config: lpv.grid: must be in 4..256 (got 2)"},
        {[](BakeConfig& c) { c.path.samples = 0; }, "bake config: path.samples: must be in 1.."},
        {[](BakeConfig& c) { c.vpl.cutError = -0.5f; }, "bake config: vpl.cut_error: must be in"},
        {[](BakeConfig& c) { c.method = Method(7); }, "bake config: method: \"unknown\" is not"},
        {[](BakeConfig& c) { c.volumes[0].resolution = glm::uvec3(8, 12, 8); },
         "bake config: volumes[0].resolution[1]: 12 is not a power of two"},
        {[](BakeConfig& c) { c.volumes[0].resolution = glm::uvec3(8, 8, 512); },
         "bake config: volumes[0].resolution[2]: must be in 1..256"},
        {[](BakeConfig& c) {
             c.volumes[0].bounds.mode = BoundsMode::Custom;
             c.volumes[0].bounds.max = glm::vec3(1.0f, -1.0f, 1.0f);
         },
         "bake config: volumes[0].bounds.max[1]: must be greater than min"},
        {[](BakeConfig& c) {
             c.volumes[0].layout = VolumeLayout::Bricked;
             c.volumes[0].position = grid::PositionMode::Corner;
         },
         "bake config: volumes[0].position: bricked volumes place probes"},
        {[](BakeConfig& c) { c.volumes.push_back(c.volumes[0]); },
         "bake config: volumes[1].name: \"volume\" is used by an earlier volume"},
        {[](BakeConfig& c) { c.volumes[0].density = std::numeric_limits<float>::quiet_NaN(); },
         "bake config: volumes[0].density: must be finite"},
        {[](BakeConfig& c) {
             c.environment.type = EnvironmentConfig::Type::Constant;
             c.environment.radiance = glm::vec3(1.0f, -1.0f, 0.0f);
         },
         "bake config: environment.radiance[1]: must be in [0, 1e+20] (got -1.0)"},
        // kMaxEmission: a radiance that the bake's float sums would overflow (3e38 gave "probe
        // 0 has a non-finite SH coefficient").
        {[](BakeConfig& c) {
             c.environment.type = EnvironmentConfig::Type::Constant;
             c.environment.radiance = glm::vec3(3e38f, 1.0f, 1.0f);
         },
         "bake config: environment.radiance[0]: must be in [0, 1e+20] (got "
         "3.0000000054977558e+38)"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.message);
        BakeConfig config;
        config.volumes.push_back(VolumeConfig{});
        config.volumes[0].resolution = glm::uvec3(2);
        c.edit(config);
        Result<void> valid = validateBakeConfig(config);
        ASSERT_FALSE(valid.ok());
        EXPECT_NE(valid.error().message.find(c.message), std::string::npos)
            << valid.error().message;
        Result<BakeResult> baked = bake(scene, config);
        ASSERT_FALSE(baked.ok());
        EXPECT_EQ(baked.error().message, valid.error().message);
    }
    BakeConfig fine;
    EXPECT_TRUE(validateBakeConfig(fine).ok());
}

// The baking guide (docs/baking.md, which holds the config tables) documents every setting:
// its key or its path appears in backquotes, and its flag.
TEST(Settings, EverySettingIsDocumentedInTheBakingGuide) {
    std::ifstream in(std::filesystem::path(PROBEKIT_SOURCE_DIR) / "docs" / "baking.md");
    ASSERT_TRUE(in) << "docs/baking.md not found";
    std::stringstream text;
    text << in.rdbuf();
    const std::string guide = text.str();
    for (const SettingInfo& s : bakeSettings()) {
        const std::string key = s.path.substr(s.path.rfind('.') + 1);
        EXPECT_TRUE(guide.find("`" + key + "`") != std::string::npos ||
                    guide.find("`" + s.path + "`") != std::string::npos)
            << s.path << " is not in docs/baking.md";
        if (!s.flag.empty()) {
            EXPECT_NE(guide.find(s.flag), std::string::npos)
                << s.flag << " (" << s.path << ") is not in docs/baking.md";
        }
    }
}

} // namespace
