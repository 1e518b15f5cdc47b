// `probekit bake`, `probekit scene` and `probekit bench-rays`.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "config_options.hpp"
#include "distributed.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/bench_rays.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/baker/scene_summary.hpp"
#include "probekit/baker/settings.hpp"
#include "probekit/baker/target.hpp"
#include "probekit/runtime/sampler.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

struct BakeOptionsCli {
    std::string scene;
    std::string output;
    std::string config;
    // Flags that set a bake setting (settings.hpp), by config path: applied over the config
    // file in the settings table's order.
    std::map<std::string, std::string> settings;
    std::optional<std::string> samples; // the per-probe directions of the chosen method
    std::vector<uint32_t> resolution;
    std::optional<std::string> env;
    bool noVisibility = false;
    bool allowUnlit = false;
    uint32_t threads = 0;
    std::optional<int> sceneIndex;
    std::vector<std::string> assetRoots; // --asset-root
    std::string report;
    bool quiet = false;
    bool verify = false;
    uint32_t verifyPoints = 256;
    uint32_t verifySamples = 4096;
};

int fail(const Error& e, const char* what = "") {
    printError("bake", what + e.message);
    return kExitFailure;
}

// --verify: the baked file's irradiance at points spread over its volumes against a path
// reference made of two independent estimates (their difference measures the reference's own
// noise, which is subtracted).
Result<baker::ErrorEstimate> verifyBake(const baker::Scene& scene, const baker::BakeConfig& config,
                                        const PvolFile& file, const BakeOptionsCli& o,
                                        double& seconds) {
    const auto start = std::chrono::steady_clock::now();
    std::vector<VolumeDesc> descs;
    for (const Volume& v : file.volumes) {
        descs.push_back(v.desc);
    }
    const std::vector<glm::vec3> points = baker::volumeSamplePoints(descs, o.verifyPoints);
    Result<baker::PointBake> a =
        baker::bakePoints(scene, config, points, o.verifySamples, 1, o.threads);
    if (!a) {
        return a.error();
    }
    Result<baker::PointBake> b =
        baker::bakePoints(scene, config, points, o.verifySamples, 2, o.threads);
    if (!b) {
        return b.error();
    }
    const runtime::VolumeSet set(file.volumes);
    baker::ErrorEstimate e =
        baker::estimateError([&](glm::vec3 p, glm::vec3 n) { return set.irradiance(p, n); }, points,
                             a.value(), b.value());
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return e;
}

// --env takes either "R,G,B" (constant radiance) or an image file.
Result<baker::EnvironmentConfig> parseEnvFlag(const std::string& value) {
    baker::EnvironmentConfig e;
    float rgb[3];
    char tail;
    if (std::sscanf(value.c_str(), "%f,%f,%f%c", &rgb[0], &rgb[1], &rgb[2], &tail) == 3) {
        e.type = baker::EnvironmentConfig::Type::Constant;
        e.radiance = glm::vec3(rgb[0], rgb[1], rgb[2]);
        if (!std::isfinite(rgb[0]) || !std::isfinite(rgb[1]) || !std::isfinite(rgb[2])) {
            return makeError(ErrorCode::OutOfRange,
                             "--env: radiance must be finite (got \"" + value + "\")");
        }
        if (e.radiance.x < 0 || e.radiance.y < 0 || e.radiance.z < 0) {
            return makeError(ErrorCode::OutOfRange, "--env: radiance must be >= 0");
        }
        return e;
    }
    // Digits, signs, points and commas only: meant as R,G,B, not as a file name.
    if (value.find_first_not_of("0123456789.,+-eE ") == std::string::npos &&
        value.find_first_of("0123456789") != std::string::npos) {
        return makeError(ErrorCode::InvalidArgument,
                         "--env: expected R,G,B (three numbers) or an image file (got \"" + value +
                             "\")");
    }
    e.type = baker::EnvironmentConfig::Type::LatLong;
    e.file = value;
    return e;
}

// The fraction done and the seconds left at the rate so far (p.probesTotal covers the whole
// bake: BakeProgress).
std::pair<double, double> progressFraction(const baker::BakeProgress& p) {
    const double fraction = p.probesTotal ? double(p.probesDone) / double(p.probesTotal) : 1.0;
    const double eta = fraction > 0 ? p.elapsedSeconds * (1.0 - fraction) / fraction : 0.0;
    return {fraction, eta};
}

// On a terminal: one line redrawn in place.
void printProgress(const baker::BakeProgress& p) {
    const auto [fraction, eta] = progressFraction(p);
    const int width = 30;
    const int filled = int(fraction * width);
    std::fprintf(stderr, "\r  [%.*s%*s] %5.1f%%  %llu/%llu probes  %.1f s, ETA %.1f s ", filled,
                 "==============================", width - filled, "", fraction * 100.0,
                 static_cast<unsigned long long>(p.probesDone),
                 static_cast<unsigned long long>(p.probesTotal), p.elapsedSeconds, eta);
    std::fflush(stderr);
}

