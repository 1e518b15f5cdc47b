// `probekit surface-reference` and `probekit surface-error`: the per-pixel accuracy of a
// volume's shading against a path-traced reference of the same view
// (docs/accuracy.md#surface-accuracy; runtime/include/probekit/runtime/surface_error.hpp defines
// the figures).
//
// surface-reference traces one ray per pixel through the same camera `probekit render` uses
// (same options, runtime::pixelDirection), and at each first hit path-traces E with the baker's
// own integrator (baker/include/probekit/baker/surface_reference.hpp). It writes an EXR holding
// per pixel E (R, G, B), A = 1 on surfaces, its standard error (err.R, err.G, err.B), the
// shading normal (N.X, N.Y, N.Z) and the point (P.X, P.Y, P.Z, metres).
//
// surface-error compares a render's irradiance EXR (`probekit render --view irradiance -o
// X.exr`, same camera options and size) or, with --volume, the CPU sampler at the reference's
// own points and normals (what `probekit sample` computes), and prints the figures; --heatmap
// writes log2(E / E_ref) as a PNG.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <glm/common.hpp>
#include <nlohmann/json.hpp>

#include "camera_options.hpp"
#include "commands.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/baker/surface_reference.hpp"
#include "probekit/formats/file_io.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/runtime/sampler.hpp"
#include "probekit/runtime/surface_error.hpp"
#include "probekit/runtime/tonemap.hpp"
#include "probekit/viewer/surface_view.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

// Images a command reads: at most 1 GiB (16384 x 16384 x 13 half channels fit).
constexpr uint64_t kMaxImageBytes = uint64_t(1) << 30;

const std::vector<std::string> kReferenceChannels = {
    "R", "G", "B", "A", "err.R", "err.G", "err.B", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z"};

Result<void> encodeAndWrite(const std::string& path, const OIIO::ImageSpec& spec,
                            const char* format, OIIO::TypeDesc type, const void* pixels) {
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(format);
    if (!out) {
        return makeError(ErrorCode::Io,
                         path + ": no OpenImageIO writer (" + OIIO::geterror() + ")");
    }
    if (!(out->set_ioproxy(&proxy) && out->open(path, spec) && out->write_image(type, pixels) &&
          out->close())) {
        return makeError(ErrorCode::Io,
                         path + ": cannot encode the image (" + out->geterror() + ")");
    }
    return writeFileAtomic(path, std::span<const uint8_t>(bytes));
}

Result<void> writeReference(const std::string& path, const runtime::SurfaceReferenceImage& r) {
    const size_t channels = kReferenceChannels.size();
    const size_t pixels = size_t(r.width) * r.height;
    std::vector<float> data(pixels * channels, 0.0f);
    for (size_t i = 0; i < pixels; ++i) {
        float* px = &data[i * channels];
        const glm::vec3 values[4] = {r.irradiance[i], r.standardError[i], r.normal[i],
                                     r.position[i]};
        for (int c = 0; c < 3; ++c) {
            px[c] = values[0][c];
            px[4 + c] = values[1][c];
            px[7 + c] = values[2][c];
            px[10 + c] = values[3][c];
        }
        px[3] = r.hit[i] ? 1.0f : 0.0f;
    }
    OIIO::ImageSpec spec(int(r.width), int(r.height), int(channels), OIIO::TypeDesc::FLOAT);
    spec.channelnames = kReferenceChannels;
    spec.alpha_channel = 3;
    spec.attribute("probekit:content", "surface irradiance reference, W/m^2");
    return encodeAndWrite(path, spec, "openexr", OIIO::TypeDesc::FLOAT, data.data());
}

struct FloatImage {
    uint32_t width = 0;
    uint32_t height = 0;
    std::vector<std::string> channels;
    std::vector<float> data; // interleaved
    int channel(const std::string& name) const {
        for (size_t c = 0; c < channels.size(); ++c) {
            if (channels[c] == name) {
                return int(c);
            }
        }
        return -1;
    }
};

Result<FloatImage> readFloatImage(const std::string& path) {
    Result<std::string> bytes = readRegularFile(path, kMaxImageBytes, "image");
    if (!bytes) {
        return bytes.error();
    }
    OIIO::Filesystem::IOMemReader proxy(bytes.value().data(), bytes.value().size());
    // Decoded from the bytes read above (a regular file of bounded size), never reopened.
    std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::create(path);
    OIIO::ImageSpec opened;
    if (!in || !in->set_ioproxy(&proxy) || !in->open(path, opened)) {
        return makeError(ErrorCode::InvalidArgument,
                         path + ": not an image OpenImageIO can read (" + OIIO::geterror() + ")");
    }
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.width < 1 || spec.height < 1 || spec.depth != 1 || spec.nchannels < 3 ||
        uint64_t(spec.width) * uint64_t(spec.height) * uint64_t(spec.nchannels) >
            kMaxImageBytes / sizeof(float)) {
        return makeError(ErrorCode::InvalidArgument,
                         path + ": expected a 2D image with at least 3 channels, got " +
                             std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                             " x " + std::to_string(spec.depth) + " with " +
                             std::to_string(spec.nchannels) + " channels");
    }
    FloatImage image;
    image.width = uint32_t(spec.width);
    image.height = uint32_t(spec.height);
    image.channels = spec.channelnames;
    image.data.resize(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.data.data())) {
        return makeError(ErrorCode::InvalidArgument,
                         path + ": cannot decode (" + in->geterror() + ")");
    }
    return image;
}

