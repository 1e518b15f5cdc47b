// `probekit bench`: speed against accuracy on one scene. Bakes (or reuses) a high-sample path
// reference of the config's volumes, sweeps the three methods over their main settings and
// writes one CSV row per variant (tools/chart draws it). It is orchestration of baker::bake and
// runtime::compareVolumes and lives in tools/ because the baker never depends on the runtime.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "probekit/formats/json_nesting.hpp"

#include "camera_options.hpp"
#include "commands.hpp"
#include "config_options.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/surface_reference.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/runtime/compare.hpp"
#include "probekit/runtime/sampler.hpp"
#include "probekit/runtime/surface_error.hpp"
#include "probekit/viewer/surface_view.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

// Path bounces of the reference and of the path runs: Russian roulette ends almost every path
// long before, and a low cap would bias both by about albedo^(cap + 1) (6% on the Cornell box
// at the former default 8), so the path rows would measure truncation instead of noise. The
// default is 64 now; this keeps a config that lowers it from skewing the sweep.
constexpr uint32_t kPathBounces = 64;
// The reference's seed is the config's plus this, so that no run shares its random numbers
// (a path run with the reference's seed would reproduce its first samples and look too good).
constexpr uint64_t kReferenceSeedOffset = 1000003;
constexpr uint32_t kReferenceSamplesFull = 131072;
constexpr uint32_t kReferenceSamplesQuick = 32768;
// Probes whose mean reference irradiance is in this lowest fraction form the "dark" set of the
// leak figure (the unlit room of a thin-wall scene, the shadows under the Cornell blocks).
constexpr double kDarkFraction = 0.25;
// Probe positions of a reused reference must match the config's to this distance (metres).
constexpr float kPositionTolerance = 1e-5f;

struct BenchOptions {
    std::string scene;
    std::string config;
    std::string out;
    std::string reference;
    std::optional<uint32_t> referenceSamples;
    bool quick = false;
    uint32_t threads = 0;
    std::optional<int> sceneIndex;
    // The view of the per-pixel figures (docs/accuracy.md#surface-accuracy).
    CameraOptions surfaceView{{}, "+z", 40.0f, {96, 72}};
    std::optional<uint32_t> surfaceSamples;
};

// Cosine directions per pixel of the surface reference (its median relative standard error on
// the Cornell box: about 4% at 1024, 8% at 256).
constexpr uint32_t kSurfaceSamplesFull = 1024;
constexpr uint32_t kSurfaceSamplesQuick = 256;

// The per-pixel reference of the bench's view, traced once.
Result<runtime::SurfaceReferenceImage> surfaceReference(const BenchOptions& o,
                                                        const baker::Scene& scene, uint64_t seed) {
    const uint32_t w = o.surfaceView.size[0], h = o.surfaceView.size[1];
    Result<runtime::Camera> camera = chooseCamera(o.surfaceView, scene.bounds, float(w) / float(h));
    if (!camera) {
        return camera.error();
    }
    const std::vector<baker::SurfaceRay> rays = viewer::viewRays(camera.value(), w, h);
    baker::SurfaceReferenceSettings settings;
    settings.samples =
        o.surfaceSamples.value_or(o.quick ? kSurfaceSamplesQuick : kSurfaceSamplesFull);
    settings.seed = seed;
    settings.threads = o.threads;
    Result<baker::SurfaceReference> traced = baker::traceSurfaceReference(scene, rays, settings);
    if (!traced) {
        return traced.error();
    }
    const runtime::SurfaceReferenceImage image = viewer::referenceImage(traced.value(), w, h);
    return image;
}

// A run's per-pixel figures: its volumes sampled by the CPU sampler at the reference's points.
Result<runtime::SurfaceError> surfaceFigures(const PvolFile& file,
                                             const runtime::SurfaceReferenceImage& r) {
    Result<runtime::VolumeSet> set = runtime::VolumeSet::make(file.volumes);
    if (!set) {
        return set.error();
    }
    std::vector<glm::vec3> e(r.hit.size(), glm::vec3(0.0f));
    for (size_t i = 0; i < r.hit.size(); ++i) {
        if (r.hit[i]) {
            e[i] = set.value().irradiance(r.position[i], r.normal[i]);
        }
    }
    return runtime::compareSurface(e, r);
}