// When stderr is not a terminal (a log file, CI, a batch farm): whole lines, one each time a
// further tenth of the work is done or kLogProgressSeconds have passed since the last line,
// whichever comes first: at most about ten lines for the work plus one per interval.
constexpr double kLogProgressSeconds = 10.0;

// --verify warns when fewer points than this carry the reference (ErrorEstimate).
constexpr double kFewEffectivePoints = 10.0;

std::function<void(const baker::BakeProgress&)> logProgress() {
    return [last_fraction = 0.0, last_seconds = 0.0](const baker::BakeProgress& p) mutable {
        const auto [fraction, eta] = progressFraction(p);
        // The total grows as refinement queues probes: the tenths count from the new fraction.
        last_fraction = std::min(last_fraction, fraction);
        const bool end = p.probesDone >= p.probesTotal && fraction > last_fraction;
        if (!end && fraction < last_fraction + 0.1 &&
            p.elapsedSeconds < last_seconds + kLogProgressSeconds) {
            return;
        }
        last_fraction = fraction;
        last_seconds = p.elapsedSeconds;
        std::fprintf(stderr, "  progress: %.1f%%  %llu/%llu probes  %.1f s, ETA %.1f s\n",
                     fraction * 100.0, static_cast<unsigned long long>(p.probesDone),
                     static_cast<unsigned long long>(p.probesTotal), p.elapsedSeconds, eta);
        std::fflush(stderr);
    };
}

// The config file (or the defaults) with the flags applied over it.
Result<baker::BakeConfig> configFromOptions(const BakeOptionsCli& o) {
    Result<baker::BakeConfig> loaded = loadConfigOrDefaults(o.config);
    if (!loaded) {
        return loaded;
    }
    baker::BakeConfig config = std::move(loaded).value();
    for (const baker::SettingInfo& s : baker::bakeSettings()) {
        if (auto it = o.settings.find(s.path); it != o.settings.end()) {
            if (auto set = baker::setBakeSetting(config, s.path, it->second, s.flag); !set) {
                return set.error();
            }
        }
    }
    if (o.samples) {
        // For vpl and lpv the only per-probe directions are those of the direct light.
        const char* path = config.method == baker::Method::Vpl   ? "vpl.direct_samples"
                           : config.method == baker::Method::Lpv ? "lpv.direct_samples"
                                                                 : "path.samples";
        if (auto set = baker::setBakeSetting(config, path, *o.samples, "--samples"); !set) {
            return set.error();
        }
    }
    if (o.noVisibility) {
        config.visibility = false;
    }
    if (o.env) {
        Result<baker::EnvironmentConfig> env = parseEnvFlag(*o.env);
        if (!env) {
            return env.error();
        }
        config.environment = env.value();
    }
    for (baker::VolumeConfig& v : config.volumes) {
        if (!o.resolution.empty()) {
            v.resolution = glm::uvec3(o.resolution[0], o.resolution[1], o.resolution[2]);
        }
        if (o.settings.count("volumes[].density")) {
            v.resolution.reset(); // --density overrides a resolution from the config file
        }
    }
    return config;
}

// Prints each of `warnings` that is not among `already` (printed before).
void printNewWarnings(const std::vector<std::string>& warnings,
                      const std::vector<std::string>& already) {
    for (const std::string& w : warnings) {
        if (std::find(already.begin(), already.end(), w) == already.end()) {
            printError("bake", "warning: " + w);
        }
    }
}

// The loader's warnings are printed unless -q (they are in --report's warnings either way).
Result<baker::Scene> loadScene(const BakeOptionsCli& o, const baker::BakeConfig& config) {
    baker::LoadOptions load_options;
    load_options.sceneIndex = o.sceneIndex;
    load_options.scale = config.scale;
    load_options.maxMemoryBytes = config.maxMemoryBytes;
    load_options.assetRoots.assign(o.assetRoots.begin(), o.assetRoots.end());
    Result<baker::Scene> scene = baker::loadGltf(o.scene, load_options);
    if (!scene) {
        return scene;
    }
    // Said where the map was named: the flag, or the config file and its field.
    Result<baker::Environment> environment = configEnvironment(config, o.config, o.env.has_value());
    if (!environment) {
        return environment.error();
    }
    scene.value().environment = std::move(environment).value();
    if (!o.quiet) {
        printNewWarnings(scene.value().warnings, {});
    }
    return scene;
}

// The bake's outputs (-o, --report) checked against each other and every file it reads: the
// config, the environment map and, once loaded, the scene's own files (file_io.hpp,
// checkOutputs).
Result<void> checkBakeOutputs(const BakeOptionsCli& o, const baker::BakeConfig* config,
                              const baker::Scene* scene) {
    std::vector<NamedPath> outputs = {{o.output, "-o"}};
    if (!o.report.empty()) {
        outputs.push_back({o.report, "--report"});
    }
    std::vector<NamedPath> inputs = {{o.scene, "the scene"}};
    if (!o.config.empty()) {
        inputs.push_back({o.config, "the config"});
    }
    if (config && !config->environment.file.empty()) {
        inputs.push_back({config->environment.file, "the environment map"});
    }
    if (scene) {
        for (const std::filesystem::path& file : scene->files) {
            inputs.push_back({file, "a file of the scene"});
        }
    }
    return checkOutputs(outputs, inputs);
}

