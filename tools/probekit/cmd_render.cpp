// `probekit render`: the runtime's headless Vulkan renderer on a glTF scene lit by a .pvol.
//
// The scene is loaded through probekit::baker and put on the renderer by probekit::viewer (the
// scene flattened to triangles and textures, its lights, the environment from --env or the
// .pvol's recorded bake settings, the dynamic GI's sky and cascades), so probekit::runtime
// never sees glTF; images are tone mapped (runtime/tonemap.hpp) and written here with
// OpenImageIO, which the runtime does not link either.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "camera_options.hpp"
#include "commands.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/runtime/dynamic_gi.hpp"
#include "probekit/runtime/gpu_context.hpp"
#include "probekit/runtime/gpu_volumes.hpp"
#include "probekit/runtime/renderer.hpp"
#include "probekit/runtime/tonemap.hpp"
#include "probekit/viewer/scene_gi.hpp"
#include "probekit/viewer/scene_view.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

constexpr int kWarmupFrames = 3;      // lavapipe compiles pipelines on first use
constexpr int kUploadRepetitions = 5; // --bench: uploads timed per volume

struct RenderOptions {
    std::string scene;
    std::string volumes;
    std::string output;
    CameraOptions framing; // --camera, --camera-from, --fov, --size
    std::string view = "shaded";
    float exposure = 0.0f;          // stops, added to the automatic exposure
    bool fixedExposure = false;     // --fixed-exposure: 2^exposure alone
    std::optional<std::string> env; // R,G,B | FILE | none; unset = the bake's environment
    int bench = 0;
    bool directLight = false;
    float normalOffset = 0.0f;
    bool noVisibility = false;
    // --dynamic-gi and its settings (runtime/include/probekit/runtime/dynamic_gi.hpp).
    bool dynamicGi = false;
    std::vector<float> sunPath; // az0, el0, az1, el1 in degrees; empty = the scene's sun
    int frames = 1;
    uint32_t giCascades = 1;
    uint32_t giResolution = 32;
    float giCell = 0.0f; // 0 = the scene's longest side / (resolution - 2)
    uint32_t giIterations = 16;
    uint32_t giBounces = 2;
    std::string giQuality = "l1";
};

// An image render writes, checked (file_io.hpp, checkOutputs) against the files named on its
// command line: the scene file, the volume and an --env map. The scene's buffers and images
// are not among them: the check runs before the scene is loaded.
Result<void> checkRenderOutput(const RenderOptions& o, const std::string& image) {
    const NamedPath outputs[] = {{image, "-o"}};
    std::vector<NamedPath> inputs = {{o.scene, "the scene"}, {o.volumes, "the volume"}};
    if (o.env && o.env->find(',') == std::string::npos && *o.env != "none") {
        inputs.push_back({*o.env, "the environment map"});
    }
    return checkOutputs(outputs, inputs);
}