Result<runtime::SurfaceReferenceImage> readReference(const std::string& path) {
    Result<FloatImage> image = readFloatImage(path);
    if (!image) {
        return image.error();
    }
    const FloatImage& f = image.value();
    int index[13];
    for (size_t c = 0; c < kReferenceChannels.size(); ++c) {
        index[c] = f.channel(kReferenceChannels[c]);
        if (index[c] < 0) {
            return makeError(ErrorCode::InvalidArgument,
                             path + ": no channel " + kReferenceChannels[c] +
                                 " (not written by probekit surface-reference)");
        }
    }
    runtime::SurfaceReferenceImage r;
    r.width = f.width;
    r.height = f.height;
    const size_t pixels = size_t(f.width) * f.height;
    const size_t stride = f.channels.size();
    r.hit.resize(pixels);
    r.irradiance.resize(pixels);
    r.standardError.resize(pixels);
    r.normal.resize(pixels);
    r.position.resize(pixels);
    for (size_t i = 0; i < pixels; ++i) {
        const float* px = &f.data[i * stride];
        const auto vec = [&](int first) {
            return glm::vec3(px[index[first]], px[index[first + 1]], px[index[first + 2]]);
        };
        r.irradiance[i] = vec(0);
        r.hit[i] = px[index[3]] > 0.5f ? 1 : 0;
        r.standardError[i] = vec(4);
        r.normal[i] = vec(7);
        r.position[i] = vec(10);
        bool finite = true;
        for (const glm::vec3 v :
             {r.irradiance[i], r.normal[i], r.position[i], r.standardError[i]}) {
            finite = finite && std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
        }
        if (r.hit[i] && !finite) {
            return makeError(ErrorCode::InvalidArgument,
                             path + ": pixel " + std::to_string(i % f.width) + "," +
                                 std::to_string(i / f.width) + " holds a non-finite value");
        }
    }
    return r;
}

