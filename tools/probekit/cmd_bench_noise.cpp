// `probekit bench-noise`: time to a worst-probe noise, adaptive against fixed sampling (method
// path). The noise is measured, not estimated: two bakes that differ only in their seed give
// each probe's noise as the difference of their irradiance (README, "Adaptive sampling").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/formats/file_io.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

// The worst-probe statistic: this quantile of the valid probes' measured noise. The maximum
// of hundreds of two-seed measurements is set by the measurement's own spread (a probe's
// squared noise from two bakes is about chi-square with 6 to 18 degrees of freedom), the 99th
// percentile much less so, and it still picks the worst room of a scene.
constexpr double kWorstQuantile = 0.99;

struct BenchNoiseOptions {
    std::string scene;
    std::string config;
    double target = 0.05;
    uint32_t pilotSamples = 1024;
    uint32_t threads = 0;
    std::string out;
};

// One configuration baked with two seeds: seconds per bake (mean) and each probe's measured
// relative noise (one bake's: sqrt(|Ea - Eb|^2 / 2) / |(Ea + Eb) / 2| over the six axis
// normals and three channels), NaN where either bake found the probe invalid.
struct NoiseRun {
    double seconds = 0.0;
    double meanSamples = 0.0;
    uint32_t maxSamples = 0;
    uint64_t overTarget = 0;
    std::vector<double> noise;
};

constexpr glm::vec3 kAxes[6] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};

Result<NoiseRun> bakeTwice(const baker::Scene& scene, baker::BakeConfig config, uint32_t threads) {
    NoiseRun run;
    std::vector<PvolFile> files;
    baker::BakeOptions options;
    options.threads = threads;
    for (int i = 0; i < 2; ++i) {
        Result<baker::BakeResult> r = baker::bake(scene, config, options);
        if (!r) {
            return r.error();
        }
        run.seconds += 0.5 * r.value().stats.seconds;
        run.meanSamples += 0.5 * r.value().stats.meanSamples;
        run.maxSamples = std::max(run.maxSamples, r.value().stats.maxSamples);
        run.overTarget += r.value().stats.probesOverTarget;
        files.push_back(std::move(r.value().file));
        config.seed += 1;
    }
    for (size_t v = 0; v < files[0].volumes.size(); ++v) {
        const Volume& a = files[0].volumes[v];
        const Volume& b = files[1].volumes[v];
        for (size_t p = 0; p < a.probeCount(); ++p) {
            if (a.validity[p] != kProbeValid || b.validity[p] != kProbeValid) {
                run.noise.push_back(std::nan(""));
                continue;
            }
            const sh::ShRgb sa = a.probe(p), sb = b.probe(p);
            double diff2 = 0.0, mean2 = 0.0;
            for (const glm::vec3& n : kAxes) {
                const glm::vec3 ea = sh::irradiance(sa, a.desc.shOrder, n);
                const glm::vec3 eb = sh::irradiance(sb, b.desc.shOrder, n);
                const glm::vec3 d = ea - eb, m = 0.5f * (ea + eb);
                diff2 += double(glm::dot(d, d));
                mean2 += double(glm::dot(m, m));
            }
            run.noise.push_back(mean2 > 0.0 ? std::sqrt(0.5 * diff2 / mean2) : std::nan(""));
        }
    }
    return run;
}

double quantile(std::vector<double> values, double q) {
    std::erase_if(values, [](double x) { return std::isnan(x); });
    if (values.empty()) {
        return std::nan("");
    }
    const size_t k = std::min(values.size() - 1, size_t(std::ceil(q * double(values.size())) - 1));
    std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(k), values.end());
    return values[k];
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

