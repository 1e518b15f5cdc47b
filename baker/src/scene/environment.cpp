// Lat-long environment maps through OpenImageIO (.hdr, .exr, or anything else it reads).
//
// The mapping from texels to directions is documented once, on Environment in scene.hpp.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <exception>
#include <string>
#include <vector>

#include <sys/stat.h>

#include <OpenImageIO/imageio.h>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/file_io.hpp"

namespace probekit::baker {
namespace {

// A lat-long map is 2:1. Exporters sometimes write one pixel more or less (2049 x 1024) and
// that only stretches the map by a fraction of a texel, so ratios within this relative
// tolerance of 2 are accepted; anything further off (a cube-map cross, a 1:1 angular probe) is
// not a lat-long map and is rejected rather than silently sampled with the wrong mapping.
constexpr double kAspectTolerance = 0.05;

// The largest map read, checked from the image header before the pixels are allocated: 2^26
// pixels (8192 x 8192, the glTF image limit; a 2:1 map of 11585 x 5792) are 1 GiB of linear
// RGBA floats. A probe volume's SH is band-limited to l <= 2, so a few hundred texels across
// already carry everything it keeps; the limit only stops a forged header (a few bytes claiming
// 10^9 pixels) from allocating what it claims.
constexpr uint64_t kMaxEnvironmentPixels = uint64_t(1) << 26;
// Channels read: RGB, and alpha if present; further channels (an EXR's depth, ids) are skipped.
constexpr int kMaxChannelsRead = 4;

} // namespace

namespace {

// The map must be a regular file: stat, not open, so a FIFO named as the map is refused, not
// waited on.
Result<void> checkRegularFile(const std::string& file) {
    struct stat info {};
    if (::stat(file.c_str(), &info) != 0) {
        return makeError(ErrorCode::Io, file + ": no such file");
    }
    if (!S_ISREG(info.st_mode)) {
        return makeError(ErrorCode::Io, file +
                                            ": the environment map is not a regular file (it is " +
                                            std::string(fileTypeText(info.st_mode)) + ")");
    }
    return {};
}

// A 2D, 2:1 image within the pixel limit.
Result<void> checkLatLongSpec(const OIIO::ImageSpec& spec, int channels, const std::string& file) {
    const int width = spec.width;
    const int height = spec.height;
    if (width <= 0 || height <= 0 || channels <= 0 || spec.depth > 1) {
        return makeError(ErrorCode::InvalidArgument,
                         file + ": not a 2D image (" + std::to_string(width) + " x " +
                             std::to_string(height) + " x " + std::to_string(spec.depth) + ", " +
                             std::to_string(channels) + " channels)");
    }
    if (uint64_t(width) * uint64_t(height) > kMaxEnvironmentPixels) {
        return makeError(ErrorCode::OutOfRange,
                         file + ": " + std::to_string(width) + " x " + std::to_string(height) +
                             " pixels, more than the environment map limit of " +
                             std::to_string(kMaxEnvironmentPixels) +
                             " (8192 x 8192); downsample it (a probe volume keeps only its "
                             "lowest 9 SH coefficients)");
    }
    const double aspect = double(width) / double(height);
    if (std::abs(aspect / 2.0 - 1.0) > kAspectTolerance) {
        return makeError(ErrorCode::InvalidArgument, file + ": " + std::to_string(width) + " x " +
                                                         std::to_string(height) +
                                                         " is not a 2:1 lat-long image");
    }

    return {};
}

// Whether the file's values are sRGB-encoded, not linear radiance: integer pixels (8 or 16 bits)
// whose colour space OIIO reports as sRGB, or, when it reports none, a PNG or JPEG (formats
// whose integers are sRGB unless they say otherwise). Float files (EXR, HDR, PFM) are linear.
bool storesSrgb(const OIIO::ImageSpec& spec, const std::string& format_name) {
    if (spec.format.is_floating_point()) {
        return false;
    }
    std::string space = spec.get_string_attribute("oiio:ColorSpace");
    std::transform(space.begin(), space.end(), space.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (space.empty()) {
        return format_name == "png" || format_name == "jpeg";
    }
    return space.find("srgb") != std::string::npos && !space.starts_with("lin");
}

// The sRGB transfer function undone: encoded value in [0, 1] to linear (IEC 61966-2-1).
float srgbToLinear(float encoded) {
    const double c = encoded;
    return static_cast<float>(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

// Decodes the colour channels (the first three, or the grey one) of sRGB pixels to linear in
// place; alpha and further channels are left as they are (they carry no radiance).
void decodeSrgb(std::vector<float>& pixels, int channels) {
    const int colour_channels = channels >= 3 ? 3 : 1;
    for (size_t p = 0; p < pixels.size(); p += size_t(channels)) {
        for (int c = 0; c < colour_channels; ++c) {
            pixels[p + size_t(c)] = srgbToLinear(pixels[p + size_t(c)]);
        }
    }
}

// The memory the decode takes, from the header alone: the pixels read as floats (the channels
// read, 4 bytes each) and the RGBA float texels they become, both held at once. Refused when
// over `max_bytes` (the bake's max_memory_mb), before either is allocated: a 664 KB EXR of
// 11585 x 5792 constant pixels decodes to 2.1 GB.
Result<void> checkDecodeMemory(int width, int height, int channels, uint64_t max_bytes,
                               const std::string& file) {
    const uint64_t pixels = uint64_t(width) * uint64_t(height);
    const uint64_t bytes = pixels * (uint64_t(channels) * sizeof(float) + sizeof(glm::vec4));
    if (bytes <= max_bytes) {
        return {};
    }
    return makeError(ErrorCode::OutOfRange,
                     file + ": the environment map decodes to " + std::to_string(bytes >> 20) +
                         " MiB (" + std::to_string(width) + " x " + std::to_string(height) +
                         " pixels, " + std::to_string(channels) +
                         " channels as float, then RGBA float texels), more than the memory "
                         "limit of " +
                         std::to_string(max_bytes >> 20) +
                         " MiB (max_memory_mb, --max-memory); downsample the map");
}

// The decoded pixels as RGB texels: one or two channels are grey (+ alpha); otherwise the first
// three are RGB. Alpha and extra channels carry no radiance and are ignored. Every radiance must
// be finite and >= 0.
Result<void> storeTexels(const std::vector<float>& pixels, int channels, const std::string& file,
                         Image& image) {
    const size_t width = image.width;
    image.texels.resize(size_t(image.width) * size_t(image.height));
    const int colour_channels = channels >= 3 ? 3 : 1;
    for (size_t t = 0; t < image.texels.size(); ++t) {
        const float* texel = &pixels[t * size_t(channels)];
        for (int c = 0; c < colour_channels; ++c) {
            if (!std::isfinite(texel[c]) || texel[c] < 0.0f) {
                return makeError(
                    std::isfinite(texel[c]) ? ErrorCode::OutOfRange : ErrorCode::NonFinite,
                    file + ": pixel (" + std::to_string(t % width) + ", " +
                        std::to_string(t / width) + ") channel " + std::to_string(c) + " = " +
                        std::to_string(texel[c]) + " is not a finite, non-negative radiance");
            }
        }
        image.texels[t] = colour_channels == 3 ? glm::vec4(texel[0], texel[1], texel[2], 1.0f)
                                               : glm::vec4(texel[0], texel[0], texel[0], 1.0f);
    }
    return {};
}

} // namespace

Result<Environment> loadLatLongEnvironment(const std::filesystem::path& path, float intensity,
                                           float rotation_deg, uint64_t max_bytes) {
    const std::string file = path.string();
    if (!std::isfinite(intensity) || intensity < 0.0f) {
        return makeError(ErrorCode::OutOfRange, file + ": environment intensity " +
                                                    std::to_string(intensity) +
                                                    " must be finite and >= 0");
    }
    if (!std::isfinite(rotation_deg)) {
        return makeError(ErrorCode::NonFinite, file + ": environment rotation must be finite");
    }
    if (Result<void> regular = checkRegularFile(file); !regular) {
        return regular.error();
    }
    try {
        auto input = OIIO::ImageInput::open(file);
        if (!input) {
            return makeError(ErrorCode::Io,
                             file + ": cannot read the image (" + OIIO::geterror() + ")");
        }
        const OIIO::ImageSpec& spec = input->spec();
        const int channels = std::min(spec.nchannels, kMaxChannelsRead);
        // Kept as values: close() below may reset the spec.
        const int width = spec.width;
        const int height = spec.height;
        if (Result<void> shape = checkLatLongSpec(spec, channels, file); !shape) {
            return shape.error();
        }
        if (Result<void> memory = checkDecodeMemory(width, height, channels, max_bytes, file);
            !memory) {
            return memory.error();
        }
        std::vector<float> pixels(size_t(width) * size_t(height) * size_t(channels));
        // Reading as FLOAT makes OIIO convert whatever the file stores (RGBE, half, 8-bit).
        if (!input->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data())) {
            return makeError(ErrorCode::Io,
                             file + ": cannot decode the pixels (" + input->geterror() + ")");
        }
        // OIIO scales integers to [0, 1] but leaves their transfer function: an 8-bit sRGB
        // PNG read as it stands is up to 2.3 times too bright in the mid-tones.
        if (storesSrgb(spec, input->format_name())) {
            decodeSrgb(pixels, channels);
        }
        input->close();

        Environment environment;
        environment.type = Environment::Type::LatLong;
        environment.intensity = intensity;
        environment.rotationDeg = rotation_deg;
        environment.source = file;
        environment.image.width = static_cast<uint32_t>(width);
        environment.image.height = static_cast<uint32_t>(height);
        if (Result<void> stored = storeTexels(pixels, channels, file, environment.image); !stored) {
            return stored.error();
        }
        return environment;
    } catch (const std::exception& e) {
        return makeError(ErrorCode::Io, file + ": " + e.what());
    }
}

} // namespace probekit::baker