// log2(E / E_ref) as blue (0.5x and below) - white (1x) - red (2x and above); E <= 0 magenta,
// edges mid grey, dark reference pixels dark grey, background black.
std::vector<uint8_t> heatmap(const runtime::SurfaceError& e) {
    std::vector<uint8_t> rgb(e.category.size() * 3, 0);
    for (size_t i = 0; i < e.category.size(); ++i) {
        glm::vec3 c(0.0f);
        switch (e.category[i]) {
        case 1: {
            const float l = e.log2Ratio[i];
            if (std::isinf(l) && l < 0.0f) {
                c = glm::vec3(1.0f, 0.0f, 1.0f);
                break;
            }
            const float t = glm::clamp(l, -1.0f, 1.0f);
            c = t >= 0.0f ? glm::vec3(1.0f, 1.0f - t, 1.0f - t)
                          : glm::vec3(1.0f + t, 1.0f + t, 1.0f);
            break;
        }
        case 2:
            c = glm::vec3(0.5f);
            break;
        case 3:
            c = glm::vec3(0.2f);
            break;
        default:
            break;
        }
        for (int k = 0; k < 3; ++k) {
            rgb[3 * i + size_t(k)] = uint8_t(std::lround(runtime::srgbEncode(c[k]) * 255.0f));
        }
    }
    return rgb;
}

nlohmann::json errorJson(const runtime::SurfaceError& e) {
    return {{"surface_pixels", e.surfacePixels},    {"edge_pixels", e.edgePixels},
            {"dark_pixels", e.darkPixels},          {"compared", e.compared},
            {"median_abs_error", e.medianAbsError}, {"mean_ratio", e.meanRatio},
            {"share_under_half", e.shareUnderHalf}, {"share_over_two", e.shareOverTwo},
            {"share_negative", e.shareNegative},    {"reference_noise", e.referenceNoise},
            {"noise_floor", e.noiseFloor}};
}

struct ReferenceOptions {
    std::string scene;
    std::string output;
    CameraOptions framing;
    uint32_t samples = 1024;
    uint32_t maxBounces = 64;
    uint64_t seed = 1;
    uint32_t threads = 0;
};

int runReference(const ReferenceOptions& o) {
    const NamedPath outputs[] = {{o.output, "-o"}};
    const NamedPath inputs[] = {{o.scene, "the scene"}};
    if (Result<void> checked = checkOutputs(outputs, inputs); !checked) {
        printError("surface-reference", checked.error().message);
        return kExitFailure;
    }
    Result<baker::Scene> scene = baker::loadGltf(o.scene);
    if (!scene) {
        printError("surface-reference", scene.error().message);
        return kExitFailure;
    }
    for (const std::string& w : scene.value().warnings) {
        printError("surface-reference", "warning: " + w);
    }
    if (!scene.value().hasGeometry()) {
        printError("surface-reference", o.scene + ": the scene has no triangles to trace");
        return kExitFailure;
    }
    const uint32_t width = o.framing.size[0], height = o.framing.size[1];
    Result<runtime::Camera> camera =
        chooseCamera(o.framing, scene.value().bounds, float(width) / float(height));
    if (!camera) {
        printError("surface-reference", camera.error().message);
        return kExitFailure;
    }
    const std::vector<baker::SurfaceRay> rays = viewer::viewRays(camera.value(), width, height);
    baker::SurfaceReferenceSettings settings;
    settings.samples = o.samples;
    settings.maxBounces = o.maxBounces;
    settings.seed = o.seed;
    settings.threads = o.threads;
    const bool tty = isatty(fileno(stderr)) != 0;
    const auto progress = [tty](size_t done, size_t total) {
        if (tty) {
            std::fprintf(stderr, "\rsurface-reference: %zu / %zu pixels", done, total);
            if (done == total) {
                std::fprintf(stderr, "\n");
            }
        }
    };
    Result<baker::SurfaceReference> traced =
        baker::traceSurfaceReference(scene.value(), rays, settings, progress);
    if (!traced) {
        printError("surface-reference", traced.error().message);
        return kExitFailure;
    }
    const runtime::SurfaceReferenceImage image =
        viewer::referenceImage(traced.value(), width, height);
    if (Result<void> written = writeReference(o.output, image); !written) {
        printError("surface-reference", written.error().message);
        return kExitFailure;
    }
    std::vector<double> noise;
    for (size_t i = 0; i < image.hit.size(); ++i) {
        const double y = runtime::surfaceLuminance(image.irradiance[i]);
        if (image.hit[i] && y > 0.0) {
            noise.push_back(runtime::surfaceLuminance(image.standardError[i]) / y);
        }
    }
    std::sort(noise.begin(), noise.end());
    std::printf("wrote %s: %ux%u, %zu surface pixels, %u samples each, %llu rays; median relative "
                "standard error %.4f\n",
                terminalText(o.output).c_str(), width, height, noise.size(), o.samples,
                static_cast<unsigned long long>(traced.value().rays),
                noise.empty() ? 0.0 : noise[noise.size() / 2]);
    return kExitOk;
}

