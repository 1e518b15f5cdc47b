// `probekit bench-noise`: time to a worst-probe noise, adaptive against fixed sampling (method
// path). The noise is measured, not estimated: two bakes that differ only in their seed give
// each probe's noise as the difference of their irradiance
// (docs/accuracy.md#adaptive-against-fixed-sampling).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "config_options.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/formats/file_io.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

// The worst-probe statistic. A probe's noise measured from a few seeds is itself noisy (its
// square is about the true one times chi-square / dof, with 3 to 18 degrees of freedom per
// pair of seeds: the 18 components are correlated), so the largest measurement, or a high
// percentile, of hundreds of probes reads probes that sit exactly at the target as 1.5-2x it,
// and it favours fixed sampling, whose few truly worst probes are outnumbered there by
// adaptive's many probes at the target. So the worst probes are chosen with one half of the
// seeds and measured with the other, and the halves then swap: the worst kWorstFraction of
// the probes (at least kWorstMinimum), their RMS noise. It estimates the true noise of the
// probes that are really the worst without the selection's bias.
constexpr double kWorstFraction = 0.01;
constexpr size_t kWorstMinimum = 8;

struct BenchNoiseOptions {
    std::string scene;
    std::string config;
    double target = 0.05;
    uint32_t pilotSamples = 1024;
    uint32_t seeds = 8;
    uint32_t threads = 0;
    std::string out;
};

// One configuration baked with `seeds` consecutive seeds: seconds per bake (mean) and each
// probe's measured relative noise, one bake's: sqrt(sum_c s_c^2 / sum_c m_c^2) over the 18
// components c (six axis normals, three channels) of its irradiance, s_c^2 the sample variance
// over the seeds and m_c the mean; NaN where any bake found the probe invalid.
struct NoiseRun {
    double seconds = 0.0;
    double meanSamples = 0.0;
    uint32_t maxSamples = 0;
    uint64_t overTarget = 0;   // summed over the seeds
    std::vector<double> noise; // from all seeds
    // From the first and the second half of the seeds (worstNoise).
    std::vector<double> firstHalf, secondHalf;
};

// One probe's relative noise from the seeds [begin, end) of `e` (axis irradiance per seed).
double probeNoise(const std::vector<std::array<double, 18>>& e, size_t begin, size_t end) {
    const double n = double(end - begin);
    double variance = 0.0, magnitude = 0.0;
    for (size_t c = 0; c < 18; ++c) {
        double mean = 0.0, spread = 0.0;
        for (size_t k = begin; k < end; ++k) {
            mean += e[k][c] / n;
        }
        for (size_t k = begin; k < end; ++k) {
            spread += (e[k][c] - mean) * (e[k][c] - mean) / (n - 1.0);
        }
        variance += spread;
        magnitude += mean * mean;
    }
    return magnitude > 0.0 ? std::sqrt(variance / magnitude) : std::nan("");
}

constexpr glm::vec3 kAxes[6] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};

Result<NoiseRun> bakeSeeds(const baker::Scene& scene, baker::BakeConfig config, uint32_t seeds,
                           uint32_t threads) {
    NoiseRun run;
    std::vector<PvolFile> files;
    baker::BakeOptions options;
    options.threads = threads;
    for (uint32_t i = 0; i < seeds; ++i) {
        Result<baker::BakeResult> r = baker::bake(scene, config, options);
        if (!r) {
            return r.error();
        }
        run.seconds += r.value().stats.seconds / seeds;
        run.meanSamples += r.value().stats.meanSamples / seeds;
        run.maxSamples = std::max(run.maxSamples, r.value().stats.maxSamples);
        run.overTarget += r.value().stats.probesOverTarget;
        files.push_back(std::move(r.value().file));
        config.seed += 1;
    }
    for (size_t v = 0; v < files[0].volumes.size(); ++v) {
        for (size_t p = 0; p < files[0].volumes[v].probeCount(); ++p) {
            std::vector<std::array<double, 18>> e;
            for (const PvolFile& f : files) {
                const Volume& volume = f.volumes[v];
                if (volume.validity[p] != kProbeValid) {
                    break;
                }
                const sh::ShRgb probe = volume.probe(p);
                std::array<double, 18>& x = e.emplace_back();
                for (size_t a = 0; a < 6; ++a) {
                    const glm::vec3 irradiance =
                        sh::irradiance(probe, volume.desc.shOrder, kAxes[a]);
                    for (int c = 0; c < 3; ++c) {
                        x[3 * a + size_t(c)] = double(irradiance[c]);
                    }
                }
            }
            if (e.size() != files.size()) {
                run.noise.push_back(std::nan(""));
                run.firstHalf.push_back(std::nan(""));
                run.secondHalf.push_back(std::nan(""));
                continue;
            }
            run.noise.push_back(probeNoise(e, 0, seeds));
            run.firstHalf.push_back(probeNoise(e, 0, seeds / 2));
            run.secondHalf.push_back(probeNoise(e, seeds / 2, seeds));
        }
    }
    return run;
}

double maximum(const std::vector<double>& values) {
    double m = 0.0;
    for (double x : values) {
        m = std::isnan(x) ? m : std::max(m, x);
    }
    return m;
}

