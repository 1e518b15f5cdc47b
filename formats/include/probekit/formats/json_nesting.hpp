// How deeply JSON text nests, measured without parsing it, and the limit every reader of
// untrusted JSON in probekit holds text to (ARCHITECTURE.md, "Rules that hold everywhere").
//
// nlohmann-json parses iteratively, but much of what is done with a parsed value recurses once
// per level: dump(), comparison, copying into a bake config, tinygltf's conversion to its Value.
// A few tens of thousands of levels overflow a thread's stack, and dump() with an indent writes
// indent x depth spaces per line, so a 100 KB file prints gigabytes. Readers therefore refuse
// text nested deeper than a limit before anything walks it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "probekit/formats/result.hpp"

namespace probekit {

// The deepest nesting of JSON arrays and objects accepted in metadata, configs and the CLI's
// JSON: probekit's own settings nest 4 levels (volumes[i].bounds.min), a hand-written config a
// few more. 64 levels leave room for any config a person writes, and at a few hundred bytes of
// stack per level in the recursive code above, cost some tens of KiB of stack: far below any
// thread's. (glTF, with free-form extras, has its own larger limit, gltf_input.hpp.)
constexpr size_t kMaxJsonDepth = 64;

// What a scan of JSON text found: the deepest nesting of arrays and objects, the byte offset at
// which nesting first went deeper than the limit the scan was given (when it did), and the
// number of values (an upper bound: each string, array, object and comma counts one).
struct JsonNesting {
    size_t deepest = 0;
    uint64_t firstTooDeep = 0; // byte offset of the first '[' or '{' past the limit
    uint64_t values = 0;
};

// Scans `text` for brackets outside strings (a string's escapes are skipped), without parsing
// it: text that is not JSON gets a depth all the same, and a parser refuses it afterwards.
// Linear time, constant stack.
JsonNesting scanJsonNesting(std::string_view text, size_t limit);

// Fails when `text` nests deeper than kMaxJsonDepth: "<source>: JSON arrays and objects nest N
// levels deep (level 65 opens at byte B), more than the limit of 64" (OutOfRange).
Result<void> checkJsonNesting(std::string_view text, std::string_view source);

// The one parse of untrusted JSON text outside the glTF loader (configs, the settings a .pvol
// records, command-line values): checkJsonNesting, then Json::parse. `Json` is
// nlohmann::json; a template so that formats itself stays free of nlohmann-json (its users in
// baker, viewer and tools include it). Errors name `source`: the nesting error above, or
// "<source>: not valid JSON: <parser's message>" (InvalidArgument).
template <class Json>
Result<Json> parseJsonText(std::string_view text, std::string_view source) {
    if (Result<void> nesting = checkJsonNesting(text, source); !nesting) {
        return nesting.error();
    }
    try {
        return Json::parse(text);
    } catch (const typename Json::exception& e) {
        // parse_error for syntax, out_of_range for a number beyond the double range (1e309).
        return makeError(ErrorCode::InvalidArgument,
                         std::string(source) + ": not valid JSON: " + e.what());
    }
}

} // namespace probekit