struct ErrorOptions {
    std::string reference;
    std::string test;
    std::string volume;
    bool noVisibility = false;
    float normalOffset = 0.0f;
    std::string heatmap;
    bool json = false;
};

// The irradiance the --volume file's CPU sampler gives at the reference's points and normals.
Result<std::vector<glm::vec3>> volumeIrradiance(const ErrorOptions& o,
                                                const runtime::SurfaceReferenceImage& r) {
    Result<PvolFile> file = readPvol(o.volume);
    if (!file) {
        return file.error();
    }
    std::vector<Volume>& volumes = file.value().volumes;
    if (volumes.empty()) {
        return makeError(ErrorCode::InvalidArgument, o.volume + ": the file holds no volume");
    }
    if (o.noVisibility) {
        for (Volume& v : volumes) {
            v.visibility.clear();
        }
    }
    Result<runtime::VolumeSet> set = runtime::VolumeSet::make(std::move(volumes));
    if (!set) {
        return makeError(set.error().code, o.volume + ": " + set.error().message);
    }
    std::vector<glm::vec3> test(r.hit.size(), glm::vec3(0.0f));
    for (size_t i = 0; i < r.hit.size(); ++i) {
        if (r.hit[i]) {
            test[i] = set.value().irradiance(r.position[i], r.normal[i], o.normalOffset);
        }
    }
    return test;
}

// The irradiance of the TEST.exr render, which must have the reference's size.
Result<std::vector<glm::vec3>> imageIrradiance(const ErrorOptions& o,
                                               const runtime::SurfaceReferenceImage& r) {
    Result<FloatImage> image = readFloatImage(o.test);
    if (!image) {
        return image.error();
    }
    const FloatImage& f = image.value();
    if (f.width != r.width || f.height != r.height) {
        return makeError(ErrorCode::InvalidArgument,
                         o.test + ": " + std::to_string(f.width) + "x" + std::to_string(f.height) +
                             ", the reference is " + std::to_string(r.width) + "x" +
                             std::to_string(r.height) +
                             " (render with the same --size and camera)");
    }
    std::vector<glm::vec3> test(r.hit.size(), glm::vec3(0.0f));
    const size_t stride = f.channels.size();
    for (size_t i = 0; i < test.size(); ++i) {
        test[i] = glm::vec3(f.data[i * stride], f.data[i * stride + 1], f.data[i * stride + 2]);
    }
    return test;
}

