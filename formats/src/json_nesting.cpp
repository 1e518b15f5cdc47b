// JSON nesting measured without parsing (formats/include/probekit/formats/json_nesting.hpp).
#include "probekit/formats/json_nesting.hpp"

#include <string>

namespace probekit {

JsonNesting scanJsonNesting(std::string_view text, size_t limit) {
    JsonNesting out;
    size_t depth = 0;
    bool in_string = false;
    for (size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (in_string) {
            if (c == '\\') {
                ++i; // the escaped character cannot end the string
            } else if (c == '"') {
                in_string = false;
            }
            continue;
        }
        switch (c) {
        case '"':
            in_string = true;
            ++out.values;
            break;
        case '[':
        case '{':
            ++out.values;
            if (++depth > out.deepest) {
                out.deepest = depth;
                if (depth == limit + 1) {
                    out.firstTooDeep = i;
                }
            }
            break;
        case ']':
        case '}':
            depth -= depth > 0 ? 1 : 0;
            break;
        case ',':
            ++out.values;
            break;
        default:
            break;
        }
    }
    return out;
}

Result<void> checkJsonNesting(std::string_view text, std::string_view source) {
    const JsonNesting nesting = scanJsonNesting(text, kMaxJsonDepth);
    if (nesting.deepest <= kMaxJsonDepth) {
        return {};
    }
    return makeError(ErrorCode::OutOfRange,
                     std::string(source) + ": JSON arrays and objects nest " +
                         std::to_string(nesting.deepest) + " levels deep (level " +
                         std::to_string(kMaxJsonDepth + 1) + " opens at byte " +
                         std::to_string(nesting.firstTooDeep) + "), more than the limit of " +
                         std::to_string(kMaxJsonDepth));
}

} // namespace probekit