void printChoice(const baker::TargetChoice& c) {
    std::printf("target error %.3g (relative RMS irradiance error against a path reference)\n"
                "  pilot: %u points x 2 estimates x %u directions, %.2f s: noise %.3g per "
                "probe, SH band 2 carries %.3g\n"
                "  chosen: SH order L%d (%s), %u directions per probe uniformly (interpolated "
                "noise %.3g), bricked volumes, levels 0..%u, refine_error %.3g\n",
                c.target, c.pilotPoints, c.pilotSamples, c.pilotSeconds, c.pilotNoise, c.band2,
                int(c.shOrder),
                c.shOrder == sh::Order::L1 ? "band 2 < 0.4 x target" : "band 2 needed", c.samples,
                c.predictedNoise, brick::kMaxLevel, c.interpolationBudget);
    if (c.samplesWanted != double(c.samples)) {
        std::printf("  the noise budget asked %.0f directions per probe; %s %u is used\n",
                    c.samplesWanted,
                    c.samples == baker::kTargetMinSamples ? "the floor" : "the cap", c.samples);
    }
    std::printf("  adaptive sampling: each probe traced to noise %.3g of its irradiance (of %.3g "
                "W/m^2, the pilot's RMS, where darker), %u to %u directions\n",
                c.probeNoiseTarget, c.noiseFloor, c.minSamples, baker::kTargetMaxSamples);
    if (c.config.method == baker::Method::Path) {
        std::printf("  plan: level 0 has %llu probes at about %.0f directions each, about %.0f s "
                    "at the pilot's speed; refinement adds finer probes where the light changes, "
                    "within max_memory_mb = %llu MiB\n",
                    static_cast<unsigned long long>(c.levelZeroProbes), c.expectedDirections,
                    c.levelZeroSeconds,
                    static_cast<unsigned long long>(c.config.maxMemoryBytes >> 20));
    }
}

void printMethod(const BakeOptionsCli& o, const baker::Scene& scene,
                 const baker::BakeConfig& config, const std::vector<VolumeDesc>& placed) {
    const auto seed = static_cast<unsigned long long>(config.seed);
    if (config.method == baker::Method::Vpl) {
        const baker::VplConfig v = baker::resolveVplConfig(scene, placed, config);
        std::printf("baking %s: method vpl, seed %llu\n"
                    "  direct light: %u directions per probe (vpl.direct_samples)\n"
                    "  %u VPLs%s, %u bounces, %s sampling, clamp %s (%.4f m%s), near field "
                    "%.4f m%s, shadows %s, cut error %g\n",
                    o.scene.c_str(), seed, v.directSamples, *v.count,
                    config.vpl.count ? " requested"
                                     : " requested (auto: 4 x surface area / probe spacing^2, "
                                       "power of two in 16384..65536)",
                    v.bounces, std::string(baker::toString(v.sampling)).c_str(),
                    std::string(baker::toString(v.clamp)).c_str(), *v.clampDistance,
                    config.vpl.clampDistance ? "" : ", auto: 2 sqrt(area / (pi count))",
                    *v.nearField, config.vpl.nearField ? "" : " (auto: 2 x clamp distance)",
                    v.shadows ? "on" : "off", double(v.cutError));
    } else if (config.method == baker::Method::Lpv) {
        const baker::LpvConfig& l = config.lpv;
        const std::string direct = l.direct == baker::LpvDirect::Traced
                                       ? "traced, " + std::to_string(l.directSamples) +
                                             " directions per probe (lpv.direct_samples)"
                                       : "propagated through the grids";
        std::printf("baking %s: method lpv, seed %llu\n"
                    "  direct light: %s\n"
                    "  %u VPLs requested, %u cascade(s) of %u cells on the longest axis "
                    "(ratio %g), %u iterations%s, occlusion %s, propagation weight %g, fade %g "
                    "cells, intensity %g\n",
                    o.scene.c_str(), seed, direct.c_str(), l.vplCount, l.cascades, l.grid,
                    double(l.cascadeRatio), l.iterations ? *l.iterations : l.grid,
                    l.iterations ? "" : " (auto: = grid)", l.occlusion ? "on" : "off",
                    double(l.propagationWeight), double(l.fadeCells), double(l.intensity));
    } else if (config.path.noiseTarget > 0.0f) {
        std::printf("baking %s: method path, adaptive sampling to noise %g (%u to %u directions "
                    "per probe), %u bounces, seed %llu\n",
                    o.scene.c_str(), double(config.path.noiseTarget), config.path.samples,
                    std::max(config.path.samples, config.path.maxSamples), config.path.maxBounces,
                    seed);
    } else {
        std::printf("baking %s: method path, %u samples, %u bounces, seed %llu\n", o.scene.c_str(),
                    config.path.samples, config.path.maxBounces, seed);
    }
}

