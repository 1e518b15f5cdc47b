// `probekit bake`, `probekit scene` and `probekit bench-rays`.
#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/bench_rays.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit::cli {
namespace {

struct BakeOptionsCli {
    std::string scene;
    std::string output;
    std::string config;
    std::optional<std::string> method;
    std::optional<uint32_t> samples;
    std::optional<uint32_t> bounces;
    std::optional<uint64_t> seed;
    std::optional<uint32_t> vplCount;
    std::optional<std::string> vplClamp;
    std::optional<std::string> vplShadows;
    std::optional<std::string> vplSampling;
    std::optional<uint32_t> vplBounces;
    std::optional<uint32_t> lpvGrid;
    std::optional<uint32_t> lpvIterations;
    std::optional<uint32_t> lpvCascades;
    std::optional<std::string> lpvOcclusion;
    std::optional<std::string> lpvDirect;
    uint32_t threads = 0;
    std::vector<uint32_t> resolution;
    std::optional<float> density;
    std::optional<std::string> position;
    std::optional<std::string> format;
    std::optional<int> shOrder;
    std::optional<std::string> env;
    std::optional<uint64_t> maxMemoryMb;
    std::optional<int> sceneIndex;
    std::string report;
    bool quiet = false;
    bool noVisibility = false;
    std::optional<double> targetError;
    bool verify = false;
    uint32_t verifyPoints = 256;
    uint32_t verifySamples = 4096;
};

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
        if (e.radiance.x < 0 || e.radiance.y < 0 || e.radiance.z < 0) {
            return makeError(ErrorCode::OutOfRange, "--env: radiance must be >= 0");
        }
        return e;
    }
    e.type = baker::EnvironmentConfig::Type::LatLong;
    e.file = value;
    return e;
}

void printProgress(const baker::BakeProgress& p) {
    const double fraction = p.probesTotal ? double(p.probesDone) / double(p.probesTotal) : 1.0;
    const int width = 30;
    const int filled = int(fraction * width);
    const double eta = fraction > 0 ? p.elapsedSeconds * (1.0 - fraction) / fraction : 0.0;
    std::fprintf(stderr, "\r  [%.*s%*s] %5.1f%%  %llu/%llu probes  %.1f s, ETA %.1f s ", filled,
                 "==============================", width - filled, "", fraction * 100.0,
                 static_cast<unsigned long long>(p.probesDone),
                 static_cast<unsigned long long>(p.probesTotal), p.elapsedSeconds, eta);
    std::fflush(stderr);
}