std::string extensionOf(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

double median(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    const size_t n = values.size();
    return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double millisecondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
}

// How a PNG maps the frame's linear values (runtime/tonemap.hpp): `ev` stops, then the ACES
// filmic curve unless the view's colours are display values already (leak: a [0, 1] ramp).
struct Display {
    float ev = 0.0f;
    bool toneMapped = true;
};

Display chooseDisplay(const RenderOptions& o, const runtime::Frame& frame) {
    Display d;
    d.toneMapped = o.view != "leak";
    d.ev = o.exposure;
    if (d.toneMapped && !o.fixedExposure) {
        d.ev += runtime::autoExposureEv(frame.color);
    }
    return d;
}

// Writes RGB as 8-bit sRGB PNG (Display's mapping) or float EXR (linear, scaled by 2^--exposure
// only, so its values stay radiance or irradiance), atomically (writeFileAtomic). `error` gets a
// message that names the path.
bool writeImage(const std::string& path, const runtime::Frame& frame, const RenderOptions& o,
                const Display& display, std::string& error) {
    const std::string ext = extensionOf(path);
    const bool png = ext == ".png";
    const float scale = std::exp2(o.exposure);
    const size_t pixels = size_t(frame.width) * frame.height;
    std::vector<float> linear(png ? 0 : pixels * 3);
    std::vector<uint8_t> encoded(png ? pixels * 3 : 0);
    const float display_scale = std::exp2(display.ev);
    for (size_t i = 0; i < pixels; ++i) {
        const glm::vec3 c(frame.color[i]);
        if (!png) {
            for (int k = 0; k < 3; ++k) {
                linear[3 * i + size_t(k)] = c[k] * scale;
            }
            continue;
        }
        const glm::vec3 shown =
            display.toneMapped ? runtime::toneMap(c, display.ev) : c * display_scale;
        for (int k = 0; k < 3; ++k) {
            encoded[3 * i + size_t(k)] =
                uint8_t(std::lround(runtime::srgbEncode(shown[k]) * 255.0f));
        }
    }
    // Encoded in memory and written by writeFileAtomic, so an image follows the same output rule
    // (regular files only, links followed) and interrupt cleanup as every other output.
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(png ? "png" : "openexr");
    if (!out) {
        error = path + ": no OpenImageIO writer for " + ext + " (" + OIIO::geterror() + ")";
        return false;
    }
    OIIO::ImageSpec spec(int(frame.width), int(frame.height), 3,
                         png ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
    if (png) {
        spec.attribute("oiio:ColorSpace", "sRGB");
    }
    const bool ok = out->set_ioproxy(&proxy) && out->open(path, spec) &&
                    (png ? out->write_image(OIIO::TypeDesc::UINT8, encoded.data())
                         : out->write_image(OIIO::TypeDesc::FLOAT, linear.data())) &&
                    out->close();
    if (!ok) {
        error = path + ": cannot encode the image (" + out->geterror() + ")";
        return false;
    }
    if (Result<void> written = writeFileAtomic(path, std::span<const uint8_t>(bytes)); !written) {
        error = written.error().message;
        return false;
    }
    return true;
}

int fail(const std::string& message) {
    printError("render", message);
    return kExitFailure;
}

void dropVisibility(std::vector<Volume>& volumes) {
    for (Volume& v : volumes) {
        v.visibility.clear(); // plain trilinear interpolation
    }
}

// The scene, its loader's warnings printed.
Result<baker::Scene> loadScene(const RenderOptions& o) {
    Result<baker::Scene> scene = baker::loadGltf(o.scene);
    if (scene) {
        for (const std::string& w : scene.value().warnings) {
            printError("render", "warning: " + w);
        }
    }
    return scene;
}

// The .pvol (its volumes without visibility under --no-visibility), as many volumes as the
// runtime takes.
Result<PvolFile> loadVolumes(const RenderOptions& o) {
    Result<PvolFile> file = readPvol(o.volumes);
    if (!file) {
        return file.error();
    }
    std::vector<Volume>& volumes = file.value().volumes;
    if (o.noVisibility) {
        dropVisibility(volumes);
    }
    if (volumes.empty() || volumes.size() > runtime::kMaxGpuVolumes) {
        return makeError(ErrorCode::OutOfRange, o.volumes + ": " + std::to_string(volumes.size()) +
                                                    " volumes; the Vulkan runtime renders 1.." +
                                                    std::to_string(runtime::kMaxGpuVolumes));
    }
    return std::move(file.value());
}

// A Vulkan context whose warnings and errors are printed.
Result<std::unique_ptr<runtime::GpuContext>> createContext() {
    runtime::ContextOptions context_options;
    context_options.onMessage = [](runtime::MessageSeverity severity, std::string_view message) {
        if (severity != runtime::MessageSeverity::Info) {
            printError("render", "vulkan: " + std::string(message));
        }
    };
    return runtime::GpuContext::create(context_options);
}

// The volumes on the GPU, with the --normal-offset; errors name the .pvol.
Result<runtime::GpuVolumeSet> uploadVolumes(runtime::GpuContext& gpu,
                                            const std::vector<Volume>& volumes,
                                            const RenderOptions& o) {
    Result<runtime::GpuVolumeSet> set = runtime::GpuVolumeSet::create(gpu, volumes);
    if (!set) {
        return makeError(set.error().code, o.volumes + ": " + set.error().message);
    }
    set.value().setNormalOffset(o.normalOffset);
    return set;
}

// The environment drawn behind the geometry: --env (R,G,B constant radiance, a lat-long FILE,
// or none), else the one the volumes were baked with as the .pvol's settings record it (none
// when they record none; black with a warning for a file outside the scene's folder and the
// .pvol's, or one that no longer loads). Both go through the bake
// config's own parsing, so --env means here what it means to probekit bake.
Result<Environment> chooseEnvironment(const RenderOptions& o, const BakeMetadata& metadata) {
    if (o.env) {
        return viewer::environmentFromSpec(*o.env, "--env");
    }
    // The .pvol is untrusted: the file it records is opened only in the scene's folder or its
    // own (ARCHITECTURE.md, the folder rule).
    std::vector<std::filesystem::path> roots;
    for (const std::string& chosen : {o.scene, o.volumes}) {
        std::error_code ec;
        const std::filesystem::path file = std::filesystem::absolute(chosen, ec);
        if (!chosen.empty() && !ec) {
            roots.push_back(file.parent_path());
        }
    }
    std::string warning;
    Result<Environment> recorded = viewer::recordedEnvironment(
        metadata, o.volumes + " (its recorded bake settings)", roots, warning);
    if (!warning.empty()) {
        printError("render", "warning: " + warning);
    }
    return recorded;
}

// The scene as the renderer's triangles, its warnings printed.
viewer::RenderScene flatten(const baker::Scene& scene) {
    viewer::RenderScene flat = viewer::flattenScene(scene);
    for (const std::string& w : flat.warnings) {
        printError("render", "warning: " + w);
    }
    return flat;
}

// A renderer drawing the scene's triangles with their textures, in front of the environment.
Result<runtime::Renderer> createRenderer(runtime::GpuContext& gpu, const viewer::RenderScene& flat,
                                         const Environment& environment) {
    Result<runtime::Renderer> renderer = runtime::Renderer::create(gpu);
    if (!renderer) {
        return renderer;
    }
    if (auto r = viewer::uploadScene(renderer.value(), flat); !r) {
        return r.error();
    }
    if (auto r = renderer.value().setEnvironment(environment); !r) {
        return r.error();
    }
    return renderer;
}

// The scene's punctual lights for --direct-light: those the bake left out (light modes), as many
// as the renderer takes.
Result<std::vector<PunctualLight>> directLights(const RenderOptions& o, const baker::Scene& scene,
                                                const BakeMetadata& metadata) {
    Result<viewer::LightSelection> selection =
        viewer::directLights(scene, metadata, o.volumes.empty() ? o.scene : o.volumes);
    if (!selection) {
        return selection.error();
    }
    const viewer::LightSelection& s = selection.value();
    if (s.dropped > 0) {
        printError("render", "warning: " + o.scene + ": only the first " +
                                 std::to_string(runtime::kMaxRenderLights) +
                                 " lights add direct light");
    }
    if (s.lights.empty()) {
        printError("render", "warning: --direct-light: the volumes hold the direct light of all " +
                                 std::to_string(s.baked) +
                                 " of the scene's lights (light mode baked); nothing is added");
    }
    return s.lights;
}

// The frame the options ask for: size, camera, view and direct light.
Result<runtime::FrameSettings> frameSettings(const RenderOptions& o, const baker::Scene& scene,
                                             const std::vector<Volume>& volumes,
                                             const BakeMetadata& metadata) {
    runtime::FrameSettings settings;
    settings.width = o.framing.size[0];
    settings.height = o.framing.size[1];
    const float aspect = float(settings.width) / float(settings.height);
    Result<runtime::Camera> camera =
        chooseCamera(o.framing, viewer::framedBox(scene, volumes), aspect);
    if (!camera) {
        return camera.error();
    }
    settings.camera = camera.value();
    const std::string views[] = {"shaded", "irradiance", "probes",      "validity",
                                 "leak",   "gi-lpv",     "gi-geometry", "gi-ao"};
    settings.view = runtime::RenderView(std::find(std::begin(views), std::end(views), o.view) -
                                        std::begin(views));
    settings.directLight = o.directLight;
    if (o.directLight) {
        Result<std::vector<PunctualLight>> lights = directLights(o, scene, metadata);
        if (!lights) {
            return lights.error();
        }
        settings.lights = std::move(lights.value());
    }
    return settings;
}

// --bench's GPU times per frame, for each volume set ([0] the volumes as given, [1] the same
// without visibility when they have it).
struct FrameTimes {
    std::vector<double> gbufferMs;
    std::vector<double> shadeMs[2];
    std::vector<double> fetchOnlyMs[2];
    runtime::ProbeStats probes; // the probes and validity views' selection
};

Result<FrameTimes> timeFrames(runtime::Renderer& renderer,
                              const std::vector<runtime::GpuVolumeSet*>& sets,
                              runtime::FrameSettings timed, int frames) {
    timed.readbackColor = false;
    // Warm-up: pipelines compile on first use (lavapipe) and caches fill.
    for (int i = 0; i < kWarmupFrames; ++i) {
        for (runtime::GpuVolumeSet* s : sets) {
            for (bool fetch_only : {false, true}) {
                timed.fetchOnly = fetch_only;
                if (auto r = renderer.render(*s, timed); !r) {
                    return r.error();
                }
            }
        }
    }
    // Shading and fetch-only frames (of each set) alternate, so all see the same machine load.
    FrameTimes out;
    for (int i = 0; i < frames; ++i) {
        for (size_t k = 0; k < sets.size(); ++k) {
            for (bool fetch_only : {false, true}) {
                timed.fetchOnly = fetch_only;
                Result<runtime::Frame> frame = renderer.render(*sets[k], timed);
                if (!frame) {
                    return frame.error();
                }
                (fetch_only ? out.fetchOnlyMs : out.shadeMs)[k].push_back(
                    frame.value().timings.shadeMs);
                if (!fetch_only && k == 0) {
                    out.gbufferMs.push_back(frame.value().timings.gbufferMs);
                    out.probes = frame.value().probes;
                }
            }
        }
    }
    return out;
}

// --bench's upload throughput: re-uploading every volume (staging copy + GPU copy + wait)
// against a plain memcpy of the same bytes; medians in milliseconds.
struct UploadTimes {
    size_t bytes = 0;
    double uploadMs = 0.0;
    double memcpyMs = 0.0;
};

Result<UploadTimes> timeUploads(runtime::GpuVolumeSet& set, const std::vector<Volume>& volumes) {
    UploadTimes out;
    for (const Volume& v : volumes) {
        out.bytes += v.texelBytes() + v.visibilityGpuBytes();
    }
    std::vector<double> upload_ms, memcpy_ms;
    std::vector<uint8_t> source(out.bytes, 1);
    std::vector<uint8_t> destination(out.bytes);
    for (int r = 0; r < kUploadRepetitions; ++r) {
        const auto start = std::chrono::steady_clock::now();
        for (size_t i = 0; i < volumes.size(); ++i) {
            if (auto u = set.replaceVolume(i, volumes[i]); !u) {
                return u.error();
            }
        }
        upload_ms.push_back(millisecondsSince(start));
        const auto copy_start = std::chrono::steady_clock::now();
        std::memcpy(destination.data(), source.data(), out.bytes);
        memcpy_ms.push_back(millisecondsSince(copy_start));
        source[size_t(r) % out.bytes] ^= destination[out.bytes - 1];
    }
    out.uploadMs = median(upload_ms);
    out.memcpyMs = std::max(median(memcpy_ms), 1e-6);
    return out;
}

// What --bench prints, one JSON object.
struct BenchRun {
    std::string device;
    size_t volumes = 0;
    double createMs = 0.0; // the first upload, GpuVolumeSet::create
    bool visibility = false;
    FrameTimes frames;
    UploadTimes uploads;
};

nlohmann::json benchReport(const RenderOptions& o, const runtime::FrameSettings& settings,
                           const BenchRun& run) {
    const double shade = median(run.frames.shadeMs[0]);
    const double fetch = median(run.frames.fetchOnlyMs[0]);
    const double upload = run.uploads.uploadMs;
    const double copy = run.uploads.memcpyMs;
    nlohmann::json bench = {{"device", run.device},
                            {"width", settings.width},
                            {"height", settings.height},
                            {"view", o.view},
                            {"volumes", run.volumes},
                            {"frames", o.bench},
                            {"gbuffer_ms", median(run.frames.gbufferMs)},
                            {"shade_ms", shade},
                            {"fetch_only_ms", fetch},
                            {"shade_over_fetch", shade / fetch},
                            {"create_ms", run.createMs},
                            {"upload_bytes", run.uploads.bytes},
                            {"upload_ms", upload},
                            {"memcpy_ms", copy},
                            {"upload_gb_per_s", double(run.uploads.bytes) / (upload * 1e6)},
                            {"memcpy_gb_per_s", double(run.uploads.bytes) / (copy * 1e6)},
                            {"upload_over_memcpy", upload / copy},
                            {"visibility", run.visibility}};
    if (run.frames.probes.budget > 0) {
        bench["probes_total"] = run.frames.probes.total;
        bench["probes_in_view"] = run.frames.probes.inView;
        bench["probes_drawn"] = run.frames.probes.drawn;
        bench["probe_budget"] = run.frames.probes.budget;
        bench["probe_stride"] = run.frames.probes.stride;
    }
    if (run.visibility) {
        const double plain_shade = median(run.frames.shadeMs[1]);
        const double plain_fetch = median(run.frames.fetchOnlyMs[1]);
        bench["shade_no_visibility_ms"] = plain_shade;
        bench["fetch_only_no_visibility_ms"] = plain_fetch;
        bench["shade_visibility_over_none"] = shade / plain_shade;
        bench["fetch_only_visibility_over_none"] = fetch / plain_fetch;
    }
    return bench;
}

// --bench N: N timed frames of the shading pass and its fetch-only floor (with visibility, of
// the same volumes without it as well: a second set, so the two are compared on the same
// data), then the upload; the report.
Result<nlohmann::json> runBench(const RenderOptions& o, runtime::GpuContext& gpu,
                                runtime::Renderer& renderer, runtime::GpuVolumeSet& set,
                                const std::vector<Volume>& volumes,
                                const runtime::FrameSettings& settings, double create_ms) {
    BenchRun run;
    run.device = gpu.deviceInfo().name;
    run.volumes = volumes.size();
    run.createMs = create_ms;
    run.visibility = std::any_of(volumes.begin(), volumes.end(),
                                 [](const Volume& v) { return v.hasVisibility(); });
    std::vector<runtime::GpuVolumeSet*> sets{&set};
    std::optional<runtime::GpuVolumeSet> plain_set;
    if (run.visibility) {
        std::vector<Volume> plain = volumes;
        dropVisibility(plain);
        Result<runtime::GpuVolumeSet> created = uploadVolumes(gpu, plain, o);
        if (!created) {
            return created.error();
        }
        plain_set.emplace(std::move(created.value()));
        sets.push_back(&*plain_set);
    }
    Result<FrameTimes> frames = timeFrames(renderer, sets, settings, o.bench);
    if (!frames) {
        return frames.error();
    }
    run.frames = std::move(frames.value());
    Result<UploadTimes> uploads = timeUploads(set, volumes);
    if (!uploads) {
        return uploads.error();
    }
    run.uploads = uploads.value();
    return benchReport(o, settings, run);
}

// --direct-light's shadows: a first frame's G-buffer, each pixel's shadow rays to the lights
// traced on the CPU with the baker's ray tracer (viewer::lightVisibility), the masks kept in
// `settings` for the frame that is written.
Result<void> traceShadows(const baker::Scene& scene, runtime::Renderer& renderer,
                          runtime::GpuVolumeSet& set, runtime::FrameSettings& settings) {
    if (!settings.directLight || settings.lights.empty()) {
        return {};
    }
    runtime::FrameSettings gbuffer = settings;
    gbuffer.readbackColor = false;
    gbuffer.readbackGBuffer = true;
    Result<runtime::Frame> frame = renderer.render(set, gbuffer);
    if (!frame) {
        return frame.error();
    }
    Result<std::vector<uint32_t>> masks =
        viewer::lightVisibility(scene, frame.value(), settings.lights);
    if (!masks) {
        return masks.error();
    }
    settings.lightVisibility = std::move(masks.value());
    return {};
}

// The frame itself: rendered, written, and reported (the --bench report, or one line).
int renderAndWrite(const RenderOptions& o, const runtime::GpuContext& gpu,
                   runtime::Renderer& renderer, runtime::GpuVolumeSet& set,
                   const runtime::FrameSettings& settings, size_t volume_count,
                   const std::optional<nlohmann::json>& bench) {
    Result<runtime::Frame> frame = renderer.render(set, settings);
    if (!frame) {
        return fail(frame.error().message);
    }
    std::string error;
    const Display display = chooseDisplay(o, frame.value());
    if (!writeImage(o.output, frame.value(), o, display, error)) {
        return fail(error);
    }
    if (bench) {
        std::printf("%s\n", jsonText(*bench).c_str());
        return kExitOk;
    }
    std::printf("wrote %s: %ux%u, %s view, %zu volume%s on %s; G-buffer %.2f ms, shading "
                "%.2f ms\n",
                terminalText(o.output).c_str(), settings.width, settings.height, o.view.c_str(),
                volume_count, volume_count == 1 ? "" : "s", gpu.deviceInfo().name.c_str(),
                frame.value().timings.gbufferMs, frame.value().timings.shadeMs);
    if (extensionOf(o.output) == ".png") {
        std::printf("  display: %s, exposure %+.2f EV (%s)\n",
                    display.toneMapped ? "ACES filmic" : "no tone curve", double(display.ev),
                    o.fixedExposure || !display.toneMapped ? "fixed" : "auto + --exposure");
    }
    const runtime::ProbeStats& p = frame.value().probes;
    if (p.budget > 0) {
        std::printf("  probes: drew %llu of %llu (%llu in view; budget %u, every %u%s)\n",
                    static_cast<unsigned long long>(p.drawn),
                    static_cast<unsigned long long>(p.total),
                    static_cast<unsigned long long>(p.inView), p.budget, p.stride,
                    p.stride == 1 ? "" : " along each lattice axis");
    }
    return kExitOk;
}

int runRender(const RenderOptions& o) {
    if (o.volumes.empty()) {
        return fail("render: VOLUME is required (without --dynamic-gi)");
    }
    if (!o.sunPath.empty() || o.frames != 1) {
        return fail("render: --sun-path and --frames need --dynamic-gi");
    }
    // A bad -o fails before any work, and never names an input.
    if (Result<void> checked = checkRenderOutput(o, o.output); !checked) {
        return fail(checked.error().message);
    }
    Result<baker::Scene> scene = loadScene(o);
    if (!scene) {
        return fail(scene.error().message);
    }
    Result<PvolFile> file = loadVolumes(o);
    if (!file) {
        return fail(file.error().message);
    }
    const std::vector<Volume>& volumes = file.value().volumes;
    const BakeMetadata& metadata = file.value().metadata;
    Result<std::unique_ptr<runtime::GpuContext>> context = createContext();
    if (!context) {
        return fail(context.error().message);
    }
    runtime::GpuContext& gpu = *context.value();
    const auto upload_start = std::chrono::steady_clock::now();
    Result<runtime::GpuVolumeSet> set = uploadVolumes(gpu, volumes, o);
    if (!set) {
        return fail(set.error().message);
    }
    const double create_ms = millisecondsSince(upload_start);
    Result<Environment> environment = chooseEnvironment(o, metadata);
    if (!environment) {
        return fail(environment.error().message);
    }
    Result<runtime::Renderer> renderer =
        createRenderer(gpu, flatten(scene.value()), environment.value());
    if (!renderer) {
        return fail(renderer.error().message);
    }
    Result<runtime::FrameSettings> settings = frameSettings(o, scene.value(), volumes, metadata);
    if (!settings) {
        return fail(settings.error().message);
    }
    if (Result<void> shadows =
            traceShadows(scene.value(), renderer.value(), set.value(), settings.value());
        !shadows) {
        return fail(shadows.error().message);
    }
    std::optional<nlohmann::json> bench;
    if (o.bench > 0) {
        Result<nlohmann::json> report =
            runBench(o, gpu, renderer.value(), set.value(), volumes, settings.value(), create_ms);
        if (!report) {
            return fail(report.error().message);
        }
        bench = std::move(report.value());
    }
    return renderAndWrite(o, gpu, renderer.value(), set.value(), settings.value(), volumes.size(),
                          bench);
}

// ---- --dynamic-gi ----

// -o for frame f: one %d or %0Nd in the path is replaced by f (no other % is accepted, so the
// path is never a format string).
Result<std::string> framePath(const std::string& pattern, int f) {
    const size_t at = pattern.find('%');
    if (at == std::string::npos) {
        return pattern;
    }
    size_t i = at + 1;
    size_t width = 0;
    while (i < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[i]))) {
        width = width * 10 + size_t(pattern[i] - '0');
        ++i;
    }
    if (i >= pattern.size() || pattern[i] != 'd' || width > 9 ||
        pattern.find('%', i + 1) != std::string::npos) {
        return makeError(ErrorCode::InvalidArgument,
                         "-o " + pattern +
                             ": the frame number is written as %d or %0Nd (N <= 9), "
                             "once; no other % is allowed");
    }
    std::string number = std::to_string(f);
    if (number.size() < width) {
        number.insert(0, width - number.size(), '0');
    }
    return pattern.substr(0, at) + number + pattern.substr(i + 1);
}

