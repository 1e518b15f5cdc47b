// What the CLI prints of text it does not control: volume and material names, metadata, error
// messages that quote a file's bytes, paths. A terminal acts on control characters (ESC starts
// sequences that can retitle the window, clear the screen or rewrite earlier lines), so every
// such string goes through one of these functions before it is printed.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

namespace probekit::cli {

// `text` with every byte a terminal could act on or mis-decode written as a visible \xNN escape
// (lower-case hex): C0 controls (0x00-0x1f, newline and tab included), DEL (0x7f), C1 controls
// (U+0080-U+009F, whose UTF-8 form is 0xc2 0x80-0x9f: both bytes are escaped) and every byte that
// is not part of a well-formed UTF-8 sequence. Everything else, other UTF-8 included, is kept.
std::string terminalText(std::string_view text);

// `j` as JSON text that is safe to print and still valid JSON for the same values: strings that
// are not valid UTF-8 get U+FFFD for each bad byte (nlohmann's error_handler replace, instead of
// its exception), control characters are \u escapes as JSON writes them, and DEL and the C1
// controls, which JSON allows raw, are \u escapes too. `indent` as nlohmann's dump (-1: one line).
std::string jsonText(const nlohmann::json& j, int indent = -1);

// Prints "probekit <command>: <message>" and a newline to stderr, the message through
// terminalText. Every error and warning the CLI prints goes through here.
void printError(std::string_view command, std::string_view message);

} // namespace probekit::cli
