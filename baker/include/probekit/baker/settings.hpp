// probekit::baker — the bake settings as data.
//
// Every setting of BakeConfig has one row in one table (baker/src/config.cpp): its JSON key,
// the member it sets, the values it admits, its unit, its help text and its command-line flag.
// That table parses the config file (parseBakeConfig), writes it back (describeConfig), checks a
// config built in code (validateBakeConfig, which bake() calls first) and gives `probekit bake`
// its flags, so a range or a choice name is written once (ARCHITECTURE.md, "bake setting").
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "probekit/baker/config.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

struct SettingInfo {
    std::string path;   // JSON path in the config file: "lpv.grid"; per volume: "volumes[].density"
    std::string flag;   // `probekit bake` flag ("--lpv-grid"); empty when the setting has none
    std::string help;   // one line for --help and the config table (docs/baking.md#config)
    std::string unit;   // "m", "MiB", "cells" ...; empty for counts, names and fractions
    std::string admits; // the values it takes, e.g. "4..256", "none, distance, spherical", "> 0"
    std::string type;   // what a value is: "INT", "NUMBER", "BOOL" or "NAME"
};

// Every scalar setting, in the order of the config's sections. Settings with structure of their
// own (bounds corners, resolution, environment radiance and file, volume names) are parsed by
// hand and are not listed.
const std::vector<SettingInfo>& bakeSettings();

// Every word a config file may hold: the key of every field of every object (the scalar
// settings' keys, the sections and the structured values' keys) and every name a setting
// admits ("auto" included), sorted. tools/fuzz.sh writes the config fuzzer's dictionary from it.
std::vector<std::string> configVocabulary();

// Checks `text` as a value of the setting at `path`, as its config field would be checked: a
// number, true/false or a name as written on a command line ("auto" where the setting has an
// automatic value). The error reads "<source>: <path>: <what>" ("<path>: <what>" without source).
Result<void> checkBakeSetting(std::string_view path, std::string_view text,
                              std::string_view source = {});

// Checks and sets one setting. A per-volume setting ("volumes[].…") sets every volume of
// config.volumes.
Result<void> setBakeSetting(BakeConfig& config, std::string_view path, std::string_view text,
                            std::string_view source = {});

// Every setting within the values it admits and the structured ones consistent (bounds not
// inverted, resolutions powers of two, volume names distinct, ...): the checks parseBakeConfig
// makes, for a config built in code. Errors read "bake config: <path>: <what>".
Result<void> validateBakeConfig(const BakeConfig& config);

} // namespace probekit::baker