// The direction the sun's light travels at frame f of --frames along --sun-path.
glm::vec3 sunTravel(const RenderOptions& o, int f) {
    const float t = o.frames > 1 ? float(f) / float(o.frames - 1) : 0.0f;
    return viewer::sunTravel({o.sunPath[0], o.sunPath[1], o.sunPath[2], o.sunPath[3]}, t);
}

double medianOf(std::vector<double> v) {
    return v.empty() ? std::numeric_limits<double>::quiet_NaN() : median(std::move(v));
}

// The inputs of a dynamic-GI render: the scene and its volumes (a placeholder without a .pvol).
struct GiInputs {
    baker::Scene scene;
    bool baked = false;
    std::vector<Volume> volumes;
    BakeMetadata metadata;
};

// The scene and the volumes --dynamic-gi renders, once -o is known to name a writable path.
Result<GiInputs> loadGiInputs(const RenderOptions& o) {
    Result<std::string> first_path = framePath(o.output, 0);
    if (!first_path) {
        return first_path.error();
    }
    if (Result<void> checked = checkRenderOutput(o, first_path.value()); !checked) {
        return checked.error();
    }
    Result<baker::Scene> loaded = loadScene(o);
    if (!loaded) {
        return loaded.error();
    }
    GiInputs in;
    in.scene = std::move(loaded.value());
    if (!in.scene.hasGeometry()) {
        return makeError(ErrorCode::InvalidArgument,
                         o.scene + ": no triangles; dynamic GI relights geometry");
    }
    in.baked = !o.volumes.empty();
    if (in.baked) {
        Result<PvolFile> file = loadVolumes(o);
        if (!file) {
            return file.error();
        }
        in.volumes = std::move(file.value().volumes);
        in.metadata = file.value().metadata;
    } else {
        Result<Volume> placeholder = viewer::placeholderVolume(in.scene);
        if (!placeholder) {
            return placeholder.error();
        }
        in.volumes.push_back(std::move(placeholder.value()));
    }
    return in;
}

