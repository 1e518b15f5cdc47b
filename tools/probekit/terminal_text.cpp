#include "terminal_text.hpp"

#include <cstdint>
#include <cstdio>

#include <nlohmann/json.hpp>

namespace probekit::cli {
namespace {

void appendEscape(std::string& out, uint8_t byte) {
    constexpr char kHex[] = "0123456789abcdef";
    out += "\\x";
    out += kHex[byte >> 4];
    out += kHex[byte & 0xf];
}

bool isContinuation(uint8_t byte) {
    return (byte & 0xc0) == 0x80;
}

// Length of the well-formed UTF-8 sequence (RFC 3629: no overlong forms, no surrogates, nothing
// above U+10FFFF) that starts `text` at `at`, or 0 when there is none.
size_t sequenceLength(std::string_view text, size_t at) {
    const auto byte = [&](size_t k) { return uint8_t(text[at + k]); };
    const uint8_t lead = byte(0);
    const size_t left = text.size() - at;
    if (lead < 0x80) {
        return 1;
    }
    // The allowed range of the second byte, which is where overlong forms, surrogates and values
    // past U+10FFFF show.
    size_t length = 0;
    uint8_t low = 0x80, high = 0xbf;
    if (lead >= 0xc2 && lead <= 0xdf) {
        length = 2;
    } else if (lead >= 0xe0 && lead <= 0xef) {
        length = 3;
        low = lead == 0xe0 ? 0xa0 : 0x80;
        high = lead == 0xed ? 0x9f : 0xbf;
    } else if (lead >= 0xf0 && lead <= 0xf4) {
        length = 4;
        low = lead == 0xf0 ? 0x90 : 0x80;
        high = lead == 0xf4 ? 0x8f : 0xbf;
    } else {
        return 0;
    }
    if (left < length || byte(1) < low || byte(1) > high) {
        return 0;
    }
    for (size_t k = 2; k < length; ++k) {
        if (!isContinuation(byte(k))) {
            return 0;
        }
    }
    return length;
}

} // namespace

std::string terminalText(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    size_t at = 0;
    while (at < text.size()) {
        const uint8_t lead = uint8_t(text[at]);
        const size_t length = sequenceLength(text, at);
        if (length == 0 || lead < 0x20 || lead == 0x7f) {
            appendEscape(out, lead);
            ++at;
            continue;
        }
        if (length == 2 && lead == 0xc2 && uint8_t(text[at + 1]) <= 0x9f) { // C1 control
            appendEscape(out, lead);
            appendEscape(out, uint8_t(text[at + 1]));
            at += 2;
            continue;
        }
        out.append(text.substr(at, length));
        at += length;
    }
    return out;
}

std::string jsonText(const nlohmann::json& j, int indent) {
    const std::string dumped = j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
    // The dump is valid UTF-8 and DEL or a C1 control can only stand inside a string, where a
    // \u escape means the same character.
    std::string out;
    out.reserve(dumped.size());
    for (size_t at = 0; at < dumped.size(); ++at) {
        const uint8_t byte = uint8_t(dumped[at]);
        if (byte == 0x7f) {
            out += "\\u007f";
        } else if (byte == 0xc2 && at + 1 < dumped.size() && uint8_t(dumped[at + 1]) >= 0x80 &&
                   uint8_t(dumped[at + 1]) <= 0x9f) {
            char escape[8];
            std::snprintf(escape, sizeof escape, "\\u%04x", unsigned(uint8_t(dumped[at + 1])));
            out += escape;
            ++at;
        } else {
            out += char(byte);
        }
    }
    return out;
}

void printError(std::string_view command, std::string_view message) {
    const std::string line = "probekit " + std::string(command) + ": " + terminalText(message);
    std::fprintf(stderr, "%s\n", line.c_str());
}

} // namespace probekit::cli