// One bake of the sweep: the method and its settings on top of the user's config.
struct Run {
    std::string method;
    std::string parameters; // "key=value" pairs separated by spaces (no commas: plain CSV)
    std::function<void(baker::BakeConfig&)> apply;
};

// Every bake yields these four rows: the bake itself is float L2, and the other variants are
// packed from its coefficients exactly as a bake with that storage and order packs its own
// (the integrators do the same work for every storage; L1 is the L2 projection truncated).
struct Variant {
    Storage storage;
    sh::Order order;
};
constexpr Variant kVariants[] = {{Storage::Float32, sh::Order::L2},
                                 {Storage::Float16, sh::Order::L2},
                                 {Storage::Float32, sh::Order::L1},
                                 {Storage::Float16, sh::Order::L1}};

std::vector<Run> sweep(bool quick) {
    std::vector<Run> runs;
    const auto path = [&](uint32_t samples) {
        runs.push_back({"path", "samples=" + std::to_string(samples), [samples](auto& c) {
                            c.method = baker::Method::Path;
                            c.path.samples = samples;
                        }});
    };
    const auto vpl = [&](uint32_t count, baker::VplClamp clamp, bool shadows) {
        runs.push_back({"vpl",
                        "count=" + std::to_string(count) +
                            " clamp=" + std::string(baker::toString(clamp)) +
                            " shadows=" + (shadows ? "on" : "off"),
                        [=](auto& c) {
                            c.method = baker::Method::Vpl;
                            c.vpl.count = count;
                            c.vpl.clamp = clamp;
                            c.vpl.shadows = shadows;
                        }});
    };
    const auto lpv = [&](uint32_t grid, uint32_t cascades, std::optional<uint32_t> iterations) {
        runs.push_back({"lpv",
                        "grid=" + std::to_string(grid) + " cascades=" + std::to_string(cascades) +
                            " iterations=" + std::to_string(iterations.value_or(grid)),
                        [=](auto& c) {
                            c.method = baker::Method::Lpv;
                            c.lpv.grid = grid;
                            c.lpv.cascades = cascades;
                            c.lpv.iterations = iterations;
                        }});
    };
    using baker::VplClamp;
    // --quick leaves out the slowest and the most redundant runs: path at 16384 samples, the
    // 64^3 LPV with more than one cascade, and the extra clamp and shadow settings.
    for (const uint32_t s : {16u, 64u, 256u, 1024u, 4096u}) {
        path(s);
    }
    if (!quick) {
        path(16384);
    }
    for (const uint32_t n : {64u, 256u, 1024u, 4096u, 16384u, 65536u}) {
        vpl(n, VplClamp::Spherical, true);
    }
    for (const uint32_t n : quick ? std::vector<uint32_t>{1024u, 16384u}
                                  : std::vector<uint32_t>{256u, 1024u, 4096u, 16384u, 65536u}) {
        vpl(n, VplClamp::None, true);
        vpl(n, VplClamp::Distance, true);
        vpl(n, VplClamp::Spherical, false);
    }
    for (const uint32_t grid : {16u, 32u, 64u}) {
        for (const uint32_t cascades : {1u, 2u, 3u}) {
            if (!(quick && grid == 64 && cascades > 1)) {
                lpv(grid, cascades, std::nullopt);
            }
        }
    }
    for (const uint32_t iterations : {8u, 16u, 64u}) {
        lpv(32, 1, iterations);
    }
    return runs;
}

// The figures of one row beyond compareVolumes'.
struct ExtraFigures {
    double darkRatio = 0.0;        // sum E over the reference's darkest probes, test / reference
    double negativeFraction = 0.0; // share of (probe, normal) pairs with E < 0 in some channel
};

// Scalar irradiance of a probe: mean over the compare normals of the channel mean.
double meanIrradiance(const Volume& v, size_t probe) {
    const sh::ShRgb s = v.probe(probe);
    double sum = 0.0;
    for (int k = 0; k < runtime::kCompareNormals; ++k) {
        const glm::vec3 e =
            sh::irradiance(s, v.desc.shOrder, sh::fibonacciDirection(k, runtime::kCompareNormals));
        sum += (double(e.x) + double(e.y) + double(e.z)) / 3.0;
    }
    return sum / runtime::kCompareNormals;
}