// The cascades the --gi-* options ask for: by default one holds the scene, centred on it; with
// --gi-cell they follow the camera, centred ahead of it (the library's default).
runtime::DynamicGiSettings giSettingsFor(const RenderOptions& o, const baker::Scene& scene) {
    runtime::DynamicGiSettings gi_settings;
    gi_settings.cascades = o.giCascades;
    gi_settings.resolution = o.giResolution;
    gi_settings.iterations = o.giIterations;
    gi_settings.bounces = o.giBounces;
    gi_settings.quality =
        o.giQuality == "zonal" ? runtime::GiQuality::L1Zonal : runtime::GiQuality::L1;
    if (o.giCell > 0.0f) {
        gi_settings.cellSize = o.giCell;
        return gi_settings;
    }
    return viewer::fitCascades(gi_settings, scene);
}

// What the dynamic-GI frames and --bench share, made once by runRenderDynamicGi.
struct GiRun {
    const RenderOptions& o;
    runtime::GpuContext& gpu;
    runtime::Renderer& renderer;
    runtime::GpuVolumeSet& set;
    runtime::DynamicGi& gi;
    const runtime::DynamicGiSettings& giSettings;
    const viewer::RenderScene& flat;
    runtime::FrameSettings& settings; // the frames' last lights stay in it for --bench
    viewer::DynamicLights& lights;
    bool baked;
};

