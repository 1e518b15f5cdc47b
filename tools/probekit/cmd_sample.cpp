// `probekit sample`: irradiance from a .pvol at a list of receiver points, through the CPU
// reference sampler (runtime/include/probekit/runtime/sampler.hpp), the same code the GPU path
// is tested against.
//
// Input CSV:  x,y,z,nx,ny,nz            (world position in metres, world normal)
// Output CSV: x,y,z,nx,ny,nz,r,g,b      (same rows, normal normalised, irradiance E in W/m^2,
//                                        not divided by pi; see formats/CONVENTIONS.md)
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "points_csv.hpp"
#include "probekit/formats/file_io.hpp"
#include "probekit/runtime/sampler.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

struct SampleOptions {
    std::string file;
    std::string points;
    std::string output; // empty: stdout
};

int fail(const std::string& message) {
    printError("sample", message);
    return kExitFailure;
}

int runSample(const SampleOptions& o) {
    // A bad -o fails before any work, and never names an input.
    if (!o.output.empty()) {
        const NamedPath outputs[] = {{o.output, "-o"}};
        const NamedPath inputs[] = {{o.file, "the volume"}, {o.points, "the points file"}};
        if (Result<void> checked = checkOutputs(outputs, inputs); !checked) {
            return fail(checked.error().message);
        }
    }
    Result<std::string> text = readRegularFile(o.points, kMaxPointsFileBytes, "points file");
    if (!text) {
        return fail(text.error().message);
    }
    Result<std::vector<SamplePoint>> parsed = parsePointsCsv(text.value(), o.points);
    if (!parsed) {
        return fail(parsed.error().message);
    }
    const std::vector<SamplePoint>& points = parsed.value();

    Result<runtime::VolumeSet> set = runtime::VolumeSet::load(o.file);
    if (!set) {
        return fail(set.error().message);
    }
    if (set.value().empty()) {
        return fail(o.file + ": the file holds no volumes to sample");
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
            return fail("writing to stdout failed");
        }
        return kExitOk;
    }
    if (auto w = writeFileAtomic(o.output, csv); !w) {
        return fail(w.error().message);
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
                    "CSV with header x,y,z,nx,ny,nz: world positions (m) and normals (a regular "
                    "file of at most 1 GiB and 16,777,216 points)")
        ->required();
    cmd->add_option("-o,--output", options->output,
                    "write the CSV (x,y,z,nx,ny,nz,r,g,b; normals normalised) here, atomically, "
                    "instead of to stdout");
    cmd->callback([options, &selected] { selected = [options] { return runSample(*options); }; });
}

} // namespace probekit::cli
