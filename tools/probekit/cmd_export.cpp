// `probekit export FILE.pvol --format three|bevy -o OUT`: a baked volume in the files an engine
// reads (docs/engines.md). One volume per output: the file's only volume, or the one --volume
// names.
#include <cstdio>
#include <memory>
#include <string>

#include "commands.hpp"
#include "probekit/exporters/bevy.hpp"
#include "probekit/exporters/three.hpp"
#include "probekit/formats/pvol.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

struct ExportOptions {
    std::string input;
    std::string format;
    std::string output;
    std::string volume;
    std::vector<unsigned> resolution;
    bool float32 = false;
    bool quiet = false;
};

// The volume --volume names (by name or index), or the file's only one.
Result<const Volume*> chooseVolume(const PvolFile& file, const ExportOptions& o) {
    const auto& vs = file.volumes;
    if (o.volume.empty()) {
        if (vs.size() == 1)
            return &vs[0];
        return Error{ErrorCode::InvalidArgument,
                     o.input + " holds " + std::to_string(vs.size()) +
                         " volumes; name one with --volume NAME or --volume INDEX"};
    }
    for (const Volume& v : vs)
        if (v.desc.name == o.volume)
            return &v;
    if (o.volume.find_first_not_of("0123456789") == std::string::npos && o.volume.size() < 9) {
        const size_t i = std::stoul(o.volume);
        if (i < vs.size())
            return &vs[i];
    }
    return Error{ErrorCode::InvalidArgument,
                 o.input + ": no volume named '" + o.volume + "' (and no such index)"};
}

Result<exporters::ExportResult> runExporter(const Volume& v, const ExportOptions& o) {
    glm::uvec3 res(0);
    if (!o.resolution.empty())
        res = glm::uvec3(o.resolution[0], o.resolution[1], o.resolution[2]);
    if (o.format == "three")
        return exporters::exportThree(v, {res, !o.float32}, o.output);
    return exporters::exportBevy(v, {res}, o.output);
}

int runExport(const ExportOptions& o) {
    const NamedPath outputs[] = {{o.output, "-o"}};
    const NamedPath inputs[] = {{o.input, "the volume"}};
    if (Result<void> checked = checkOutputs(outputs, inputs); !checked) {
        printError("export", checked.error().message);
        return kExitFailure;
    }
    Result<PvolFile> file = readPvol(o.input);
    if (!file) {
        printError("export", file.error().message);
        return kExitFailure;
    }
    Result<const Volume*> volume = chooseVolume(file.value(), o);
    if (!volume) {
        printError("export", volume.error().message);
        return kExitFailure;
    }
    Result<exporters::ExportResult> result = runExporter(*volume.value(), o);
    if (!result) {
        printError("export", o.input + ": " + result.error().message);
        return kExitFailure;
    }
    for (const exporters::OutputFile& f : result.value().files) {
        if (Result<void> w = writeFileAtomic(f.path, f.bytes); !w) {
            printError("export", w.error().message);
            return kExitFailure;
        }
        if (!o.quiet)
            std::printf("wrote %s\n", terminalText(f.path.string()).c_str());
    }
    if (!o.quiet)
        for (const std::string& line : result.value().notes)
            std::printf("%s\n", terminalText(line).c_str());
    return kExitOk;
}

} // namespace

void addExportCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<ExportOptions>();
    CLI::App* cmd = app.add_subcommand(
        "export", "Convert a volume of FILE.pvol for an engine: three.js's LightProbeGrid "
                  "(OUT.json + OUT.bin) or Bevy's irradiance volume (OUT.ktx2)");
    cmd->add_option("FILE", o->input, "the .pvol to convert")->required();
    cmd->add_option("--format", o->format, "three or bevy")
        ->required()
        ->check(CLI::IsMember({"three", "bevy"}));
    cmd->add_option("-o,--output", o->output,
                    "output file (three: OUT.json, its atlas OUT.bin "
                    "beside it; bevy: OUT.ktx2)")
        ->required();
    cmd->add_option("--volume", o->volume,
                    "the volume to convert, by name or index (required "
                    "when the file holds several)");
    cmd->add_option("--resolution", o->resolution,
                    "X,Y,Z: the dense grid a bricked or rotated volume is resampled to (powers "
                    "of two; default: the finest bricks' spacing, at most 64 per axis)")
        ->expected(3)
        ->delimiter(',');
    cmd->add_flag("--float", o->float32, "three: float32 atlas texels (default: half)");
    cmd->add_flag("-q,--quiet", o->quiet, "print nothing but errors");
    cmd->callback([o, &selected] { selected = [o] { return runExport(*o); }; });
}

} // namespace probekit::cli