// Renders and writes the --frames frames, the sun moved along --sun-path and the GI updated
// for each.
Result<void> renderGiFrames(GiRun& run) {
    const RenderOptions& o = run.o;
    for (int f = 0; f < o.frames; ++f) {
        if (!o.sunPath.empty()) {
            run.lights.sunLight()->direction = sunTravel(o, f);
        }
        if (auto r = run.gi.setLights(run.lights.lights); !r) {
            return r;
        }
        Result<runtime::GiUpdateStats> stats = run.gi.update(uint64_t(f));
        if (!stats) {
            return stats.error();
        }
        const runtime::GiShadingInputs inputs = run.gi.shadingInputs();
        run.settings.dynamicGi = &inputs;
        run.settings.lights = run.lights.lights;
        Result<runtime::Frame> frame = run.renderer.render(run.set, run.settings);
        if (!frame) {
            return frame.error();
        }
        Result<std::string> path = framePath(o.output, f);
        std::string error;
        const Display display = chooseDisplay(o, frame.value());
        if (!writeImage(path.value(), frame.value(), o, display, error)) {
            return makeError(ErrorCode::Io, error);
        }
        const runtime::GiTimings t = run.gi.timings();
        if (o.bench == 0) {
            std::printf("wrote %s: frame %d, %s view; GI %u dispatches (%u cascades), "
                        "occupancy %.2f ms, inject %.2f ms, propagate %.2f ms, resolve %.2f ms; "
                        "shading %.2f ms\n",
                        terminalText(path.value()).c_str(), f, o.view.c_str(),
                        stats.value().dispatches, stats.value().cascadesUpdated, t.occupancyMs,
                        t.injectMs, t.propagateMs, t.resolveMs, frame.value().timings.shadeMs);
        }
    }
    return {};
}

