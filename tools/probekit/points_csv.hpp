// The receiver points `probekit sample` reads: a CSV with the header x,y,z,nx,ny,nz and one
// point per row (world position in metres, world normal). Separate from the command so that a
// fuzz target can drive the parser alone.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/result.hpp"

namespace probekit::cli {

struct SamplePoint {
    glm::vec3 position{0.0f};
    glm::vec3 normal{0.0f, 1.0f, 0.0f}; // unit length
};

// Limits on a points file: its size and its point count. 2^24 points are far beyond a real
// receiver set, and with them the output CSV (up to about 150 bytes a row) stays near 2.5 GB.
constexpr uint64_t kMaxPointsFileBytes = uint64_t(1) << 30; // 1 GiB
constexpr size_t kMaxPoints = size_t(1) << 24;              // 16,777,216

// Parses a points CSV. Spaces and tabs around fields, CRLF line ends, blank lines, a UTF-8
// byte order mark and a leading '+' on numbers are accepted. Every failure is an Error whose
// message starts "<source>:<line>: " (or "<source>: " for an empty file) and says what was
// expected; the quoted text is the file's own (at most 80 bytes of it), so print it through
// terminalText. More than `max_points` rows is an error. Total: any bytes give points or an
// Error, never an exception.
Result<std::vector<SamplePoint>> parsePointsCsv(std::string_view text, std::string_view source,
                                                size_t max_points = kMaxPoints);

} // namespace probekit::cli