// The dark set: (volume, probe) pairs valid in the reference whose mean irradiance is in its
// lowest kDarkFraction. Chosen once, from the reference alone, so every run is judged on the
// same probes.
std::vector<std::pair<size_t, size_t>> darkProbes(const PvolFile& reference) {
    std::vector<std::pair<double, std::pair<size_t, size_t>>> all;
    for (size_t v = 0; v < reference.volumes.size(); ++v) {
        const Volume& vol = reference.volumes[v];
        for (size_t i = 0; i < vol.probeCount(); ++i) {
            if (vol.validity[i] == kProbeValid) {
                all.push_back({meanIrradiance(vol, i), {v, i}});
            }
        }
    }
    std::sort(all.begin(), all.end());
    const size_t keep = std::max<size_t>(1, size_t(double(all.size()) * kDarkFraction));
    std::vector<std::pair<size_t, size_t>> out;
    for (size_t i = 0; i < std::min(keep, all.size()); ++i) {
        out.push_back(all[i].second);
    }
    return out;
}

ExtraFigures extraFigures(const PvolFile& test, const PvolFile& reference,
                          const std::vector<std::pair<size_t, size_t>>& dark) {
    ExtraFigures f;
    double test_sum = 0.0, ref_sum = 0.0;
    for (const auto& [v, i] : dark) {
        test_sum += meanIrradiance(test.volumes[v], i);
        ref_sum += meanIrradiance(reference.volumes[v], i);
    }
    f.darkRatio = ref_sum > 0.0 ? test_sum / ref_sum : 0.0;
    size_t negative = 0, total = 0;
    for (const Volume& vol : test.volumes) {
        for (size_t i = 0; i < vol.probeCount(); ++i) {
            const sh::ShRgb s = vol.probe(i);
            for (int k = 0; k < runtime::kCompareNormals; ++k) {
                const glm::vec3 e = sh::irradiance(
                    s, vol.desc.shOrder, sh::fibonacciDirection(k, runtime::kCompareNormals));
                negative += (e.x < 0.0f || e.y < 0.0f || e.z < 0.0f) ? 1 : 0;
                ++total;
            }
        }
    }
    f.negativeFraction = total ? double(negative) / double(total) : 0.0;
    return f;
}

// The bake's float L2 volumes (baked without deringing) repacked as `variant`, and deringed for
// that order and storage as a dense bake of it would be when `dering`. A half overflow is the error
// makeVolume gives (it names the volume and the value): the row records it, never an infinity.
Result<PvolFile> repack(const PvolFile& baked, Variant variant, bool dering) {
    PvolFile out;
    out.metadata = baked.metadata;
    const sh::Rounding rounding =
        variant.storage == Storage::Float16 ? sh::Rounding::Float16 : sh::Rounding::Float32;
    for (const Volume& v : baked.volumes) {
        std::vector<sh::ShRgb> probes(v.probeCount());
        for (size_t i = 0; i < probes.size(); ++i) {
            probes[i] = variant.order == sh::Order::L1 ? sh::truncateToL1(v.probe(i)) : v.probe(i);
            if (dering) {
                probes[i] = sh::deringIrradiance(probes[i], variant.order, rounding).sh;
            }
        }
        VolumeDesc desc = v.desc;
        desc.storage = variant.storage;
        desc.shOrder = variant.order;
        Result<Volume> packed = makeVolume(desc, probes, v.validity);
        if (!packed) {
            return packed.error();
        }
        out.volumes.push_back(std::move(packed).value());
    }
    return out;
}