// --bench's GPU times in milliseconds, one per timed update or frame.
struct GiBenchTimes {
    std::vector<double> occupancy, inject, propagate, resolve, shade, shadeBaked;
};

// N updates, each with the sun turned by twice the threshold so every one is a full relight
// (the geometry volume is rebuilt once, by the first: it is timed apart).
Result<void> timeGiUpdates(GiRun& run, GiBenchTimes& times) {
    const RenderOptions& o = run.o;
    PunctualLight* moving = run.lights.sunLight();
    for (int i = 0; i < o.bench + kWarmupFrames; ++i) {
        if (moving) {
            const float angle = 2.0f * run.giSettings.angleThreshold * float(i % 2 == 0 ? 1 : -1);
            const glm::vec3 d = moving->direction;
            moving->direction = glm::vec3(d.x * std::cos(angle) - d.z * std::sin(angle), d.y,
                                          d.x * std::sin(angle) + d.z * std::cos(angle));
            if (auto r = run.gi.setLights(run.lights.lights); !r) {
                return r;
            }
        } else if (auto r = run.gi.setGeometry(run.flat.vertices, run.flat.indices); !r) {
            return r;
        }
        Result<runtime::GiUpdateStats> stats = run.gi.update(uint64_t(o.frames + i));
        if (!stats) {
            return stats.error();
        }
        const runtime::GiTimings t = run.gi.timings();
        if (i >= kWarmupFrames) {
            if (stats.value().geometryRebuilt) {
                times.occupancy.push_back(t.occupancyMs);
            }
            times.inject.push_back(t.injectMs);
            times.propagate.push_back(t.propagateMs);
            times.resolve.push_back(t.resolveMs);
        }
    }
    return {};
}

// The geometry volume alone, when no timed update rebuilt it: rebuilt by a geometry change.
Result<void> timeGiOccupancy(GiRun& run, GiBenchTimes& times) {
    const RenderOptions& o = run.o;
    for (int i = 0; i < std::min(o.bench, 8) && times.occupancy.empty(); ++i) {
        if (auto r = run.gi.setGeometry(run.flat.vertices, run.flat.indices); !r) {
            return r;
        }
        Result<runtime::GiUpdateStats> stats =
            run.gi.update(uint64_t(o.frames + o.bench + kWarmupFrames + i));
        if (!stats) {
            return stats.error();
        }
        times.occupancy.push_back(run.gi.timings().occupancyMs);
    }
    return {};
}