// Writes --heatmap: the figures' log2 ratio per pixel as an sRGB PNG.
Result<void> writeHeatmap(const std::string& path, const runtime::SurfaceError& e,
                          const runtime::SurfaceReferenceImage& r) {
    const std::vector<uint8_t> rgb = heatmap(e);
    OIIO::ImageSpec spec(int(r.width), int(r.height), 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    return encodeAndWrite(path, spec, "png", OIIO::TypeDesc::UINT8, rgb.data());
}

// Prints the figures as text.
void printSurfaceError(const runtime::SurfaceError& s) {
    std::printf("%zu surface pixels: %zu compared, %zu at edges, %zu dark in the reference\n"
                "  median abs error  %.4f   (reference noise %.4f: a perfect image measures "
                "about %.4f)\n"
                "  mean E / E_ref    %.4f\n"
                "  under 0.5x        %.4f\n"
                "  over 2x           %.4f\n"
                "  negative E        %.4f\n",
                s.surfacePixels, s.compared, s.edgePixels, s.darkPixels, s.medianAbsError,
                s.referenceNoise, s.noiseFloor, s.meanRatio, s.shareUnderHalf, s.shareOverTwo,
                s.shareNegative);
}

int runError(const ErrorOptions& o) {
    const auto fail = [](const std::string& message) {
        printError("surface-error", message);
        return kExitFailure;
    };
    if (o.test.empty() == o.volume.empty()) {
        printError("surface-error", "give either TEST.exr or --volume FILE.pvol");
        return kExitUsage;
    }
    if (!o.heatmap.empty()) {
        if (Result<std::filesystem::path> target = resolveOutputPath(o.heatmap); !target) {
            return fail(target.error().message);
        }
    }
    Result<runtime::SurfaceReferenceImage> reference = readReference(o.reference);
    if (!reference) {
        return fail(reference.error().message);
    }
    const runtime::SurfaceReferenceImage& r = reference.value();
    Result<std::vector<glm::vec3>> test =
        o.volume.empty() ? imageIrradiance(o, r) : volumeIrradiance(o, r);
    if (!test) {
        return fail(test.error().message);
    }
    Result<runtime::SurfaceError> e = runtime::compareSurface(test.value(), r);
    if (!e) {
        return fail(e.error().message);
    }
    if (!o.heatmap.empty()) {
        if (Result<void> w = writeHeatmap(o.heatmap, e.value(), r); !w) {
            return fail(w.error().message);
        }
    }
    if (o.json) {
        std::printf("%s\n", jsonText(errorJson(e.value())).c_str());
        return kExitOk;
    }
    printSurfaceError(e.value());
    return kExitOk;
}

} // namespace

void addSurfaceCommands(CLI::App& app, Command& selected) {
    auto r = std::make_shared<ReferenceOptions>();
    CLI::App* ref = app.add_subcommand(
        "surface-reference",
        "Path-trace the irradiance at every surface pixel of a view (the per-pixel reference "
        "for surface-error); same camera options as render");
    ref->add_option("SCENE", r->scene, "glTF scene (.gltf or .glb)")->required();
    ref->add_option("-o,--output", r->output, "the reference EXR to write")->required();
    addCameraOptions(ref, r->framing);
    ref->add_option("--samples", r->samples, "cosine-distributed directions per pixel")
        ->check(CLI::Range(1u, 1u << 24))
        ->capture_default_str();
    ref->add_option("--max-bounces", r->maxBounces, "diffuse bounces after the surface")
        ->check(CLI::Range(0u, 1024u))
        ->capture_default_str();
    ref->add_option("--seed", r->seed, "random seed")->capture_default_str();
    ref->add_option("--threads", r->threads, "threads, 0 = all")->capture_default_str();
    ref->callback([r, &selected] { selected = [r] { return runReference(*r); }; });

    auto e = std::make_shared<ErrorOptions>();
    CLI::App* err = app.add_subcommand(
        "surface-error",
        "Per-pixel error of a render's irradiance EXR (or of a volume, sampled on the CPU at the "
        "reference's points) against a surface-reference EXR");
    err->add_option("REFERENCE", e->reference, "EXR written by surface-reference")->required();
    err->add_option("TEST", e->test,
                    "EXR written by render --view irradiance with the same camera and size");
    err->add_option("--volume", e->volume,
                    "instead of TEST: sample this .pvol with the CPU sampler (probekit sample) at "
                    "the reference's points and normals");
    err->add_flag("--no-visibility", e->noVisibility,
                  "with --volume: drop visibility data (plain trilinear interpolation)");
    err->add_option("--normal-offset", e->normalOffset,
                    "with --volume: metres along the normal to move each point before sampling")
        ->capture_default_str();
    err->add_option("--heatmap", e->heatmap,
                    "write log2(E / E_ref) as a PNG: blue 0.5x, white 1x, red 2x, magenta E <= "
                    "0, grey edges");
    err->add_flag("--json", e->json, "print one JSON line");
    err->callback([e, &selected] { selected = [e] { return runError(*e); }; });
}

} // namespace probekit::cli
