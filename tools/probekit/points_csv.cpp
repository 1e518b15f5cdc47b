#include "points_csv.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <exception>
#include <optional>
#include <string>

#include <glm/geometric.hpp>

namespace probekit::cli {
namespace {

constexpr std::array<std::string_view, 6> kInputColumns = {"x", "y", "z", "nx", "ny", "nz"};

// Quoted file text is cut to this many bytes, so one huge line cannot make a huge message.
constexpr size_t kMaxQuotedBytes = 80;

std::string quoted(std::string_view text) {
    // Appended piece by piece: GCC 12 misreports "\"" + std::string(...) under -Wrestrict.
    std::string out = "\"";
    out += text.substr(0, kMaxQuotedBytes);
    out += '"';
    if (text.size() > kMaxQuotedBytes) {
        out += "... (" + std::to_string(text.size()) + " bytes)";
    }
    return out;
}

std::string_view trim(std::string_view text) {
    const size_t first = text.find_first_not_of(" \t");
    if (first == std::string_view::npos) {
        return {};
    }
    const size_t last = text.find_last_not_of(" \t");
    return text.substr(first, last - first + 1);
}

// Splits one line on commas, trimming spaces and tabs around each field. Only the first six
// fields are kept (`count` says how many there were), so a line of a million commas allocates
// no more than a good one.
std::vector<std::string_view> splitFields(std::string_view line, size_t& count) {
    std::vector<std::string_view> fields;
    count = 0;
    size_t start = 0;
    while (true) {
        const size_t comma = line.find(',', start);
        if (fields.size() < kInputColumns.size()) {
            fields.push_back(trim(line.substr(start, comma - start)));
        }
        ++count;
        if (comma == std::string_view::npos) {
            return fields;
        }
        start = comma + 1;
    }
}

std::optional<float> parseFloat(std::string_view field) {
    // from_chars rejects a leading '+', which spreadsheets sometimes write.
    if (!field.empty() && field.front() == '+') {
        field.remove_prefix(1);
    }
    float value = 0.0f;
    const auto [end, error] = std::from_chars(field.data(), field.data() + field.size(), value);
    if (error != std::errc() || end != field.data() + field.size() || !std::isfinite(value)) {
        return std::nullopt;
    }
    return value;
}

Result<std::vector<SamplePoint>> parse(std::string_view text, const std::string& source,
                                       size_t max_points) {
    std::vector<SamplePoint> points;
    std::string_view rest = text;
    // A UTF-8 byte order mark, as some spreadsheet exports write, is not part of the header.
    if (rest.starts_with("\xEF\xBB\xBF")) {
        rest.remove_prefix(3);
    }
    bool header_seen = false;
    size_t line_number = 0;
    auto failure = [&](const std::string& what) {
        return makeError(ErrorCode::InvalidArgument,
                         source + ":" + std::to_string(line_number) + ": " + what);
    };
    while (!rest.empty()) {
        const size_t newline = rest.find('\n');
        std::string_view line = rest.substr(0, newline);
        rest = newline == std::string_view::npos ? std::string_view() : rest.substr(newline + 1);
        ++line_number;
        if (line.ends_with('\r')) {
            line.remove_suffix(1);
        }
        if (trim(line).empty()) {
            continue;
        }
        size_t field_count = 0;
        const std::vector<std::string_view> fields = splitFields(line, field_count);
        if (!header_seen) {
            bool header_ok = field_count == kInputColumns.size();
            for (size_t i = 0; header_ok && i < fields.size(); ++i) {
                header_ok = fields[i] == kInputColumns[i];
            }
            if (!header_ok) {
                return failure("expected the header \"x,y,z,nx,ny,nz\", found " + quoted(line));
            }
            header_seen = true;
            continue;
        }
        if (field_count != kInputColumns.size()) {
            return failure("expected 6 fields (x,y,z,nx,ny,nz), found " +
                           std::to_string(field_count));
        }
        if (points.size() == max_points) {
            return failure("more than " + std::to_string(max_points) +
                           " points, the most one file may hold");
        }
        std::array<float, 6> values{};
        for (size_t i = 0; i < fields.size(); ++i) {
            const std::optional<float> value = parseFloat(fields[i]);
            if (!value) {
                return failure("column " + std::to_string(i + 1) + " (" +
                               std::string(kInputColumns[i]) + "): " + quoted(fields[i]) +
                               " is not a finite number");
            }
            values[i] = *value;
        }
        SamplePoint point;
        point.position = glm::vec3(values[0], values[1], values[2]);
        const glm::vec3 normal(values[3], values[4], values[5]);
        const float length = glm::length(normal);
        // The length can overflow to infinity for huge components; that is no direction either.
        if (!(length > 0.0f) || !std::isfinite(length)) {
            return failure("the normal (" + std::string(fields[3]) + ", " + std::string(fields[4]) +
                           ", " + std::string(fields[5]) + ") has no direction (zero length)");
        }
        point.normal = normal / length;
        points.push_back(point);
    }
    if (!header_seen) {
        return makeError(ErrorCode::InvalidArgument,
                         source + ": empty; expected the header \"x,y,z,nx,ny,nz\"");
    }
    return points;
}

} // namespace

Result<std::vector<SamplePoint>> parsePointsCsv(std::string_view text, std::string_view source,
                                                size_t max_points) {
    try {
        return parse(text, std::string(source), max_points);
    } catch (const std::exception& e) { // only allocation can throw here
        return makeError(ErrorCode::InvalidArgument,
                         std::string(source) + ": cannot parse the points: " + e.what());
    }
}

} // namespace probekit::cli