// N frames shaded with the GI and, with a volume, N of the baked-only pass.
Result<void> timeGiShading(GiRun& run, GiBenchTimes& times) {
    const runtime::GiShadingInputs inputs = run.gi.shadingInputs();
    for (int i = 0; i < run.o.bench + kWarmupFrames; ++i) {
        for (int pass = 0; pass < (run.baked ? 2 : 1); ++pass) {
            runtime::FrameSettings s = run.settings;
            s.readbackColor = false;
            s.dynamicGi = pass == 0 ? &inputs : nullptr;
            Result<runtime::Frame> frame = run.renderer.render(run.set, s);
            if (!frame) {
                return frame.error();
            }
            if (i >= kWarmupFrames) {
                (pass == 0 ? times.shade : times.shadeBaked)
                    .push_back(frame.value().timings.shadeMs);
            }
        }
    }
    return {};
}

// Prints --bench's medians as one JSON line.
void printGiBench(const GiRun& run, const GiBenchTimes& times) {
    const runtime::DynamicGiSettings& gi_settings = run.giSettings;
    nlohmann::json bench = {{"device", run.gpu.deviceInfo().name},
                            {"width", run.settings.width},
                            {"height", run.settings.height},
                            {"view", run.o.view},
                            {"frames", run.o.bench},
                            {"gi_cascades", gi_settings.cascades},
                            {"gi_resolution", gi_settings.resolution},
                            {"gi_iterations", gi_settings.iterations},
                            {"gi_bounces", gi_settings.bounces},
                            {"gi_gpu_mib", double(run.gi.gpuBytes()) / (1024.0 * 1024.0)},
                            {"gi_occupancy_ms", medianOf(times.occupancy)},
                            {"gi_inject_ms", medianOf(times.inject)},
                            {"gi_propagate_ms", medianOf(times.propagate)},
                            {"gi_resolve_ms", medianOf(times.resolve)},
                            {"gi_relight_ms", medianOf(times.inject) + medianOf(times.propagate) +
                                                  medianOf(times.resolve)},
                            {"shade_ms", medianOf(times.shade)}};
    if (run.baked) {
        bench["shade_baked_only_ms"] = medianOf(times.shadeBaked);
    }
    std::printf("%s\n", jsonText(bench).c_str());
}

// --bench N: the GI's relight and geometry times, then the shading pass's, printed as JSON.
Result<void> benchDynamicGi(GiRun& run) {
    GiBenchTimes times;
    if (auto r = timeGiUpdates(run, times); !r) {
        return r;
    }
    if (auto r = timeGiOccupancy(run, times); !r) {
        return r;
    }
    if (auto r = timeGiShading(run, times); !r) {
        return r;
    }
    printGiBench(run, times);
    return {};
}

int runRenderDynamicGi(const RenderOptions& o) {
    Result<GiInputs> inputs = loadGiInputs(o);
    if (!inputs) {
        return fail(inputs.error().message);
    }
    const GiInputs& in = inputs.value();
    const baker::Scene& scene = in.scene;
    Result<std::unique_ptr<runtime::GpuContext>> context = createContext();
    if (!context) {
        return fail(context.error().message);
    }
    runtime::GpuContext& gpu = *context.value();
    Result<runtime::GpuVolumeSet> set = uploadVolumes(gpu, in.volumes, o);
    if (!set) {
        return fail(set.error().message);
    }
    Result<Environment> environment = chooseEnvironment(o, in.metadata);
    if (!environment) {
        return fail(environment.error().message);
    }
    const viewer::RenderScene flat = flatten(scene);
    Result<runtime::Renderer> renderer = createRenderer(gpu, flat, environment.value());
    if (!renderer) {
        return fail(renderer.error().message);
    }
    Result<runtime::FrameSettings> frame_settings =
        frameSettings(o, scene, in.volumes, in.metadata);
    if (!frame_settings) {
        return fail(frame_settings.error().message);
    }
    runtime::FrameSettings settings = frame_settings.value();
    viewer::DynamicLights lights = viewer::dynamicLights(scene, in.baked, !o.sunPath.empty());
    if (lights.lights.empty() && environment.value().isBlack()) {
        printError("render", "warning: " + o.scene +
                                 ": no dynamic light (no directional light, no --sun-path) and "
                                 "no sky: the dynamic GI stays black");
    }
    const runtime::DynamicGiSettings gi_settings = giSettingsFor(o, scene);
    Result<runtime::DynamicGi> gi = runtime::DynamicGi::create(gpu, gi_settings);
    if (!gi) {
        return fail(gi.error().message);
    }
    if (auto r = viewer::prepareGi(gi.value(), flat, scene, environment.value(), settings.camera,
                                   o.giCell <= 0.0f);
        !r) {
        return fail(r.error().message);
    }
    settings.dynamicGi = nullptr;
    settings.bakedLight = in.baked;
    settings.directLight = true;
    GiRun run{o,           gpu,  renderer.value(), set.value(), gi.value(),
              gi_settings, flat, settings,         lights,      in.baked};
    if (auto r = renderGiFrames(run); !r) {
        return fail(r.error().message);
    }
    if (o.bench == 0) {
        return kExitOk;
    }
    if (auto r = benchDynamicGi(run); !r) {
        return fail(r.error().message);
    }
    return kExitOk;
}

// The scene, the volumes and the image to write, with its framing.
void addRenderInputOptions(CLI::App* cmd, RenderOptions& o) {
    cmd->add_option("SCENE", o.scene, "glTF scene (.gltf or .glb)")->required();
    cmd->add_option("VOLUME", o.volumes,
                    "the .pvol lighting it (optional with --dynamic-gi: dynamic GI alone)");
    cmd->add_option("-o,--output", o.output, "image to write: .png (8-bit sRGB) or .exr (float)")
        ->required()
        ->check([](const std::string& path) {
            const std::string ext = extensionOf(path);
            return ext == ".png" || ext == ".exr" ? std::string()
                                                  : "the output must end in .png or .exr";
        });
    addCameraOptions(cmd, o.framing);
}