void printVolumes(const std::vector<VolumeDesc>& placed) {
    for (const VolumeDesc& d : placed) {
        const glm::uvec3 r = d.grid.resolution();
        const glm::vec3 lo = d.grid.bounds().min;
        const glm::vec3 hi = d.grid.bounds().max;
        if (d.layout == VolumeLayout::Bricked) {
            std::printf("  volume '%s': bricked, %ux%ux%u level-0 bricks, levels 0..%u, L%d, "
                        "%s, bounds (%.3f, %.3f, %.3f) .. (%.3f, %.3f, %.3f) m\n",
                        terminalText(d.name).c_str(), r.x, r.y, r.z, d.bricks.maxLevel,
                        int(d.shOrder), std::string(toString(d.storage)).c_str(), lo.x, lo.y, lo.z,
                        hi.x, hi.y, hi.z);
            continue;
        }
        std::printf("  volume '%s': %ux%ux%u %s probes, L%d, %s, bounds (%.3f, %.3f, %.3f) "
                    ".. (%.3f, %.3f, %.3f) m\n",
                    terminalText(d.name).c_str(), r.x, r.y, r.z,
                    std::string(grid::toString(d.grid.mode())).c_str(), int(d.shOrder),
                    std::string(toString(d.storage)).c_str(), lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
    }
}

uint64_t gpuBytes(const PvolFile& file) {
    uint64_t bytes = 0;
    for (const Volume& v : file.volumes) {
        bytes += v.gpuBytes();
    }
    return bytes;
}

bool anyBricked(const PvolFile& file) {
    for (const Volume& v : file.volumes) {
        if (v.desc.layout == VolumeLayout::Bricked) {
            return true;
        }
    }
    return false;
}

// The VPLs a bake asked for: the resolved vpl.count its metadata records (an automatic count is
// chosen before the bake), or lpv.vpl_count. The light paths place about that many, not exactly
// (BakeStats::vpls has the count placed).
uint64_t requestedVpls(const baker::BakeConfig& config, const baker::BakeResult& result) {
    if (config.method == baker::Method::Lpv) {
        return config.lpv.vplCount;
    }
    const nlohmann::json settings =
        nlohmann::json::parse(result.file.metadata.parametersJson, nullptr, false);
    const nlohmann::json::json_pointer count("/vpl/count");
    return settings.contains(count) && settings.at(count).is_number_unsigned()
               ? settings.at(count).get<uint64_t>()
               : 0;
}

nlohmann::json makeReport(const BakeOptionsCli& o, const baker::BakeConfig& config,
                          const baker::BakeResult& result,
                          const std::optional<baker::TargetChoice>& choice) {
    const baker::BakeStats& s = result.stats;
    nlohmann::json report = {
        {"scene", o.scene},
        {"output", o.output},
        {"bake_seconds", s.seconds},
        {"probes", s.probes},
        {"rays", s.rays},
        {"mrays_per_second", s.mraysPerSecond},
        {"invalid_probes", s.invalidProbes},
        {"relocated_probes", s.relocatedProbes},
        {"deringed_probes", s.deringedProbes},
        {"dering_mean_change", s.deringMeanChange},
        {"dering_max_change", s.deringMaxChange},
        {"peak_memory_bytes", s.peakMemoryBytes},
        {"predicted_peak_bytes", s.predictedPeakBytes},
        {"predicted_memory",
         {{"phase", s.predictedPeakPhase},
          {"terms", s.predictedTerms},
          {"bricked_refinement_bound_bytes", s.predictedRefinementBytes}}},
        {"threads", s.threads},
        {"vpls", s.vpls},
        {"vpls_requested", requestedVpls(config, result)},
        {"vpl_light_paths", s.vplLightPaths},
        {"vpl_mean_cut", s.vplMeanCut},
        {"samples_mean", s.meanSamples},
        {"samples_max", s.maxSamples},
        {"probes_over_noise_target", s.probesOverTarget},
        {"settings", nlohmann::json::parse(result.file.metadata.parametersJson)},
        {"gpu_bytes", gpuBytes(result.file)},
        {"warnings", result.warnings},
    };
    if (anyBricked(result.file)) {
        report["bricks_per_level"] = {s.bricksPerLevel[0], s.bricksPerLevel[1], s.bricksPerLevel[2],
                                      s.bricksPerLevel[3]};
        report["solid_bricks_per_level"] = {s.solidBricksPerLevel[0], s.solidBricksPerLevel[1],
                                            s.solidBricksPerLevel[2], s.solidBricksPerLevel[3]};
        report["refine_candidates"] = s.refineCandidates;
        report["nudged_probes"] = s.nudgedProbes;
        report["budget_dropped"] = s.budgetDropped;
        report["budget_error"] = s.budgetError;
        report["predicted_interpolation_error"] = s.predictedInterpolationError;
    }
    if (choice) {
        report["target_error"] = choice->target;
        report["predicted_error"] = baker::predictError(*choice, s);
        report["chosen"] = {{"sh_order", int(choice->shOrder)},
                            {"samples", choice->samples},
                            {"refine_error", choice->interpolationBudget},
                            {"pilot_noise", choice->pilotNoise},
                            {"band2", choice->band2},
                            {"pilot_seconds", choice->pilotSeconds}};
    }
    return report;
}

void printSummary(const BakeOptionsCli& o, const baker::BakeConfig& config,
                  const baker::BakeResult& result,
                  const std::optional<baker::TargetChoice>& choice) {
    const baker::BakeStats& s = result.stats;
    const auto count = [](uint64_t n) { return static_cast<unsigned long long>(n); };
    std::printf("wrote %s: %.2f s, %llu probes, %.3g rays, %.2f Mrays/s, %llu invalid probes, "
                "peak memory %.1f MiB (predicted %.1f), %u threads\n",
                o.output.c_str(), s.seconds, count(s.probes), double(s.rays), s.mraysPerSecond,
                count(s.invalidProbes), double(s.peakMemoryBytes) / (1 << 20),
                double(s.predictedPeakBytes) / (1 << 20), s.threads);
    if (s.relocatedProbes > 0) {
        std::printf("  %llu probes inside geometry baked at the nearest free point instead "
                    "(validity.relocate)\n",
                    count(s.relocatedProbes));
    }
    if (config.dering) {
        std::printf("  deringed %llu probes (irradiance changed by %.3g RMS on average, %.3g at "
                    "most)\n",
                    count(s.deringedProbes), s.deringMeanChange, s.deringMaxChange);
    }
    if (config.method == baker::Method::Vpl) {
        std::printf("  VPLs: %llu requested, %llu placed from %llu light paths, %.1f clusters "
                    "gathered per probe\n",
                    count(requestedVpls(config, result)), count(s.vpls), count(s.vplLightPaths),
                    s.vplMeanCut);
    }
    if (config.method == baker::Method::Lpv) {
        std::printf("  VPLs: %llu requested, %llu placed\n", count(requestedVpls(config, result)),
                    count(s.vpls));
    }
    if (config.path.noiseTarget > 0.0f) {
        std::printf("  adaptive sampling to noise %.3g: %.0f directions per probe on average, "
                    "%u at most (cap %u); %llu valid probes stopped at the cap above the target\n",
                    double(config.path.noiseTarget), s.meanSamples, s.maxSamples,
                    config.path.maxSamples, count(s.probesOverTarget));
    }
    if (anyBricked(result.file)) {
        std::printf("  bricks by level %llu / %llu / %llu / %llu, %llu tested for "
                    "refinement, %llu probes nudged off surfaces, GPU bytes %llu, predicted "
                    "interpolation error %.3g\n",
                    count(s.bricksPerLevel[0]), count(s.bricksPerLevel[1]),
                    count(s.bricksPerLevel[2]), count(s.bricksPerLevel[3]),
                    count(s.refineCandidates), count(s.nudgedProbes), count(gpuBytes(result.file)),
                    s.predictedInterpolationError);
        std::printf("  bricks with every probe inside geometry by level %llu / %llu / %llu / "
                    "%llu\n",
                    count(s.solidBricksPerLevel[0]), count(s.solidBricksPerLevel[1]),
                    count(s.solidBricksPerLevel[2]), count(s.solidBricksPerLevel[3]));
        if (s.budgetDropped > 0) {
            std::printf("  max_memory_mb bound: %llu finer bricks dropped, the costliest "
                        "with disagreement %.3g\n",
                        count(s.budgetDropped), s.budgetError);
        }
    }
    if (choice) {
        std::printf("  predicted error %.3g (target %.3g)\n", baker::predictError(*choice, s),
                    choice->target);
    }
}

// --verify: measures, prints and records the error of the written file.
Result<void> runVerify(const BakeOptionsCli& o, const baker::Scene& scene,
                       const baker::BakeConfig& config, const PvolFile& file,
                       nlohmann::json& report) {
    double seconds = 0.0;
    Result<baker::ErrorEstimate> e = verifyBake(scene, config, file, o, seconds);
    if (!e) {
        return e.error();
    }
    report["verify"] = {{"rel_rmse", e.value().relRmse},
                        {"rel_rmse_raw", e.value().relRmseRaw},
                        {"reference_noise", e.value().referenceNoise},
                        {"points", e.value().points},
                        {"points_requested", o.verifyPoints},
                        {"capped_points", e.value().cappedPoints},
                        {"effective_points", e.value().effectivePoints},
                        {"samples", o.verifySamples},
                        {"seconds", seconds}};
    if (!o.quiet) {
        // Points inside geometry have no reference and are skipped (estimateError).
        std::printf("verify: measured error %.4f against a path reference (%zu of %u points "
                    "valid, %zu at the bright-point cap, 2 x %u directions, reference noise "
                    "%.4f subtracted; raw %.4f), %.2f s\n",
                    e.value().relRmse, e.value().points, o.verifyPoints, e.value().cappedPoints,
                    o.verifySamples, e.value().referenceNoise, e.value().relRmseRaw, seconds);
    }
    // A handful of lit points carrying the reference make the figure theirs alone.
    if (e.value().points > 0 && e.value().effectivePoints < kFewEffectivePoints) {
        char text[400];
        std::snprintf(text, sizeof text,
                      "--verify: the reference's (capped) squared irradiance sits on %.1f "
                      "effective points of %zu (most points are dark): the measured error is "
                      "mostly theirs, not the whole volume's",
                      e.value().effectivePoints, e.value().points);
        report["warnings"].push_back(text);
        if (!o.quiet) {
            printError("bake", std::string("warning: ") + text);
        }
    }
    return {};
}

// --target-error fails the command when the error is more than kTargetTolerance x the target:
// --verify's measurement when there is one (it is the evidence; the prediction can be far off
// either way), its own prediction otherwise. The message says which and what bound the error.
std::string targetMissed(const baker::TargetChoice& choice, const baker::BakeStats& stats,
                         const nlohmann::json& report) {
    const double limit = baker::kTargetTolerance * choice.target;
    const double predicted = baker::predictError(choice, stats);
    char text[640];
    if (report.contains("verify")) {
        if (report["verify"]["rel_rmse"].get<double>() <= limit) {
            return {};
        }
        std::snprintf(text, sizeof text,
                      "target_error: --verify measured %.3g, more than %.3g x the target %.3g "
                      "(predicted %.3g; %s)",
                      report["verify"]["rel_rmse"].get<double>(), baker::kTargetTolerance,
                      choice.target, predicted, baker::explainError(choice, stats).c_str());
        return text;
    }
    if (predicted > limit) {
        std::snprintf(text, sizeof text,
                      "target_error: the predicted error %.3g is more than %.3g x the target %.3g "
                      "(%s)",
                      predicted, baker::kTargetTolerance, choice.target,
                      baker::explainError(choice, stats).c_str());
        return text;
    }
    return {};
}

Result<baker::BakeResult> bakeWithProgress(const BakeOptionsCli& o, const baker::Scene& scene,
                                           const baker::BakeConfig& config) {
    baker::BakeOptions options;
    options.threads = o.threads;
    options.allowUnlit = o.allowUnlit;
    if (DistributedBake* job = currentJob()) {
        options.distributor = job->distributor();
    }
    const bool terminal = isatty(STDERR_FILENO);
    if (!o.quiet) {
        options.progress = terminal ? printProgress : logProgress();
    }
    Result<baker::BakeResult> result = baker::bake(scene, config, options);
    if (!o.quiet && terminal) {
        std::fprintf(stderr, "\n");
    }
    return result;
}

// The distributed bake's line and report fields (rank 0; docs/baking.md#distributed-bakes).
void addTraffic(const DistributedBake& job, nlohmann::json& report, bool print) {
    const DistributedTraffic t = job.traffic();
    const double probes = t.probes > 0 ? double(t.probes) : 1.0;
    report["processes"] = job.size();
    report["mpi_chunks"] = t.chunks;
    report["mpi_result_bytes_per_probe"] = double(t.resultBytes) / probes;
    report["mpi_broadcast_bytes_per_probe"] = double(t.broadcastBytes) / probes;
    report["mpi_control_bytes_per_probe"] = double(t.controlBytes) / probes;
    if (print) {
        std::printf("  distributed over %d processes: %llu chunks; per probe %.1f B of results "
                    "to rank 0, %.1f B broadcast back, %.1f B of requests\n",
                    job.size(), static_cast<unsigned long long>(t.chunks),
                    double(t.resultBytes) / probes, double(t.broadcastBytes) / probes,
                    double(t.controlBytes) / probes);
    }
}

int runBakeProcess(const BakeOptionsCli& all, const DistributedBake* job);

int runBake(const BakeOptionsCli& o) {
    const DistributedBake* job = currentJob();
    const int code = runBakeProcess(o, job);
    // A process that fails alone must not leave the others waiting for it: end the job.
    if (code != kExitOk && job && job->size() > 1) {
        currentJob()->abort("bake failed (exit " + std::to_string(code) +
                            "); ending every process of the job");
    }
    return code;
}

// The options this process bakes with: only rank 0 prints, reports and verifies.
BakeOptionsCli processOptions(const BakeOptionsCli& all, bool rank0) {
    BakeOptionsCli o = all;
    if (!rank0) {
        o.quiet = true;
        o.report.clear();
        o.verify = false;
    }
    return o;
}

// --target-error: the settings its pilot bakes choose, written into `config` (none without it).
Result<std::optional<baker::TargetChoice>>
chooseForTarget(const BakeOptionsCli& o, const baker::Scene& scene, baker::BakeConfig& config) {
    std::optional<baker::TargetChoice> choice;
    if (!config.targetError) {
        return choice;
    }
    Result<baker::TargetChoice> chosen =
        baker::chooseSettings(scene, config, *config.targetError, o.threads);
    if (!chosen) {
        return chosen.error();
    }
    choice = std::move(chosen).value();
    config = choice->config;
    if (!o.quiet) {
        printChoice(*choice);
    }
    return choice;
}

// A finished bake and what made it, for rank 0's output.
struct BakeDone {
    const BakeOptionsCli& o;
    const baker::Scene& scene;
    const baker::BakeConfig& config;
    const baker::BakeResult& result;
    const std::optional<baker::TargetChoice>& choice;
};

// Rank 0 after the bake: writes the file, prints its summary, verifies it, writes the report
// and fails when --target-error was missed.
int finishBake(const BakeDone& d, const DistributedBake* job) {
    const BakeOptionsCli& o = d.o;
    if (auto w = writePvol(o.output, d.result.file); !w) {
        return fail(w.error());
    }
    nlohmann::json report = makeReport(o, d.config, d.result, d.choice);
    if (!o.quiet) {
        printSummary(o, d.config, d.result, d.choice);
    }
    if (job && job->size() > 1) {
        addTraffic(*job, report, !o.quiet);
    }
    if (o.verify) {
        if (auto v = runVerify(o, d.scene, d.config, d.result.file, report); !v) {
            return fail(v.error(), "--verify: ");
        }
    }
    const std::string missed = d.choice ? targetMissed(*d.choice, d.result.stats, report) : "";
    if (!missed.empty()) {
        report["target_missed"] = missed;
    }
    if (!o.report.empty()) {
        if (auto w = writeFileAtomic(o.report, jsonText(report, 2) + "\n"); !w) {
            return fail(w.error(), "--report: ");
        }
    }
    if (!missed.empty()) {
        printError("bake", missed + " (" + o.output + " is written, for inspection)");
        return kExitFailure;
    }
    return kExitOk;
}

// One process's part: every process bakes (its share of the probes goes through the job's
// distributor); rank 0 alone prints, writes the file and the report and verifies.
int runBakeProcess(const BakeOptionsCli& all, const DistributedBake* job) {
    const bool rank0 = !job || job->rank() == 0;
    const BakeOptionsCli o = processOptions(all, rank0);
    // A bad -o or --report fails before the bake, not after it (on rank 0, the only one that
    // writes them: other nodes need not see their folders); checked again with the scene's files.
    if (rank0) {
        if (Result<void> outputs = checkBakeOutputs(o, nullptr, nullptr); !outputs) {
            return fail(outputs.error());
        }
    }
    Result<baker::BakeConfig> config = configFromOptions(o);
    if (!config) {
        return fail(config.error());
    }
    Result<baker::Scene> scene = loadScene(o, config.value());
    if (!scene) {
        return fail(scene.error());
    }
    if (rank0) {
        if (Result<void> outputs = checkBakeOutputs(o, &config.value(), &scene.value()); !outputs) {
            return fail(outputs.error());
        }
    }
    // bake() refuses an unlit scene too; checked here before --target-error's pilot runs.
    if (Result<void> lit = baker::checkSceneLit(scene.value()); !lit && !o.allowUnlit) {
        return fail(lit.error());
    }
    Result<std::optional<baker::TargetChoice>> choice =
        chooseForTarget(o, scene.value(), config.value());
    if (!choice) {
        return fail(choice.error());
    }
    Result<baker::VolumePlan> plan = baker::planVolumes(scene.value(), config.value());
    if (!plan) {
        return fail(plan.error());
    }
    if (!o.quiet) {
        printMethod(o, scene.value(), config.value(), plan.value().volumes);
        printVolumes(plan.value().volumes);
        std::fflush(stdout);
    }
    // What placing the volumes changed from what was asked, before the bake starts; the bake
    // repeats these in its warnings, which are not printed twice.
    const std::vector<std::string>& notes = plan.value().notes;
    if (rank0 && !o.quiet) {
        printNewWarnings(notes, {});
    }
    Result<baker::BakeResult> result = bakeWithProgress(o, scene.value(), config.value());
    if (!result) {
        return fail(result.error());
    }
    if (!rank0) {
        return kExitOk;
    }
    if (!o.quiet) {
        printNewWarnings(result.value().warnings, notes);
    }
    return finishBake({o, scene.value(), config.value(), result.value(), choice.value()}, job);
}

// A CLI11 check of a flag's value by the settings table's rule for `path`.
CLI::Validator settingValidator(const std::string& path, const std::string& admits) {
    return CLI::Validator(
        [path](std::string& value) {
            Result<void> ok = baker::checkBakeSetting(path, value);
            return ok ? std::string() : ok.error().message;
        },
        "[" + admits + "]");
}

const baker::SettingInfo& samplesInfo() {
    for (const baker::SettingInfo& s : baker::bakeSettings()) {
        if (s.path == "path.samples") {
            return s;
        }
    }
    std::abort(); // the settings table lists path.samples
}

// One flag per setting of the table that names one.
void addSettingFlags(CLI::App* cmd, const std::shared_ptr<BakeOptionsCli>& o) {
    for (const baker::SettingInfo& s : baker::bakeSettings()) {
        if (s.flag.empty()) {
            continue;
        }
        const std::string help = s.help + (s.unit.empty() ? "" : " (" + s.unit + ")");
        cmd->add_option_function<std::string>(
               s.flag, [o, path = s.path](const std::string& v) { o->settings[path] = v; }, help)
            ->check(settingValidator(s.path, s.admits))
            ->type_name(s.type);
    }
}

} // namespace

void addBakeCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<BakeOptionsCli>();
    CLI::App* cmd = app.add_subcommand("bake", "Bake SH probe volumes for a glTF scene");
    cmd->add_option("SCENE", o->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
    cmd->add_option("-o,--output", o->output, "output .pvol")->required();
    cmd->add_option("--config", o->config, "bake config JSON (flags override it)");
    addSettingFlags(cmd, o);
    cmd->add_option("--samples", o->samples,
                    "directions per probe (path: full paths; vpl, lpv: direct light only)")
        ->check(settingValidator("path.samples", samplesInfo().admits))
        ->type_name(samplesInfo().type);
    cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)");
    auto* res = cmd->add_option("--resolution", o->resolution,
                                "probes per axis X,Y,Z (powers of two), every volume")
                    ->delimiter(',')
                    ->expected(3);
    cmd->get_option("--density")->excludes(res);
    cmd->add_option("--env", o->env, "environment: constant radiance R,G,B or a lat-long image");
    cmd->add_option("--scene", o->sceneIndex, "glTF scene index (default: the file's default)");
    addAssetRootOption(cmd, o->assetRoots);
    cmd->add_option("--report", o->report, "write a JSON report of the bake");
    cmd->add_flag("-q,--quiet", o->quiet,
                  "print nothing but errors: no progress, summary or warnings (--report still "
                  "records the warnings)");
    cmd->add_flag("--allow-unlit", o->allowUnlit,
                  "bake a scene that emits no light (no light, no emissive material, black "
                  "environment) with a warning instead of failing: every probe is zero");
    cmd->add_flag("--no-visibility", o->noVisibility,
                  "store no per-probe visibility (validity.visibility false): plain trilinear "
                  "interpolation, which leaks light through walls between probes");
    cmd->add_flag("--verify", o->verify,
                  "measure the error of the result against a path reference at points spread "
                  "over the volumes");
    cmd->add_option("--verify-points", o->verifyPoints, "--verify: points")
        ->check(CLI::Range(8u, 1u << 20))
        ->capture_default_str();
    cmd->add_option("--verify-samples", o->verifySamples,
                    "--verify: directions per point for each of the two reference estimates")
        ->check(CLI::Range(64u, 1u << 24))
        ->capture_default_str();
    cmd->callback([o, &selected] { selected = [o] { return runBake(*o); }; });
}

