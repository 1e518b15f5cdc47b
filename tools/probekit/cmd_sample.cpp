// `probekit sample`: irradiance from a .pvol at a list of receiver points, through the CPU
// reference sampler (runtime/include/probekit/runtime/sampler.hpp), the same code the GPU path
// is tested against.
//
// Input CSV:  x,y,z,nx,ny,nz            (world position in metres, world normal)
// Output CSV: x,y,z,nx,ny,nz,r,g,b      (same rows, normal normalised, irradiance E in W/m^2,
//                                        not divided by pi; see formats/CONVENTIONS.md)
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/geometric.hpp>

#include "commands.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit::cli {
namespace {

constexpr std::array<std::string_view, 6> kInputColumns = {"x", "y", "z", "nx", "ny", "nz"};

struct SampleOptions {
    std::string file;
    std::string points;
    std::string output; // empty: stdout
};

struct SamplePoint {
    glm::vec3 position{0.0f};
    glm::vec3 normal{0.0f, 1.0f, 0.0f};
};

std::string_view trim(std::string_view text) {
    const size_t first = text.find_first_not_of(" \t");
    if (first == std::string_view::npos) {
        return {};
    }
    const size_t last = text.find_last_not_of(" \t");
    return text.substr(first, last - first + 1);
}

// Splits one line on commas, trimming spaces and tabs around each field.
std::vector<std::string_view> splitFields(std::string_view line) {
    std::vector<std::string_view> fields;
    size_t start = 0;
    while (true) {
        const size_t comma = line.find(',', start);
        fields.push_back(trim(line.substr(start, comma - start)));
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

// Parses the whole points file; on failure returns the message (naming file, line, column).
std::optional<std::string> parsePoints(const std::string& path, const std::string& text,
                                       std::vector<SamplePoint>& points) {
    std::string_view rest = text;
    // A UTF-8 byte order mark, as some spreadsheet exports write, is not part of the header.
    if (rest.starts_with("\xEF\xBB\xBF")) {
        rest.remove_prefix(3);
    }
    bool header_seen = false;
    size_t line_number = 0;
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
        const std::string where = path + ":" + std::to_string(line_number);
        const std::vector<std::string_view> fields = splitFields(line);
        if (!header_seen) {
            bool header_ok = fields.size() == kInputColumns.size();
            for (size_t i = 0; header_ok && i < fields.size(); ++i) {
                header_ok = fields[i] == kInputColumns[i];
            }
            if (!header_ok) {
                return where + ": expected the header \"x,y,z,nx,ny,nz\", found \"" +
                       std::string(line) + "\"";
            }
            header_seen = true;
            continue;
        }
        if (fields.size() != kInputColumns.size()) {
            return where + ": expected 6 fields (x,y,z,nx,ny,nz), found " +
                   std::to_string(fields.size());
        }
        std::array<float, 6> values{};
        for (size_t i = 0; i < fields.size(); ++i) {
            const std::optional<float> value = parseFloat(fields[i]);
            if (!value) {
                return where + ": column " + std::to_string(i + 1) + " (" +
                       std::string(kInputColumns[i]) + "): \"" + std::string(fields[i]) +
                       "\" is not a finite number";
            }
            values[i] = *value;
        }
        SamplePoint point;
        point.position = glm::vec3(values[0], values[1], values[2]);
        const glm::vec3 normal(values[3], values[4], values[5]);
        const float length = glm::length(normal);
        // The length can overflow to infinity for huge components; that is no direction either.
        if (!(length > 0.0f) || !std::isfinite(length)) {
            return where + ": the normal (" + std::string(fields[3]) + ", " +
                   std::string(fields[4]) + ", " + std::string(fields[5]) +
                   ") has no direction (zero length)";
        }
        point.normal = normal / length;
        points.push_back(point);
    }
    if (!header_seen) {
        return path + ": empty; expected the header \"x,y,z,nx,ny,nz\"";
    }
    return std::nullopt;
}

int runSample(const SampleOptions& o) {
    std::ifstream in(o.points, std::ios::binary);
    if (!in) {
        std::fprintf(stderr, "probekit sample: %s: cannot open the points file\n",
                     o.points.c_str());
        return kExitFailure;
    }
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (in.bad()) {
        std::fprintf(stderr, "probekit sample: %s: read failed\n", o.points.c_str());
        return kExitFailure;
    }
    std::vector<SamplePoint> points;
    if (std::optional<std::string> error = parsePoints(o.points, text, points)) {
        std::fprintf(stderr, "probekit sample: %s\n", error->c_str());
        return kExitFailure;
    }

    Result<runtime::VolumeSet> set = runtime::VolumeSet::load(o.file);
    if (!set) {
        std::fprintf(stderr, "probekit sample: %s\n", set.error().message.c_str());
        return kExitFailure;
    }
    if (set.value().empty()) {
        std::fprintf(stderr, "probekit sample: %s: the file holds no volumes to sample\n",
                     o.file.c_str());
        return kExitFailure;
    }

    std::string csv = "x,y,z,nx,ny,nz,r,g,b\n";
    csv.reserve(csv.size() + points.size() * 128);
    char row[512];
    for (const SamplePoint& p : points) {
        const glm::vec3 e = set.value().irradiance(p.position, p.normal);
        // %.9g round-trips every float.
        const int n = std::snprintf(
            row, sizeof row, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", p.position.x,
            p.position.y, p.position.z, p.normal.x, p.normal.y, p.normal.z, e.x, e.y, e.z);
        csv.append(row, size_t(n));
    }

    if (o.output.empty()) {
        if (std::fwrite(csv.data(), 1, csv.size(), stdout) != csv.size() ||
            std::fflush(stdout) != 0) {
            std::fprintf(stderr, "probekit sample: writing to stdout failed\n");
            return kExitFailure;
        }
        return kExitOk;
    }
    if (auto w = writeFileAtomic(o.output, csv); !w) {
        std::fprintf(stderr, "probekit sample: %s\n", w.error().message.c_str());
        return kExitFailure;
    }
    return kExitOk;
}

} // namespace

void addSampleCommand(CLI::App& app, Command& selected) {
    auto options = std::make_shared<SampleOptions>();
    CLI::App* cmd = app.add_subcommand(
        "sample", "Irradiance E (W/m^2, not divided by pi) of a .pvol at the points of a CSV, "
                  "through the CPU reference sampler");
    cmd->add_option("FILE", options->file, "the .pvol file")->required();
    cmd->add_option("--points", options->points,
                    "CSV with header x,y,z,nx,ny,nz: world positions (m) and normals")
        ->required();
    cmd->add_option("-o,--output", options->output,
                    "write the CSV (x,y,z,nx,ny,nz,r,g,b; normals normalised) here, atomically, "
                    "instead of to stdout");
    cmd->callback([options, &selected] { selected = [options] { return runSample(*options); }; });
}

} // namespace probekit::cli