// RMS noise, measured by `measure`, of the worst probes as `select` ranks them.
double worstBy(const std::vector<double>& select, const std::vector<double>& measure) {
    std::vector<size_t> order;
    for (size_t i = 0; i < select.size(); ++i) {
        if (!std::isnan(select[i]) && !std::isnan(measure[i])) {
            order.push_back(i);
        }
    }
    if (order.empty()) {
        return std::nan("");
    }
    const size_t count =
        std::min(order.size(),
                 std::max(kWorstMinimum, size_t(std::ceil(kWorstFraction * double(order.size())))));
    std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(count), order.end(),
                      [&](size_t a, size_t b) { return select[a] > select[b]; });
    double sum = 0.0;
    for (size_t k = 0; k < count; ++k) {
        sum += measure[order[k]] * measure[order[k]];
    }
    return std::sqrt(sum / double(count));
}

double worstNoise(const NoiseRun& run) {
    const double a = worstBy(run.firstHalf, run.secondHalf);
    const double b = worstBy(run.secondHalf, run.firstHalf);
    return std::sqrt(0.5 * (a * a + b * b));
}

double rms(const std::vector<double>& values) {
    double sum = 0.0;
    size_t n = 0;
    for (double x : values) {
        if (!std::isnan(x)) {
            sum += x * x;
            ++n;
        }
    }
    return n > 0 ? std::sqrt(sum / double(n)) : std::nan("");
}

// The three measured configurations and their worst-probe noise (worstNoise).
struct NoiseResults {
    NoiseRun adaptive, pilot, fixed;
    double adaptiveWorst = 0.0, pilotWorst = 0.0, fixedWorst = 0.0;
    uint32_t fixedSamples = 0;
};

// The config, refused unless it is what bench-noise measures (method path on dense grids, no
// target_error), with float storage.
Result<baker::BakeConfig> noiseBaseConfig(const BenchNoiseOptions& o) {
    Result<baker::BakeConfig> loaded = loadConfigOrDefaults(o.config);
    if (!loaded) {
        return loaded;
    }
    baker::BakeConfig base = std::move(loaded).value();
    if (base.method != baker::Method::Path || base.targetError) {
        return makeError(ErrorCode::InvalidArgument,
                         o.config + ": bench-noise measures method path without target_error");
    }
    base.volumes = baker::volumeConfigs(base);
    for (baker::VolumeConfig& v : base.volumes) {
        v.layout = v.layout.value_or(VolumeLayout::Dense); // "auto": a dense grid here
        if (v.layout == VolumeLayout::Bricked) {
            return makeError(ErrorCode::InvalidArgument,
                             o.config + ": bench-noise compares dense grids probe by probe");
        }
        v.storage = Storage::Float32; // half floats would add their rounding to the noise
    }
    return base;
}

// The scene at the config's scale, lit by its environment.
Result<baker::Scene> loadNoiseScene(const BenchNoiseOptions& o, const baker::BakeConfig& base) {
    baker::LoadOptions load_options;
    load_options.scale = base.scale;
    load_options.maxMemoryBytes = base.maxMemoryBytes;
    Result<baker::Scene> scene = baker::loadGltf(o.scene, load_options);
    if (!scene) {
        return scene;
    }
    Result<baker::Environment> env = configEnvironment(base, o.config);
    if (!env) {
        return env.error();
    }
    scene.value().environment = std::move(env).value();
    return scene;
}

// `base` with fixed sampling: `samples` directions per probe, no noise target.
baker::BakeConfig fixedSampling(const baker::BakeConfig& base, uint32_t samples) {
    baker::BakeConfig fixed = base;
    fixed.path.noiseTarget = 0.0f;
    fixed.path.samples = samples;
    return fixed;
}

// The fixed count that matches adaptive's worst probe: noise falls as 1 / sqrt(samples) probe
// by probe, so it follows from the pilot's (rounded up to a multiple of 64).
uint32_t matchedSamples(uint32_t pilot_samples, double pilot_worst, double adaptive_worst) {
    const double ratio = pilot_worst / adaptive_worst;
    const double wanted = std::ceil(double(pilot_samples) * ratio * ratio / 64.0) * 64.0;
    return uint32_t(std::clamp(wanted, 64.0, double(1u << 24)));
}