// What the image shows, its exposure and what is drawn where no geometry is.
void addRenderViewOptions(CLI::App* cmd, RenderOptions& o) {
    cmd->add_option("--view", o.view,
                    "shaded (albedo/pi x E + emission), irradiance (E, W/m^2), probes (spheres "
                    "lit by their own SH; for bricked volumes flat spheres coloured by brick "
                    "level: 0 blue, 1 green, 2 yellow, 3 magenta), validity (invalid probes "
                    "red), leak (the visible share v of the interpolation weight as (1, v, v): "
                    "white where no probe is hidden, red where all are; white everywhere "
                    "without visibility data); with --dynamic-gi also gi-lpv (the cascades' "
                    "irradiance alone, W/m^2), gi-geometry (the geometry volume's albedo x "
                    "coverage) and gi-ao (its openness in front of the surface)")
        ->check(CLI::IsMember({"shaded", "irradiance", "probes", "validity", "leak", "gi-lpv",
                               "gi-geometry", "gi-ao"}))
        ->capture_default_str();
    cmd->add_option("--exposure", o.exposure,
                    "stops added to the exposure: PNG scales by 2^(auto EV + EV) before the ACES "
                    "filmic curve (auto EV brings the log-average luminance to 0.18); EXR is "
                    "linear, scaled by 2^EV alone")
        ->capture_default_str();
    cmd->add_flag("--fixed-exposure", o.fixedExposure,
                  "no automatic exposure: PNG scales by 2^EV alone before the tone curve");
    cmd->add_option("--env", o.env,
                    "background where no geometry is (shaded and probes views): constant "
                    "radiance R,G,B (W/sr/m^2), a lat-long image FILE, or none (default: the "
                    "environment the volumes were baked with, from the .pvol's settings)");
}

// --bench and the options that change how the volumes are sampled and lit.
void addRenderShadingOptions(CLI::App* cmd, RenderOptions& o) {
    cmd->add_option("--bench", o.bench,
                    "after warm-up, time N frames of the shading pass and of its fetch-only "
                    "floor, and the volume upload; print one JSON line. Volumes with visibility "
                    "are also timed without it (frames alternating): shade_no_visibility_ms, "
                    "shade_visibility_over_none")
        ->check(CLI::Range(1, 100000));
    cmd->add_flag("--no-visibility", o.noVisibility,
                  "drop the volumes' visibility data before upload: plain trilinear "
                  "interpolation, as for volumes baked without it (compare with and without)");
    cmd->add_flag("--direct-light", o.directLight,
                  "add the direct light of the scene's punctual lights the volumes left out "
                  "(light modes indirect and none; every light for files that record no "
                  "modes), shadowed by rays traced on the CPU from the G-buffer (with "
                  "--dynamic-gi: unshadowed, but directional lights shadowed by the GI)");
    cmd->add_option("--normal-offset", o.normalOffset,
                    "metres along the normal to move each shading point before sampling "
                    "(against self-leaking; 0 matches probekit sample)")
        ->capture_default_str();
}

// --dynamic-gi and its settings.
void addDynamicGiOptions(CLI::App* cmd, RenderOptions& o) {
    cmd->add_flag("--dynamic-gi", o.dynamicGi,
                  "relight with the runtime's dynamic GI (light propagation cascades in Vulkan "
                  "compute) from the scene's directional light and --env's sky, added to the "
                  "volume's light (the bake must not hold the sun) or alone without a volume; "
                  "the sun's direct light is shaded with its shadow marched through the GI's "
                  "geometry volume");
    cmd->add_option("--sun-path", o.sunPath,
                    "with --dynamic-gi: az0,el0,az1,el1 in degrees; the sun (the scene's "
                    "directional light, or a 3 W/m^2 white one) moves from the first azimuth "
                    "and elevation to the second over --frames frames (azimuth 0 = the sun in "
                    "+z, 90 = in +x)")
        ->delimiter(',')
        ->expected(4);
    cmd->add_option("--frames", o.frames, "frames to render (one image each: put %d or %03d in -o)")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    cmd->add_option("--gi-cascades", o.giCascades, "dynamic GI cascades, 1..4")
        ->check(CLI::Range(1u, 4u))
        ->capture_default_str();
    cmd->add_option("--gi-resolution", o.giResolution, "cells per cascade axis, 32 or 64")
        ->check(CLI::IsMember({32u, 64u}))
        ->capture_default_str();
    cmd->add_option("--gi-cell", o.giCell,
                    "finest cell size in metres (default: the scene's longest side / "
                    "(resolution - 2), so one cascade holds the scene)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--gi-iterations", o.giIterations, "propagation steps per bounce, 1..256")
        ->check(CLI::Range(1u, 256u))
        ->capture_default_str();
    cmd->add_option("--gi-bounces", o.giBounces, "surface bounces, 1..4")
        ->check(CLI::Range(1u, 4u))
        ->capture_default_str();
    cmd->add_option("--gi-quality", o.giQuality,
                    "l1, or zonal (a zonal band 2 hallucinated from L1)")
        ->check(CLI::IsMember({"l1", "zonal"}))
        ->capture_default_str();
}

} // namespace

void addRenderCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand(
        "render", "Render a glTF scene lit by a .pvol with the Vulkan runtime (headless)");
    addRenderInputOptions(cmd, *o);
    addRenderViewOptions(cmd, *o);
    addRenderShadingOptions(cmd, *o);
    addDynamicGiOptions(cmd, *o);
    cmd->callback([o, &selected] {
        selected = [o] { return o->dynamicGi ? runRenderDynamicGi(*o) : runRender(*o); };
    });
}

} // namespace probekit::cli