// Whether a reference file holds a path bake of exactly these volumes for this scene; the
// message says what differs.
Result<void> checkReference(const PvolFile& ref, const std::vector<VolumeDesc>& volumes,
                            const baker::Scene& scene, uint64_t run_seed) {
    const auto differ = [](const std::string& what) {
        return makeError(ErrorCode::InvalidArgument,
                         what + " (delete it to rebuild, or pass --reference another path)");
    };
    if (ref.metadata.method != "path") {
        return differ("method is '" + ref.metadata.method + "', not path");
    }
    if (ref.metadata.sceneHash != scene.sourceHash) {
        return differ("baked from another scene file (scene hash differs)");
    }
    if (ref.metadata.seed == run_seed) {
        return differ("its seed equals the runs' seed, so path runs would share its samples");
    }
    if (ref.volumes.size() != volumes.size()) {
        return differ(std::to_string(ref.volumes.size()) + " volumes, the config places " +
                      std::to_string(volumes.size()));
    }
    for (size_t v = 0; v < volumes.size(); ++v) {
        const VolumeDesc& a = ref.volumes[v].desc;
        const VolumeDesc& b = volumes[v];
        const std::string name = "volume " + std::to_string(v) + " ('" + b.name + "'): ";
        if (a.grid.resolution() != b.grid.resolution() || a.grid.mode() != b.grid.mode()) {
            return differ(name + "resolution or probe placement differs");
        }
        const size_t last = b.grid.probeCount() - 1;
        for (const size_t i : {size_t(0), last}) {
            const glm::vec3 d =
                a.grid.probeWorld(a.grid.probeCoords(i)) - b.grid.probeWorld(b.grid.probeCoords(i));
            if (std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)}) > kPositionTolerance) {
                return differ(name + "probe positions differ");
            }
        }
        if (a.shOrder != sh::Order::L2 || a.storage != Storage::Float32) {
            return differ(name + "not float L2");
        }
    }
    return {};
}

uint32_t referenceSamplesOf(const PvolFile& ref) {
    const Result<nlohmann::json> parsed =
        parseJsonText<nlohmann::json>(ref.metadata.parametersJson, "parameters");
    const nlohmann::json::json_pointer samples("/path/samples");
    if (!parsed || !parsed.value().contains(samples) ||
        !parsed.value().at(samples).is_number_unsigned()) {
        return 0;
    }
    return parsed.value().at(samples).get<uint32_t>();
}

std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) {
        return s;
    }
    std::string q = "\"";
    for (const char c : s) {
        q += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
    }
    return q + "\"";
}

