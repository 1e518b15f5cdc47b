// What `probekit info` prints for a .pvol, as a string: text for people or one JSON object.
// Separate from the command so that a fuzz target can drive decode, validate and formatting.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "probekit/formats/pvol.hpp"

namespace probekit::cli {

// Describes `file`, read from `source` (a path, printed as given) of `file_bytes` bytes. Text
// output passes every string from the file through terminalText; JSON output through jsonText
// (terminal_text.hpp), so neither prints raw control bytes, and bytes that are not UTF-8 are
// escaped (text) or replaced by U+FFFD (JSON) instead of aborting. Total: a volume that fails
// validateVolume gives its error, anything else gives the description, never an exception.
Result<std::string> formatInfo(const PvolFile& file, std::string_view source, uint64_t file_bytes,
                               bool json);

} // namespace probekit::cli