// The three measurements: adaptive sampling to the target, fixed sampling at the pilot count,
// and fixed sampling at the count that matches adaptive's worst probe.
Result<NoiseResults> measureNoise(const BenchNoiseOptions& o, const baker::Scene& scene,
                                  const baker::BakeConfig& base) {
    NoiseResults out;
    // 1. Adaptive sampling to the target, from path.samples.
    baker::BakeConfig adaptive = base;
    adaptive.path.noiseTarget = float(o.target);
    std::fprintf(stderr, "bench-noise: adaptive, noise target %g, %u to %u directions\n", o.target,
                 adaptive.path.samples, adaptive.path.maxSamples);
    Result<NoiseRun> ad = bakeSeeds(scene, adaptive, o.seeds, o.threads);
    if (!ad) {
        return ad.error();
    }
    out.adaptive = std::move(ad).value();
    out.adaptiveWorst = worstNoise(out.adaptive);

    // 2. Fixed sampling at the pilot count.
    std::fprintf(stderr, "bench-noise: fixed pilot, %u directions\n", o.pilotSamples);
    Result<NoiseRun> pilot =
        bakeSeeds(scene, fixedSampling(base, o.pilotSamples), o.seeds, o.threads);
    if (!pilot) {
        return pilot.error();
    }
    out.pilot = std::move(pilot).value();
    out.pilotWorst = worstNoise(out.pilot);
    out.fixedSamples = matchedSamples(o.pilotSamples, out.pilotWorst, out.adaptiveWorst);

    // 3. Fixed sampling at that count, measured.
    std::fprintf(stderr, "bench-noise: fixed, %u directions\n", out.fixedSamples);
    Result<NoiseRun> fx =
        bakeSeeds(scene, fixedSampling(base, out.fixedSamples), o.seeds, o.threads);
    if (!fx) {
        return fx.error();
    }
    out.fixed = std::move(fx).value();
    out.fixedWorst = worstNoise(out.fixed);
    return out;
}

// The results as bench-noise's one JSON line.
nlohmann::json noiseReport(const BenchNoiseOptions& o, const NoiseResults& r) {
    const NoiseRun& ad = r.adaptive;
    const NoiseRun& fx = r.fixed;
    const double ad_worst = r.adaptiveWorst, fx_worst = r.fixedWorst;
    return {
        {"scene", o.scene},
        {"noise_target", o.target},
        {"worst_fraction", kWorstFraction},
        {"adaptive_seconds", ad.seconds},
        {"adaptive_samples_mean", ad.meanSamples},
        {"adaptive_samples_max", ad.maxSamples},
        {"seeds", o.seeds},
        {"adaptive_probes_over_target", double(ad.overTarget) / o.seeds},
        {"adaptive_worst_noise", ad_worst},
        {"adaptive_max_noise", maximum(ad.noise)},
        {"adaptive_rms_noise", rms(ad.noise)},
        {"fixed_pilot_samples", o.pilotSamples},
        {"fixed_pilot_worst_noise", r.pilotWorst},
        {"fixed_samples", r.fixedSamples},
        {"fixed_seconds", fx.seconds},
        {"fixed_worst_noise", fx_worst},
        {"fixed_max_noise", maximum(fx.noise)},
        {"fixed_rms_noise", rms(fx.noise)},
        {"time_ratio", ad.seconds / fx.seconds},
        // Fixed sampling's time scaled to adaptive's worst noise exactly (noise ~ 1/sqrt(time)).
        {"time_ratio_matched",
         ad.seconds / (fx.seconds * (fx_worst / ad_worst) * (fx_worst / ad_worst))},
        {"worst_noise_over_target", ad_worst / o.target},
    };
}

int runBenchNoise(const BenchNoiseOptions& o) {
    const auto fail = [](const std::string& message) {
        printError("bench-noise", message);
        return kExitFailure;
    };
    Result<baker::BakeConfig> base = noiseBaseConfig(o);
    if (!base) {
        return fail(base.error().message);
    }
    Result<baker::Scene> scene = loadNoiseScene(o, base.value());
    if (!scene) {
        return fail(scene.error().message);
    }
    Result<NoiseResults> results = measureNoise(o, scene.value(), base.value());
    if (!results) {
        return fail(results.error().message);
    }
    const nlohmann::json line = noiseReport(o, results.value());
    std::printf("%s\n", line.dump().c_str());
    if (!o.out.empty()) {
        if (auto w = writeFileAtomic(o.out, line.dump() + "\n"); !w) {
            return fail(w.error().message);
        }
    }
    return kExitOk;
}

} // namespace

void addBenchNoiseCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<BenchNoiseOptions>();
    CLI::App* cmd = app.add_subcommand(
        "bench-noise",
        "Seconds to a worst-probe noise, adaptive sampling (path.noise_target) against fixed: "
        "noise measured between seeds; one JSON line");
    cmd->add_option("SCENE", o->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
    cmd->add_option("--config", o->config,
                    "bake config JSON (method path): volumes, environment, path.samples as "
                    "adaptive's minimum, path.max_samples as its cap");
    cmd->add_option("--target", o->target, "adaptive sampling's noise target")
        ->check(CLI::Range(1e-4, 0.99))
        ->capture_default_str();
    cmd->add_option("--pilot-samples", o->pilotSamples,
                    "fixed sampling's pilot: directions per probe")
        ->check(CLI::Range(64u, 1u << 20))
        ->capture_default_str();
    cmd->add_option("--seeds", o->seeds,
                    "bakes per configuration (at least 4: the worst probes are chosen with half of "
                    "them and measured with the other half)")
        ->check(CLI::Range(4u, 64u))
        ->capture_default_str();
    cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)");
    cmd->add_option("--out", o->out, "also write the JSON line to this file");
    cmd->callback([o, &selected] { selected = [o] { return runBenchNoise(*o); }; });
}

} // namespace probekit::cli