std::string number(double v) {
    if (!std::isfinite(v)) {
        return "nan";
    }
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

constexpr const char* kCsvHeader =
    "method,parameters,format,sh_order,bake_s,rays,bytes,rel_rmse,max_probe_err,max_abs_err,"
    "dark_ratio,negative_fraction,invalid_probes,surface_median_error,surface_mean_ratio,"
    "surface_under_half,surface_over_two,surface_negative,status\n";

// The user's config made into the sweep's base: refused where bench cannot sweep it, every
// volume float L2 (the four storage variants are packed from it, kVariants) and the path
// bounces raised to kPathBounces.
Result<baker::BakeConfig> benchBaseConfig(const BenchOptions& o) {
    Result<baker::BakeConfig> loaded = loadConfigOrDefaults(o.config);
    if (!loaded) {
        return loaded;
    }
    baker::BakeConfig base = std::move(loaded).value();
    if (base.targetError) {
        return makeError(ErrorCode::InvalidArgument,
                         o.config + ": target_error: bench sweeps the settings itself; remove it");
    }
    for (size_t i = 0; i < base.volumes.size(); ++i) {
        // The metric compares probe by probe against a reference of the same grids; a bricked
        // volume's bricks depend on the bake, so no two runs share their probes.
        if (base.volumes[i].layout == VolumeLayout::Bricked) {
            return makeError(ErrorCode::InvalidArgument,
                             o.config + ": volumes[" + std::to_string(i) +
                                 "].layout: bench compares dense grids probe by probe; measure "
                                 "bricked volumes with `probekit bake --verify` (or "
                                 "tools/bench-bricked.sh)");
        }
    }
    base.volumes = baker::volumeConfigs(base);
    for (baker::VolumeConfig& v : base.volumes) {
        v.layout = VolumeLayout::Dense; // "auto" too: the sweep's grids are dense
        v.storage = Storage::Float32;
        v.shOrder = sh::Order::L2;
    }
    base.path.maxBounces = std::max(base.path.maxBounces, kPathBounces);
    return base;
}

// The scene lit by the config's environment, and the volumes the config places in it.
struct BenchScene {
    baker::Scene scene;
    std::vector<VolumeDesc> volumes;
};

// Loads the scene and places the config's volumes in it.
Result<BenchScene> loadBenchScene(const BenchOptions& o, const baker::BakeConfig& base) {
    baker::LoadOptions load_options;
    load_options.sceneIndex = o.sceneIndex;
    load_options.scale = base.scale;
    load_options.maxMemoryBytes = base.maxMemoryBytes;
    Result<baker::Scene> scene = baker::loadGltf(o.scene, load_options);
    if (!scene) {
        return scene.error();
    }
    Result<baker::Environment> env = configEnvironment(base, o.config);
    if (!env) {
        return env.error();
    }
    scene.value().environment = std::move(env).value();
    Result<std::vector<VolumeDesc>> placed = baker::resolveVolumes(scene.value(), base);
    if (!placed) {
        return placed.error();
    }
    return BenchScene{std::move(scene).value(), std::move(placed).value()};
}

// Where the reference is read or written: --reference, else NAME-reference.pvol beside the CSV.
std::filesystem::path referencePath(const BenchOptions& o) {
    const std::filesystem::path out_path(o.out);
    return o.reference.empty()
               ? out_path.parent_path() / (out_path.stem().string() + "-reference.pvol")
               : std::filesystem::path(o.reference);
}

// The reference at `path`, if it holds a path bake of exactly these volumes.
Result<PvolFile> reuseReference(const std::filesystem::path& path, const BenchScene& in,
                                uint64_t run_seed) {
    Result<PvolFile> r = readPvol(path);
    if (!r) {
        return r;
    }
    if (auto ok = checkReference(r.value(), in.volumes, in.scene, run_seed); !ok) {
        return makeError(ok.error().code,
                         path.string() + ": does not match: " + ok.error().message);
    }
    std::fprintf(stderr, "bench: reusing reference %s (path, %u samples)\n", path.string().c_str(),
                 referenceSamplesOf(r.value()));
    return r;
}

// A new reference: the config's volumes baked by the path method with many samples, written
// to `path`.
Result<PvolFile> bakeReference(const BenchOptions& o, const baker::Scene& scene,
                               const baker::BakeConfig& base,
                               const baker::BakeOptions& bake_options,
                               const std::filesystem::path& path) {
    baker::BakeConfig rc = base;
    rc.method = baker::Method::Path;
    rc.dering = false; // the reference keeps the path method's own coefficients
    rc.seed = base.seed + kReferenceSeedOffset;
    rc.path.samples =
        o.referenceSamples.value_or(o.quick ? kReferenceSamplesQuick : kReferenceSamplesFull);
    std::fprintf(stderr, "bench: baking the reference (path, %u samples, %u bounces) -> %s\n",
                 rc.path.samples, rc.path.maxBounces, path.string().c_str());
    Result<baker::BakeResult> r = baker::bake(scene, rc, bake_options);
    if (!r) {
        return makeError(r.error().code, "reference: " + r.error().message);
    }
    if (auto w = writePvol(path, r.value().file); !w) {
        return w.error();
    }
    std::fprintf(stderr, "bench: reference done in %.1f s\n", r.value().stats.seconds);
    return std::move(r).value().file;
}

// Prints the surface reference's own noise, the floor under every run's per-pixel figures.
void reportSurfaceReference(const BenchOptions& o, const runtime::SurfaceReferenceImage& surface) {
    Result<runtime::SurfaceError> self = runtime::compareSurface(surface.irradiance, surface);
    std::fprintf(stderr,
                 "bench: surface reference %ux%u from %s, %zu pixels compared, median "
                 "relative noise %.4f (a perfect volume measures a median error of about "
                 "%.4f)\n",
                 surface.width, surface.height,
                 o.surfaceView.camera.empty() ? o.surfaceView.cameraFrom.c_str() : "--camera",
                 self ? self.value().compared : size_t(0), self ? self.value().referenceNoise : 0.0,
                 self ? self.value().noiseFloor : 0.0);
}

// What every row of the sweep is measured against, made once.
struct BenchContext {
    const BenchOptions& o;
    const baker::Scene& scene;
    const baker::BakeConfig& base;
    const baker::BakeOptions& bakeOptions;
    const PvolFile& reference;
    const std::vector<std::pair<size_t, size_t>>& dark;
    const runtime::SurfaceReferenceImage& surface;
    size_t runCount;
};

// One finished bake of the sweep: which run it was and how long it took.
struct BakedRun {
    const Run& run;
    size_t index;
    double seconds;
    const baker::BakeResult& result;
};

// Appends one variant's CSV row (and prints the float L2 row's figures); fails only when the
// comparison itself does.
Result<void> benchVariant(const BenchContext& ctx, const BakedRun& baked, Variant variant,
                          std::string& csv) {
    const Run& run = baked.run;
    const baker::BakeResult& r = baked.result;
    const std::string format(toString(variant.storage));
    const std::string order = variant.order == sh::Order::L1 ? "L1" : "L2";
    const std::string prefix = run.method + "," + csvField(run.parameters) + "," + format + "," +
                               order + "," + number(baked.seconds) + "," +
                               std::to_string(r.stats.rays) + ",";
    Result<PvolFile> packed = repack(r.file, variant, ctx.base.dering);
    if (!packed) {
        csv += prefix + "0,nan,nan,nan,nan,nan," + std::to_string(r.stats.invalidProbes) +
               ",nan,nan,nan,nan,nan," + csvField("saturated: " + packed.error().message) + "\n";
        std::fprintf(stderr, "bench [%zu/%zu] %s %s %s %s: %s\n", baked.index + 1, ctx.runCount,
                     run.method.c_str(), run.parameters.c_str(), format.c_str(), order.c_str(),
                     terminalText(packed.error().message).c_str());
        return {};
    }
    Result<runtime::VolumeError> e =
        runtime::compareVolumes(packed.value().volumes, ctx.reference.volumes);
    if (!e) {
        return e.error();
    }
    uint64_t bytes = 0;
    for (const Volume& v : packed.value().volumes) {
        bytes += v.texelBytes();
    }
    const ExtraFigures f = extraFigures(packed.value(), ctx.reference, ctx.dark);
    Result<runtime::SurfaceError> sf = surfaceFigures(packed.value(), ctx.surface);
    if (!sf) {
        return sf.error();
    }
    const runtime::SurfaceError& px = sf.value();
    csv += prefix + std::to_string(bytes) + "," + number(e.value().relRmse) + "," +
           number(e.value().maxProbeErr) + "," + number(e.value().maxAbsErr) + "," +
           number(f.darkRatio) + "," + number(f.negativeFraction) + "," +
           std::to_string(r.stats.invalidProbes) + "," + number(px.medianAbsError) + "," +
           number(px.meanRatio) + "," + number(px.shareUnderHalf) + "," + number(px.shareOverTwo) +
           "," + number(px.shareNegative) + ",ok\n";
    if (variant.storage == Storage::Float32 && variant.order == sh::Order::L2) {
        std::fprintf(stderr,
                     "bench [%zu/%zu] %-4s %-40s %7.2f s  rel RMSE %.4f  worst probe "
                     "%.4f  dark ratio %.3f  per pixel: median %.4f, mean ratio %.3f, "
                     "negative %.4f\n",
                     baked.index + 1, ctx.runCount, run.method.c_str(), run.parameters.c_str(),
                     baked.seconds, e.value().relRmse, e.value().maxProbeErr, f.darkRatio,
                     px.medianAbsError, px.meanRatio, px.shareNegative);
    }
    return {};
}

// Bakes one run of the sweep and appends its rows: one per variant, or one saying why the
// bake failed.
Result<void> benchRun(const BenchContext& ctx, const Run& run, size_t index, std::string& csv) {
    baker::BakeConfig c = ctx.base;
    run.apply(c);
    c.dering = false; // repack derings each variant as its own bake would
    const auto start = std::chrono::steady_clock::now();
    Result<baker::BakeResult> r = baker::bake(ctx.scene, c, ctx.bakeOptions);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!r) {
        // A method that cannot bake this scene is a result too: one row saying why.
        csv += run.method + "," + csvField(run.parameters) + ",,," + number(seconds) +
               ",0,0,nan,nan,nan,nan,nan,0,nan,nan,nan,nan,nan," +
               csvField("bake failed: " + r.error().message) + "\n";
        std::fprintf(stderr, "bench [%zu/%zu] %s %s: bake failed: %s\n", index + 1, ctx.runCount,
                     run.method.c_str(), run.parameters.c_str(),
                     terminalText(r.error().message).c_str());
        return {};
    }
    const BakedRun baked{run, index, seconds, r.value()};
    for (const Variant variant : kVariants) {
        if (auto v = benchVariant(ctx, baked, variant, csv); !v) {
            return v;
        }
    }
    return {};
}

