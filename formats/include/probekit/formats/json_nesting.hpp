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
#include <set>
#include <string>
#include <string_view>
#include <vector>

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

namespace detail {

// Watches the events of one parse for a key given twice in the same object. nlohmann keeps the
// last of two equal keys without a word, while configs treat an unknown key as an error: a key
// written twice (the second perhaps by a merge tool) would silently change a bake. One frame per
// open array or object, so the path of the first repeated key can be named:
// "volumes[1].bounds.min".
template <class Json>
class DuplicateKeyFinder {
public:
    // The parser callback: records, never refuses, so the parse itself runs to its end and a
    // syntax error later in the text is still reported as such.
    bool operator()(int /*depth*/, typename Json::parse_event_t event, Json& parsed) {
        using Event = typename Json::parse_event_t;
        switch (event) {
        case Event::object_start:
        case Event::array_start:
            frames_.push_back(Frame{event == Event::object_start, {}, {}, 0});
            break;
        case Event::object_end:
        case Event::array_end:
            if (!frames_.empty()) {
                frames_.pop_back();
            }
            countElement();
            break;
        case Event::key:
            onKey(parsed);
            break;
        case Event::value:
            countElement();
            break;
        }
        return true;
    }

    // Empty when no key was repeated; otherwise the path of the first one.
    const std::string& firstRepeated() const { return repeated_; }

private:
    struct Frame {
        bool object = false;
        std::set<std::string> keys;
        std::string key;     // objects: the key whose value is being read
        size_t elements = 0; // arrays: elements read so far, the index of the next
    };

    void countElement() {
        if (!frames_.empty() && !frames_.back().object) {
            ++frames_.back().elements;
        }
    }

    void onKey(const Json& parsed) {
        if (frames_.empty() || !parsed.is_string()) {
            return;
        }
        Frame& top = frames_.back();
        top.key = parsed.template get<std::string>();
        if (!top.keys.insert(top.key).second && repeated_.empty()) {
            repeated_ = path();
        }
    }

    // The path of the key now being read, from the outermost frame inwards.
    std::string path() const {
        std::string p;
        for (const Frame& f : frames_) {
            if (f.object) {
                if (!p.empty()) {
                    p += '.';
                }
                p += f.key;
            } else {
                p += '[';
                p += std::to_string(f.elements);
                p += ']';
            }
        }
        return p;
    }

    std::vector<Frame> frames_;
    std::string repeated_;
};

} // namespace detail

// The one parse of untrusted JSON text outside the glTF loader (configs, the settings a .pvol
// records, command-line values): checkJsonNesting, then Json::parse. `Json` is
// nlohmann::json; a template so that formats itself stays free of nlohmann-json (its users in
// baker, viewer and tools include it). Errors name `source`: the nesting error above,
// "<source>: not valid JSON: <parser's message>" (InvalidArgument), or, for an object that
// gives a key twice (nlohmann would keep the last silently), "<source>: volumes[0].name: given
// twice" (InvalidArgument).
template <class Json>
Result<Json> parseJsonText(std::string_view text, std::string_view source) {
    if (Result<void> nesting = checkJsonNesting(text, source); !nesting) {
        return nesting.error();
    }
    detail::DuplicateKeyFinder<Json> duplicates;
    Json parsed;
    try {
        parsed = Json::parse(
            text, [&duplicates](int depth, typename Json::parse_event_t event, Json& value) {
                return duplicates(depth, event, value);
            });
    } catch (const typename Json::exception& e) {
        // parse_error for syntax, out_of_range for a number beyond the double range (1e309).
        return makeError(ErrorCode::InvalidArgument,
                         std::string(source) + ": not valid JSON: " + e.what());
    }
    if (!duplicates.firstRepeated().empty()) {
        return makeError(ErrorCode::InvalidArgument,
                         std::string(source) + ": " + duplicates.firstRepeated() + ": given twice");
    }
    return parsed;
}

} // namespace probekit
