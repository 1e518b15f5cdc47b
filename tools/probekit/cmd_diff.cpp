// `probekit diff`: the error of one .pvol against a reference .pvol with the same grids, with a
// metric and a tolerance, so CI and people use the same code path (runtime/compare.hpp).
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/runtime/compare.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {

void addDiffCommand(CLI::App& app, Command& selected) {
    struct Options {
        std::string test;
        std::string reference;
        std::string metric = "rel_rmse";
        double tolerance = -1.0;
    };
    auto o = std::make_shared<Options>();
    CLI::App* cmd = app.add_subcommand(
        "diff", "Irradiance error of FILE against REFERENCE (same grids): prints one JSON line; "
                "with --tolerance, exit 1 when the metric exceeds it");
    cmd->add_option("FILE", o->test, "the .pvol to judge")->required();
    cmd->add_option("REFERENCE", o->reference, "the reference .pvol")->required();
    cmd->add_option("--metric", o->metric,
                    "rel_rmse (all probes) or max_probe_err (worst probe, relative to the RMS "
                    "irradiance)")
        ->check(CLI::IsMember({"rel_rmse", "max_probe_err"}))
        ->capture_default_str();
    cmd->add_option("--tolerance", o->tolerance, "largest acceptable value of the metric")
        ->check(CLI::NonNegativeNumber);
    cmd->callback([o, &selected] {
        selected = [o] {
            Result<PvolFile> test = readPvol(o->test);
            if (!test) {
                printError("diff", test.error().message);
                return kExitFailure;
            }
            Result<PvolFile> ref = readPvol(o->reference);
            if (!ref) {
                printError("diff", ref.error().message);
                return kExitFailure;
            }
            Result<runtime::VolumeError> e =
                runtime::compareVolumes(test.value().volumes, ref.value().volumes);
            if (!e) {
                printError("diff", o->test + " vs " + o->reference + ": " + e.error().message);
                return kExitFailure;
            }
            const runtime::VolumeError& v = e.value();
            const double value = o->metric == "rel_rmse" ? v.relRmse : v.maxProbeErr;
            const bool pass = o->tolerance < 0.0 || value <= o->tolerance;
            nlohmann::json j = {
                {"rel_rmse", v.relRmse},         {"max_probe_err", v.maxProbeErr},
                {"max_abs_err", v.maxAbsErr},    {"probes_compared", v.probesCompared},
                {"worst_volume", v.worstVolume}, {"worst_probe", v.worstProbe},
                {"metric", o->metric},           {"value", value}};
            if (o->tolerance >= 0.0) {
                j["tolerance"] = o->tolerance;
                j["pass"] = pass;
            }
            std::printf("%s\n", jsonText(j).c_str());
            return pass ? kExitOk : kExitFailure;
        };
    });
}

} // namespace probekit::cli