int runBench(const BenchOptions& o) {
    const auto fail = [](const std::string& message) {
        printError("bench", message);
        return kExitFailure;
    };
    Result<baker::BakeConfig> config = benchBaseConfig(o);
    if (!config) {
        return fail(config.error().message);
    }
    const baker::BakeConfig& base = config.value();
    Result<BenchScene> loaded = loadBenchScene(o, base);
    if (!loaded) {
        return fail(loaded.error().message);
    }
    const BenchScene& in = loaded.value();
    baker::BakeOptions bake_options;
    bake_options.threads = o.threads;

    // The reference: reused when it exists (and matches), else baked and written.
    const std::filesystem::path ref_path = referencePath(o);
    Result<PvolFile> reference = std::filesystem::exists(ref_path)
                                     ? reuseReference(ref_path, in, base.seed)
                                     : bakeReference(o, in.scene, base, bake_options, ref_path);
    if (!reference) {
        return fail(reference.error().message);
    }
    const auto dark = darkProbes(reference.value());

    const uint64_t ref_seed = base.seed + kReferenceSeedOffset;
    Result<runtime::SurfaceReferenceImage> surface = surfaceReference(o, in.scene, ref_seed);
    if (!surface) {
        return fail("surface reference: " + surface.error().message);
    }
    reportSurfaceReference(o, surface.value());

    std::string csv = kCsvHeader;
    const std::vector<Run> runs = sweep(o.quick);
    const BenchContext ctx{o,    in.scene,        base,       bake_options, reference.value(),
                           dark, surface.value(), runs.size()};
    for (size_t ri = 0; ri < runs.size(); ++ri) {
        if (auto r = benchRun(ctx, runs[ri], ri, csv); !r) {
            return fail(r.error().message);
        }
        // Rewritten after every run, atomically: an interrupted sweep leaves a complete CSV.
        if (auto w = writeFileAtomic(std::filesystem::path(o.out), csv); !w) {
            return fail(w.error().message);
        }
    }
    std::fprintf(stderr, "bench: wrote %s (%zu runs)\n", o.out.c_str(), runs.size());
    return kExitOk;
}

} // namespace

void addBenchCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<BenchOptions>();
    CLI::App* cmd = app.add_subcommand(
        "bench", "Speed against accuracy: sweep path, VPL and LPV settings against a path "
                 "reference of the same volumes; one CSV row per run (tools/chart draws it)");
    cmd->add_option("SCENE", o->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
    cmd->add_option("--config", o->config,
                    "bake config JSON: volumes, environment, seed and method defaults");
    cmd->add_option("--out", o->out, "results CSV")->required();
    cmd->add_option("--reference", o->reference,
                    "path reference .pvol: reused when it exists and matches the volumes, baked "
                    "there otherwise (default: beside the CSV, NAME-reference.pvol)");
    cmd->add_option("--reference-samples", o->referenceSamples,
                    "samples per probe of a new reference (default 131072, --quick 32768)")
        ->check(CLI::Range(1u, 1u << 24));
    cmd->add_flag("--quick", o->quick,
                  "a shorter sweep and reference (under 2 minutes on the Cornell box)");
    cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)");
    cmd->add_option("--surface-camera-from", o->surfaceView.cameraFrom,
                    "the side of the scene the per-pixel figures' view frames it from (surface_* "
                    "columns; render's --camera-from)")
        ->check(CLI::IsMember({"+x", "-x", "+y", "-y", "+z", "-z"}))
        ->capture_default_str();
    cmd->add_option("--surface-camera", o->surfaceView.camera,
                    "eye_x,eye_y,eye_z,at_x,at_y,at_z of that view instead")
        ->delimiter(',')
        ->expected(6);
    cmd->add_option("--surface-size", o->surfaceView.size, "that view's width,height in pixels")
        ->delimiter(',')
        ->expected(2)
        ->check(CLI::Range(1u, 4096u))
        ->capture_default_str();
    cmd->add_option("--surface-samples", o->surfaceSamples,
                    "cosine directions per pixel of its reference (default 1024, --quick 256)")
        ->check(CLI::Range(1u, 1u << 20));
    cmd->add_option("--scene", o->sceneIndex, "glTF scene index (default: the file's default)");
    cmd->callback([o, &selected] { selected = [o] { return runBench(*o); }; });
}

} // namespace probekit::cli