void addSceneCommand(CLI::App& app, Command& selected) {
    struct Options {
        std::string name;
        std::string output;
    };
    auto o = std::make_shared<Options>();
    CLI::App* cmd =
        app.add_subcommand("scene", "Write one of the bundled generated scenes as glTF");
    cmd->add_option("NAME", o->name, "scene name")
        ->required()
        ->check(CLI::IsMember(baker::generatedSceneNames()));
    cmd->add_option("-o,--output", o->output, "output .gltf (a .bin is written beside it)")
        ->required();
    cmd->callback([o, &selected] {
        selected = [o] {
            if (auto w = baker::writeGeneratedScene(o->name, o->output); !w) {
                printError("scene", w.error().message);
                return kExitFailure;
            }
            std::printf("wrote %s\n", o->output.c_str());
            return kExitOk;
        };
    });
}

void addBenchRaysCommand(CLI::App& app, Command& selected) {
    struct Options {
        std::string scene;
        uint64_t rays = 4'000'000;
        uint32_t threads = 0;
    };
    auto o = std::make_shared<Options>();
    CLI::App* cmd = app.add_subcommand(
        "bench-rays", "Raw Embree throughput on a scene: incoherent closest-hit and occlusion "
                      "rays, Mrays/s (prints one JSON line)");
    cmd->add_option("SCENE", o->scene, "glTF scene")->required();
    cmd->add_option("--rays", o->rays, "rays per measurement")->capture_default_str();
    cmd->add_option("--threads", o->threads, "threads (0 = all cores)");
    cmd->callback([o, &selected] {
        selected = [o] {
            Result<baker::Scene> scene = baker::loadGltf(o->scene);
            if (!scene) {
                printError("bench-rays", scene.error().message);
                return kExitFailure;
            }
            Result<baker::RayThroughput> r =
                baker::measureRayThroughput(scene.value(), o->rays, o->threads);
            if (!r) {
                printError("bench-rays", r.error().message);
                return kExitFailure;
            }
            const nlohmann::json j = {
                {"scene", o->scene},
                {"rays", r.value().rays},
                {"threads", r.value().threads},
                {"closest_hit_mrays_per_second", r.value().closestHitMraysPerSec},
                {"occlusion_mrays_per_second", r.value().occlusionMraysPerSec}};
            std::printf("%s\n", jsonText(j).c_str());
            return kExitOk;
        };
    });
}

} // namespace probekit::cli