int runBenchNoise(const BenchNoiseOptions& o) {
    const auto fail = [](const std::string& message) {
        printError("bench-noise", message);
        return kExitFailure;
    };
    Result<baker::BakeConfig> loaded = o.config.empty()
                                           ? Result<baker::BakeConfig>(baker::BakeConfig{})
                                           : baker::loadBakeConfig(o.config);
    if (!loaded) {
        return fail(loaded.error().message);
    }
    baker::BakeConfig base = std::move(loaded).value();
    if (base.method != baker::Method::Path || base.targetError) {
        return fail(o.config + ": bench-noise measures method path without target_error");
    }
    if (base.volumes.empty()) {
        base.volumes.push_back(baker::VolumeConfig{});
    }
    for (baker::VolumeConfig& v : base.volumes) {
        if (v.layout == VolumeLayout::Bricked) {
            return fail(o.config + ": bench-noise compares dense grids probe by probe");
        }
        v.storage = Storage::Float32; // half floats would add their rounding to the noise
    }
    baker::LoadOptions load_options;
    load_options.scale = base.scale;
    Result<baker::Scene> scene = baker::loadGltf(o.scene, load_options);
    if (!scene) {
        return fail(scene.error().message);
    }
    Result<baker::Environment> env = baker::makeEnvironment(base.environment);
    if (!env) {
        return fail(env.error().message);
    }
    scene.value().environment = std::move(env).value();

    // 1. Adaptive sampling to the target, from path.samples.
    baker::BakeConfig adaptive = base;
    adaptive.path.noiseTarget = float(o.target);
    std::fprintf(stderr, "bench-noise: adaptive, noise target %g, %u to %u directions\n", o.target,
                 adaptive.path.samples, adaptive.path.maxSamples);
    Result<NoiseRun> ad = bakeTwice(scene.value(), adaptive, o.threads);
    if (!ad) {
        return fail(ad.error().message);
    }
    const double ad_worst = quantile(ad.value().noise, kWorstQuantile);

    // 2. Fixed sampling at the pilot count: noise falls as 1 / sqrt(samples) probe by probe,
    // so the count that matches adaptive's worst probe follows from it.
    baker::BakeConfig fixed = base;
    fixed.path.noiseTarget = 0.0f;
    fixed.path.samples = o.pilotSamples;
    std::fprintf(stderr, "bench-noise: fixed pilot, %u directions\n", o.pilotSamples);
    Result<NoiseRun> pilot = bakeTwice(scene.value(), fixed, o.threads);
    if (!pilot) {
        return fail(pilot.error().message);
    }
    const double pilot_worst = quantile(pilot.value().noise, kWorstQuantile);
    const double ratio = pilot_worst / ad_worst;
    const double wanted = std::ceil(double(o.pilotSamples) * ratio * ratio / 64.0) * 64.0;
    fixed.path.samples = uint32_t(std::clamp(wanted, 64.0, double(1u << 24)));

    // 3. Fixed sampling at that count, measured.
    std::fprintf(stderr, "bench-noise: fixed, %u directions\n", fixed.path.samples);
    Result<NoiseRun> fx = bakeTwice(scene.value(), fixed, o.threads);
    if (!fx) {
        return fail(fx.error().message);
    }
    const double fx_worst = quantile(fx.value().noise, kWorstQuantile);

    const nlohmann::json line = {
        {"scene", o.scene},
        {"noise_target", o.target},
        {"worst_quantile", kWorstQuantile},
        {"adaptive_seconds", ad.value().seconds},
        {"adaptive_samples_mean", ad.value().meanSamples},
        {"adaptive_samples_max", ad.value().maxSamples},
        {"adaptive_probes_over_target", ad.value().overTarget / 2},
        {"adaptive_worst_noise", ad_worst},
        {"adaptive_max_noise", quantile(ad.value().noise, 1.0)},
        {"adaptive_rms_noise", rms(ad.value().noise)},
        {"fixed_pilot_samples", o.pilotSamples},
        {"fixed_pilot_worst_noise", pilot_worst},
        {"fixed_samples", fixed.path.samples},
        {"fixed_seconds", fx.value().seconds},
        {"fixed_worst_noise", fx_worst},
        {"fixed_max_noise", quantile(fx.value().noise, 1.0)},
        {"fixed_rms_noise", rms(fx.value().noise)},
        {"time_ratio", ad.value().seconds / fx.value().seconds},
        {"worst_noise_over_target", ad_worst / o.target},
    };
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
        "noise measured between two seeds; one JSON line");
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
    cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)");
    cmd->add_option("--out", o->out, "also write the JSON line to this file");
    cmd->callback([o, &selected] { selected = [o] { return runBenchNoise(*o); }; });
}

} // namespace probekit::cli