int runBake(const BakeOptionsCli& o) {
    Result<baker::BakeConfig> config_result = o.config.empty()
                                                  ? Result<baker::BakeConfig>(baker::BakeConfig{})
                                                  : baker::loadBakeConfig(o.config);
    if (!config_result) {
        std::fprintf(stderr, "probekit bake: %s\n", config_result.error().message.c_str());
        return kExitFailure;
    }
    baker::BakeConfig config = std::move(config_result).value();
    // Flags override the config file.
    if (o.method) {
        config.method = *o.method;
    }
    if (o.samples) {
        // For vpl and lpv the only per-probe directions are those of the direct light.
        (config.method == "vpl"   ? config.vpl.directSamples
         : config.method == "lpv" ? config.lpv.directSamples
                                  : config.path.samples) = *o.samples;
    }
    if (o.bounces) {
        config.path.maxBounces = *o.bounces;
    }
    if (o.seed) {
        config.seed = *o.seed;
    }
    if (o.vplCount) {
        config.vpl.count = *o.vplCount;
    }
    if (o.vplClamp) {
        config.vpl.clamp = *o.vplClamp == "none"       ? baker::VplClamp::None
                           : *o.vplClamp == "distance" ? baker::VplClamp::Distance
                                                       : baker::VplClamp::Spherical;
    }
    if (o.vplShadows) {
        config.vpl.shadows = *o.vplShadows == "on";
    }
    if (o.vplSampling) {
        config.vpl.sampling = *o.vplSampling == "random"     ? baker::VplSampling::Random
                              : *o.vplSampling == "jittered" ? baker::VplSampling::Jittered
                                                             : baker::VplSampling::Stratified;
    }
    if (o.vplBounces) {
        config.vpl.bounces = *o.vplBounces;
    }
    if (o.lpvGrid) {
        config.lpv.grid = *o.lpvGrid;
    }
    if (o.lpvIterations) {
        config.lpv.iterations = *o.lpvIterations;
    }
    if (o.lpvCascades) {
        config.lpv.cascades = *o.lpvCascades;
    }
    if (o.lpvOcclusion) {
        config.lpv.occlusion = *o.lpvOcclusion == "on";
    }
    if (o.lpvDirect) {
        config.lpv.direct =
            *o.lpvDirect == "traced" ? baker::LpvDirect::Traced : baker::LpvDirect::Propagated;
    }
    if (o.noVisibility) {
        config.visibility = false;
    }
    if (o.maxMemoryMb) {
        config.maxMemoryBytes = *o.maxMemoryMb << 20;
    }
    if (o.env) {
        Result<baker::EnvironmentConfig> env = parseEnvFlag(*o.env);
        if (!env) {
            std::fprintf(stderr, "probekit bake: %s\n", env.error().message.c_str());
            return kExitFailure;
        }
        config.environment = env.value();
    }
    if (config.volumes.empty()) {
        config.volumes.push_back(baker::VolumeConfig{});
    }
    for (baker::VolumeConfig& v : config.volumes) {
        if (!o.resolution.empty()) {
            const glm::uvec3 res(o.resolution[0], o.resolution[1], o.resolution[2]);
            v.resolution = res;
        }
        if (o.density) {
            v.resolution.reset();
            v.density = *o.density;
        }
        if (o.position) {
            v.position =
                *o.position == "corner" ? grid::PositionMode::Corner : grid::PositionMode::Center;
        }
        if (o.format) {
            v.storage = *o.format == "float" ? Storage::Float32 : Storage::Float16;
        }
        if (o.shOrder) {
            v.shOrder = *o.shOrder == 1 ? sh::Order::L1 : sh::Order::L2;
        }
    }

    baker::LoadOptions load_options;
    load_options.sceneIndex = o.sceneIndex;
    Result<baker::Scene> scene = baker::loadGltf(o.scene, load_options);
    if (!scene) {
        std::fprintf(stderr, "probekit bake: %s\n", scene.error().message.c_str());
        return kExitFailure;
    }
    Result<baker::Environment> env = baker::makeEnvironment(config.environment);
    if (!env) {
        std::fprintf(stderr, "probekit bake: %s\n", env.error().message.c_str());
        return kExitFailure;
    }
    scene.value().environment = std::move(env).value();
    for (const std::string& w : scene.value().warnings) {
        std::fprintf(stderr, "probekit bake: warning: %s\n", w.c_str());
    }

    if (o.targetError) {
        config.targetError = *o.targetError;
    }
    std::optional<baker::TargetChoice> choice;
    if (config.targetError) {
        Result<baker::TargetChoice> chosen =
            baker::chooseSettings(scene.value(), config, *config.targetError, o.threads);
        if (!chosen) {
            std::fprintf(stderr, "probekit bake: %s\n", chosen.error().message.c_str());
            return kExitFailure;
        }
        choice = std::move(chosen).value();
        config = choice->config;
        if (!o.quiet) {
            std::printf(
                "target error %.3g (relative RMS irradiance error against a path reference)\n"
                "  pilot: %u points x 2 estimates x %u directions, %.2f s: noise %.3g per "
                "probe, SH band 2 carries %.3g\n"
                "  chosen: SH order L%d (%s), %u directions per probe (interpolated noise "
                "%.3g), bricked volumes, levels 0..%u, refine_error %.3g\n",
                choice->target, choice->pilotPoints, choice->pilotSamples, choice->pilotSeconds,
                choice->pilotNoise, choice->band2, int(choice->shOrder),
                choice->shOrder == sh::Order::L1 ? "band 2 < 0.4 x target" : "band 2 needed",
                choice->samples, choice->predictedNoise, brick::kMaxLevel,
                choice->interpolationBudget);
        }
    }

    Result<std::vector<VolumeDesc>> placed = baker::resolveVolumes(scene.value(), config);
    if (!placed) {
        std::fprintf(stderr, "probekit bake: %s\n", placed.error().message.c_str());
        return kExitFailure;
    }
    if (!o.quiet) {
        if (config.method == "vpl") {
            const baker::VplConfig v =
                baker::resolveVplConfig(scene.value(), placed.value(), config);
            std::printf("baking %s: method vpl, seed %llu\n"
                        "  direct light: %u directions per probe (vpl.direct_samples)\n"
                        "  %u VPLs%s, %u bounces, %s sampling, clamp %s (%.4f m%s), near field "
                        "%.4f m%s, shadows %s, cut error %g\n",
                        o.scene.c_str(), static_cast<unsigned long long>(config.seed),
                        v.directSamples, *v.count,
                        config.vpl.count ? ""
                                         : " (auto: 4 x surface area / probe spacing^2, "
                                           "power of two in 16384..65536)",
                        v.bounces, std::string(baker::toString(v.sampling)).c_str(),
                        std::string(baker::toString(v.clamp)).c_str(), *v.clampDistance,
                        config.vpl.clampDistance ? "" : ", auto: 2 sqrt(area / (pi count))",
                        *v.nearField, config.vpl.nearField ? "" : " (auto: 2 x clamp distance)",
                        v.shadows ? "on" : "off", double(v.cutError));
        } else if (config.method == "lpv") {
            const baker::LpvConfig& l = config.lpv;
            const std::string direct = l.direct == baker::LpvDirect::Traced
                                           ? "traced, " + std::to_string(l.directSamples) +
                                                 " directions per probe (lpv.direct_samples)"
                                           : "propagated through the grids";
            std::printf("baking %s: method lpv, seed %llu\n"
                        "  direct light: %s\n"
                        "  %u VPLs, %u cascade(s) of %u cells on the longest axis (ratio %g), %u "
                        "iterations%s, occlusion %s, propagation weight %g, fade %g cells, "
                        "intensity %g\n",
                        o.scene.c_str(), static_cast<unsigned long long>(config.seed),
                        direct.c_str(), l.vplCount, l.cascades, l.grid, double(l.cascadeRatio),
                        l.iterations ? *l.iterations : l.grid,
                        l.iterations ? "" : " (auto: = grid)", l.occlusion ? "on" : "off",
                        double(l.propagationWeight), double(l.fadeCells), double(l.intensity));
        } else {
            std::printf("baking %s: method %s, %u samples, %u bounces, seed %llu\n",
                        o.scene.c_str(), config.method.c_str(), config.path.samples,
                        config.path.maxBounces, static_cast<unsigned long long>(config.seed));
        }
        for (const VolumeDesc& d : placed.value()) {
            const glm::uvec3 r = d.grid.resolution();
            const glm::vec3 lo = d.grid.bounds().min;
            const glm::vec3 hi = d.grid.bounds().max;
            if (d.layout == VolumeLayout::Bricked) {
                std::printf("  volume '%s': bricked, %ux%ux%u level-0 bricks, levels 0..%u, L%d, "
                            "%s, bounds (%.3f, %.3f, %.3f) .. (%.3f, %.3f, %.3f) m\n",
                            d.name.c_str(), r.x, r.y, r.z, d.bricks.maxLevel, int(d.shOrder),
                            std::string(toString(d.storage)).c_str(), lo.x, lo.y, lo.z, hi.x, hi.y,
                            hi.z);
                continue;
            }
            std::printf("  volume '%s': %ux%ux%u %s probes, L%d, %s, bounds (%.3f, %.3f, %.3f) "
                        ".. (%.3f, %.3f, %.3f) m\n",
                        d.name.c_str(), r.x, r.y, r.z,
                        std::string(grid::toString(d.grid.mode())).c_str(), int(d.shOrder),
                        std::string(toString(d.storage)).c_str(), lo.x, lo.y, lo.z, hi.x, hi.y,
                        hi.z);
        }
        std::fflush(stdout);
    }

    baker::BakeOptions bake_options;
    bake_options.threads = o.threads;
    const bool show_progress = !o.quiet && isatty(STDERR_FILENO);
    if (show_progress) {
        bake_options.progress = printProgress;
    }
    Result<baker::BakeResult> result = baker::bake(scene.value(), config, bake_options);
    if (show_progress) {
        std::fprintf(stderr, "\n");
    }
    if (!result) {
        std::fprintf(stderr, "probekit bake: %s\n", result.error().message.c_str());
        return kExitFailure;
    }
    for (const std::string& w : result.value().warnings) {
        std::fprintf(stderr, "probekit bake: warning: %s\n", w.c_str());
    }
    if (auto w = writePvol(o.output, result.value().file); !w) {
        std::fprintf(stderr, "probekit bake: %s\n", w.error().message.c_str());
        return kExitFailure;
    }
    const baker::BakeStats& s = result.value().stats;
    nlohmann::json report = {
        {"scene", o.scene},
        {"output", o.output},
        {"bake_seconds", s.seconds},
        {"probes", s.probes},
        {"rays", s.rays},
        {"mrays_per_second", s.mraysPerSecond},
        {"invalid_probes", s.invalidProbes},
        {"peak_memory_bytes", s.peakMemoryBytes},
        {"threads", s.threads},
        {"vpls", s.vpls},
        {"vpl_light_paths", s.vplLightPaths},
        {"vpl_mean_cut", s.vplMeanCut},
        {"settings", nlohmann::json::parse(result.value().file.metadata.parametersJson)},
    };
    uint64_t gpu_bytes = 0;
    bool any_bricked = false;
    for (const Volume& v : result.value().file.volumes) {
        gpu_bytes += v.gpuBytes();
        any_bricked |= v.desc.layout == VolumeLayout::Bricked;
    }
    report["gpu_bytes"] = gpu_bytes;
    if (any_bricked) {
        report["bricks_per_level"] = {s.bricksPerLevel[0], s.bricksPerLevel[1], s.bricksPerLevel[2],
                                      s.bricksPerLevel[3]};
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
    if (!o.quiet) {
        std::printf("wrote %s: %.2f s, %llu probes, %.3g rays, %.2f Mrays/s, %llu invalid probes, "
                    "peak memory %.1f MiB, %u threads\n",
                    o.output.c_str(), s.seconds, static_cast<unsigned long long>(s.probes),
                    double(s.rays), s.mraysPerSecond,
                    static_cast<unsigned long long>(s.invalidProbes),
                    double(s.peakMemoryBytes) / (1 << 20), s.threads);
        if (config.method == "vpl") {
            std::printf("  %llu VPLs from %llu light paths, %.1f clusters gathered per probe\n",
                        static_cast<unsigned long long>(s.vpls),
                        static_cast<unsigned long long>(s.vplLightPaths), s.vplMeanCut);
        }
        if (any_bricked) {
            std::printf("  bricks by level %llu / %llu / %llu / %llu, %llu tested for "
                        "refinement, %llu probes nudged off surfaces, GPU bytes %llu, predicted "
                        "interpolation error %.3g\n",
                        static_cast<unsigned long long>(s.bricksPerLevel[0]),
                        static_cast<unsigned long long>(s.bricksPerLevel[1]),
                        static_cast<unsigned long long>(s.bricksPerLevel[2]),
                        static_cast<unsigned long long>(s.bricksPerLevel[3]),
                        static_cast<unsigned long long>(s.refineCandidates),
                        static_cast<unsigned long long>(s.nudgedProbes),
                        static_cast<unsigned long long>(gpu_bytes), s.predictedInterpolationError);
            if (s.budgetDropped > 0) {
                std::printf("  max_memory_mb bound: %llu finer bricks dropped, the costliest "
                            "with disagreement %.3g\n",
                            static_cast<unsigned long long>(s.budgetDropped), s.budgetError);
            }
        }
        if (choice) {
            std::printf("  predicted error %.3g (target %.3g)\n", baker::predictError(*choice, s),
                        choice->target);
        }
    }
    if (o.verify) {
        double seconds = 0.0;
        Result<baker::ErrorEstimate> e =
            verifyBake(scene.value(), config, result.value().file, o, seconds);
        if (!e) {
            std::fprintf(stderr, "probekit bake: --verify: %s\n", e.error().message.c_str());
            return kExitFailure;
        }
        report["verify"] = {{"rel_rmse", e.value().relRmse},
                            {"rel_rmse_raw", e.value().relRmseRaw},
                            {"reference_noise", e.value().referenceNoise},
                            {"points", e.value().points},
                            {"samples", o.verifySamples},
                            {"seconds", seconds}};
        if (!o.quiet) {
            std::printf("verify: measured error %.4f against a path reference (%zu points, 2 x "
                        "%u directions, reference noise %.4f subtracted; raw %.4f), %.2f s\n",
                        e.value().relRmse, e.value().points, o.verifySamples,
                        e.value().referenceNoise, e.value().relRmseRaw, seconds);
        }
    }
    if (!o.report.empty()) {
        const std::string text = report.dump(2) + "\n";
        if (auto w = writeFileAtomic(o.report, text); !w) {
            std::fprintf(stderr, "probekit bake: --report: %s\n", w.error().message.c_str());
            return kExitFailure;
        }
    }
    return kExitOk;
}

} // namespace

void addBakeCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<BakeOptionsCli>();
    CLI::App* cmd = app.add_subcommand("bake", "Bake SH probe volumes for a glTF scene");
    cmd->add_option("SCENE", o->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
    cmd->add_option("-o,--output", o->output, "output .pvol")->required();
    cmd->add_option("--config", o->config, "bake config JSON (flags override it)");
    cmd->add_option("--method", o->method, "lighting method")
        ->check(CLI::IsMember({"path", "vpl", "lpv"}));
    cmd->add_option("--samples", o->samples,
                    "directions per probe (path: full paths; vpl, lpv: direct light only)")
        ->check(CLI::Range(1u, 1u << 24));
    cmd->add_option("--bounces", o->bounces, "path: maximum bounces")->check(CLI::Range(0u, 1024u));
    cmd->add_option("--seed", o->seed, "random seed");
    cmd->add_option("--vpl-count", o->vplCount, "vpl: VPLs to place (default: from the scene)")
        ->check(CLI::Range(1u, 1u << 24));
    cmd->add_option("--vpl-clamp", o->vplClamp, "vpl: near-VPL clamping")
        ->check(CLI::IsMember({"none", "distance", "spherical"}));
    cmd->add_option("--vpl-shadows", o->vplShadows, "vpl: visibility of VPLs at probes")
        ->check(CLI::IsMember({"on", "off"}));
    cmd->add_option("--vpl-sampling", o->vplSampling, "vpl: light-path sampling")
        ->check(CLI::IsMember({"random", "stratified", "jittered"}));
    cmd->add_option("--vpl-bounces", o->vplBounces, "vpl: reflections per light path")
        ->check(CLI::Range(1u, 1024u));
    cmd->add_option("--lpv-grid", o->lpvGrid, "lpv: cells along the longest axis of a cascade")
        ->check(CLI::Range(4u, 256u));
    cmd->add_option("--lpv-iterations", o->lpvIterations,
                    "lpv: propagation steps (default: the grid size)")
        ->check(CLI::Range(1u, 4096u));
    cmd->add_option("--lpv-cascades", o->lpvCascades, "lpv: nested grids per volume")
        ->check(CLI::Range(1u, 4u));
    cmd->add_option("--lpv-occlusion", o->lpvOcclusion, "lpv: geometry volume")
        ->check(CLI::IsMember({"on", "off"}));
    cmd->add_option("--lpv-direct", o->lpvDirect, "lpv: direct light traced or propagated")
        ->check(CLI::IsMember({"traced", "propagated"}));
    cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)");
    auto* res = cmd->add_option("--resolution", o->resolution,
                                "probes per axis X,Y,Z (powers of two), every volume")
                    ->delimiter(',')
                    ->expected(3);
    cmd->add_option("--density", o->density, "automatic resolution: probes per metre")
        ->check(CLI::PositiveNumber)
        ->excludes(res);
    cmd->add_option("--position", o->position, "probe placement")
        ->check(CLI::IsMember({"center", "corner"}));
    cmd->add_option("--format", o->format, "texel storage")
        ->check(CLI::IsMember({"float", "half"}));
    cmd->add_option("--sh-order", o->shOrder, "SH order")->check(CLI::IsMember({1, 2}));
    cmd->add_option("--env", o->env, "environment: constant radiance R,G,B or a lat-long image");
    cmd->add_option("--max-memory", o->maxMemoryMb, "memory budget for the grids, MiB")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--scene", o->sceneIndex, "glTF scene index (default: the file's default)");
    cmd->add_option("--report", o->report, "write a JSON report of the bake");
    cmd->add_flag("-q,--quiet", o->quiet, "print nothing but errors");
    cmd->add_flag("--no-visibility", o->noVisibility,
                  "store no per-probe visibility (validity.visibility false): plain trilinear "
                  "interpolation, which leaks light through walls between probes");
    cmd->add_option("--target-error", o->targetError,
                    "choose density, refinement, SH order and samples for this relative RMS "
                    "irradiance error (e.g. 0.05)")
        ->check(CLI::Range(1e-4, 0.99));
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
                std::fprintf(stderr, "probekit scene: %s\n", w.error().message.c_str());
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
                std::fprintf(stderr, "probekit bench-rays: %s\n", scene.error().message.c_str());
                return kExitFailure;
            }
            Result<baker::RayThroughput> r =
                baker::measureRayThroughput(scene.value(), o->rays, o->threads);
            if (!r) {
                std::fprintf(stderr, "probekit bench-rays: %s\n", r.error().message.c_str());
                return kExitFailure;
            }
            const nlohmann::json j = {
                {"scene", o->scene},
                {"rays", r.value().rays},
                {"threads", r.value().threads},
                {"closest_hit_mrays_per_second", r.value().closestHitMraysPerSec},
                {"occlusion_mrays_per_second", r.value().occlusionMraysPerSec}};
            std::printf("%s\n", j.dump().c_str());
            return kExitOk;
        };
    });
}

} // namespace probekit::cli
