// exportThree: a volume as the atlas of three.js's LightProbeGrid (three.hpp; the layout and the
// units are described in docs/engines.md#threejs).
//
// The atlas is one RGBA 3D texture, nx x ny x 7 (nz + 2) texels. Sub-volume t (t = 0..6) holds
// floats 4t..4t+3 of the 27 coefficients of a probe, ordered coefficient-major (coefficient k,
// channel c at 3k + c; the 28th float is 0), at slices t (nz + 2) + 1 + iz; slice t (nz + 2)
// repeats iz = 0 and slice t (nz + 2) + nz + 1 repeats iz = nz - 1, so that the texture's linear
// filter never mixes two sub-volumes. Within a slice texels are x-fastest, then y. three.js's
// shader evaluates E(n) = sum A_l L_lm Y_lm(n) with the constants of formats/CONVENTIONS.md
// (0.886227 = pi Y00, ...) from radiance SH in the same basis, and multiplies by the Lambert BRDF
// albedo / pi, so the coefficients are written as the .pvol stores them, unscaled. It samples at
// p + n spacing / 2 (per axis) with clamp addressing at the outermost cell centres: E there is
// runtime::VolumeSet::irradiance at that point (tests/unit/test_export_three.cpp decodes the
// files by those rules and compares).
//
// A volume with visibility (formats/include/probekit/formats/visibility.hpp) also gets its six
// bytes per probe, after the atlas in the same .bin: an RGBA8 3D texture nx x ny x 2 nz, slice iz
// holding (+x, -x, +y, -y) and slice nz + iz holding (+z, -z, 255, 255) of the probes of layer
// iz. integrations/three/probekit-three.js's visibility chunk weighs its taps with them as the
// CPU sampler does (runtime/include/probekit/runtime/sampler.hpp, step V).
#include "probekit/exporters/three.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <string>

#include <Imath/half.h>
#include <nlohmann/json.hpp>

#include "probekit/exporters/resample.hpp"
#include "probekit/formats/visibility.hpp"

namespace probekit::exporters {
namespace {

constexpr uint32_t kSubVolumes = 7;    // 28 floats per probe in RGBA texels, 27 used
constexpr uint32_t kPaddingSlices = 1; // at each end of every sub-volume

// The box whose cell centres are the probes: the grid's own bounds in centre mode; in corner
// mode (probes on the faces) the bounds grown by half a spacing on every side, which puts
// three.js's cell centres exactly on the corner-mode probes, so nothing is resampled.
grid::Aabb cellCentreBounds(const grid::GridLayout& g) {
    if (g.mode() == grid::PositionMode::Center)
        return g.bounds();
    const glm::vec3 half = 0.5f * g.spacing();
    return {g.bounds().min - half, g.bounds().max + half};
}

// One probe's 27 coefficients in three.js's order (coefficient-major, RGB), plus a 0.
std::array<float, 4 * kSubVolumes> threeOrder(const sh::ShRgb& probe) {
    std::array<float, 4 * kSubVolumes> f{};
    for (int k = 0; k < 9; ++k)
        for (int c = 0; c < 3; ++c)
            f[3 * k + c] = probe.rgb[k][c];
    return f;
}

void putLittleEndian(std::vector<uint8_t>& out, size_t at, uint32_t bits, size_t bytes) {
    for (size_t b = 0; b < bytes; ++b)
        out[at + b] = uint8_t(bits >> (8 * b));
}

struct AtlasSize {
    uint32_t nx, ny, nz, depth;
    size_t texels() const { return size_t(nx) * ny * depth; }
};

AtlasSize atlasSize(const grid::GridLayout& g) {
    const glm::uvec3 r = g.resolution();
    return {r.x, r.y, r.z, kSubVolumes * (r.z + 2 * kPaddingSlices)};
}

// The atlas bytes; fails when a coefficient does not fit binary16.
Result<std::vector<uint8_t>> packAtlas(const Volume& dense, bool half) {
    const grid::GridLayout& g = dense.desc.grid;
    const AtlasSize a = atlasSize(g);
    const size_t bytes = half ? 2 : 4;
    std::vector<uint8_t> out(a.texels() * 4 * bytes);
    const uint32_t padded = a.nz + 2 * kPaddingSlices;
    for (uint32_t slice = 0; slice < a.depth; ++slice) {
        const uint32_t t = slice / padded;
        const uint32_t local = slice % padded;
        const uint32_t iz = std::min(a.nz - 1, local == 0 ? 0u : local - kPaddingSlices);
        for (uint32_t iy = 0; iy < a.ny; ++iy)
            for (uint32_t ix = 0; ix < a.nx; ++ix) {
                const size_t probe = g.linearIndex({ix, iy, iz});
                const auto f = threeOrder(dense.probe(probe));
                const size_t texel = (size_t(slice) * a.ny + iy) * a.nx + ix;
                for (uint32_t j = 0; j < 4; ++j) {
                    const float v = f[4 * t + j];
                    if (half && std::abs(v) > kHalfMax)
                        return Error{ErrorCode::InvalidArgument,
                                     "volume '" + dense.desc.name + "': probe " +
                                         std::to_string(probe) + " holds " + std::to_string(v) +
                                         ", beyond half-float range (65504); export with --float"};
                    uint32_t bits = 0;
                    if (half)
                        bits = Imath::half(v).bits();
                    else
                        std::memcpy(&bits, &v, 4);
                    putLittleEndian(out, (texel * 4 + j) * bytes, bits, bytes);
                }
            }
    }
    return out;
}

nlohmann::json vec3Json(glm::vec3 v) {
    return nlohmann::json::array({v.x, v.y, v.z});
}

nlohmann::json visibilityJson(const grid::GridLayout& g, size_t byteOffset, size_t byteLength) {
    const glm::uvec3 r = g.resolution();
    return {{"byteOffset", byteOffset},
            {"byteLength", byteLength},
            {"width", r.x},
            {"height", r.y},
            {"depth", 2 * r.z},
            {"format", "RGBA"},
            {"type", "uint8"},
            {"layout", "slice iz: (+x, -x, +y, -y), slice nz + iz: (+z, -z, 255, 255) of the "
                       "probes of layer iz; x fastest, then y"},
            {"units", "distance to the first surface along the half-axis in cells, q / 255"},
            {"ramp", visibility::kRamp},
            {"floor", visibility::kFloor}};
}

nlohmann::json header(const Volume& source, const Resampled& r, bool half,
                      const std::string& binName, size_t byteLength) {
    const grid::GridLayout& g = r.volume.desc.grid;
    const grid::Aabb box = cellCentreBounds(g);
    const AtlasSize a = atlasSize(g);
    nlohmann::json j;
    j["format"] = "probekit-three-lightprobegrid";
    j["version"] = 1;
    j["volume"] = source.desc.name;
    j["bounds"] = {{"min", vec3Json(box.min)}, {"max", vec3Json(box.max)}};
    j["resolution"] = {a.nx, a.ny, a.nz};
    j["probes"] = "cell centres: min + (i + 0.5) (max - min) / resolution, world frame";
    j["atlas"] = {{"file", binName},
                  {"width", a.nx},
                  {"height", a.ny},
                  {"depth", a.depth},
                  {"format", "RGBA"},
                  {"type", half ? "half" : "float"},
                  {"byteOrder", "little-endian"},
                  {"byteOffset", 0},
                  {"byteLength", byteLength},
                  {"paddingSlices", kPaddingSlices},
                  {"layout", "7 sub-volumes along z, each nz + 2 slices (edge slice repeated at "
                             "both ends); sub-volume t holds floats 4t..4t+3 of the 27 "
                             "coefficients ordered coefficient-major, RGB; x fastest, then y"}};
    j["sh"] = {{"order", 2},
               {"basis", "real orthonormal, Ramamoorthi-Hanrahan order and constants, no "
                         "Condon-Shortley phase, glTF world axes"},
               {"coefficients", "radiance L_lm in W/(sr m^2), unscaled"},
               {"irradiance", "E(n) = sum A_l L_lm Y_lm(n), A = (pi, 2pi/3, pi/4), W/m^2"}};
    j["source"] = {{"layout", std::string(toString(source.desc.layout))},
                   {"positionMode", std::string(toString(source.desc.grid.mode()))},
                   {"resampled", r.resampled},
                   {"resampleRelRms", r.relRms},
                   {"resampleRelMax", r.relMax},
                   {"visibilityDropped", source.hasVisibility() && !r.volume.hasVisibility()}};
    return j;
}

// The visibility texture described at the top of this file.
std::vector<uint8_t> packVisibility(const Volume& dense) {
    const grid::GridLayout& g = dense.desc.grid;
    const glm::uvec3 r = g.resolution();
    const size_t layer = size_t(r.x) * r.y;
    std::vector<uint8_t> out(layer * 2 * r.z * 4, visibility::kClear);
    for (size_t probe = 0; probe < g.probeCount(); ++probe) {
        const uint8_t* q = &dense.visibility[visibility::kBytesPerProbe * probe];
        const glm::uvec3 c = g.probeCoords(probe);
        const size_t in_layer = size_t(c.y) * r.x + c.x;
        std::copy(q, q + 4, &out[4 * (c.z * layer + in_layer)]);
        std::copy(q + 4, q + 6, &out[4 * ((r.z + c.z) * layer + in_layer)]);
    }
    return out;
}

std::vector<uint8_t> bytesOf(const std::string& s) {
    return {s.begin(), s.end()};
}

} // namespace

Result<ExportResult> exportThree(const Volume& volume, const ThreeOptions& options,
                                 const std::filesystem::path& out) {
    if (out.extension() == ".bin")
        return Error{ErrorCode::InvalidArgument,
                     out.string() + ": the header cannot be named .bin (its data goes there); "
                                    "name it OUT.json"};
    Result<Resampled> dense = denseAxisAligned(volume, options.resolution);
    if (!dense)
        return dense.error();
    const Resampled& r = dense.value();
    Result<std::vector<uint8_t>> atlas = packAtlas(r.volume, options.half);
    if (!atlas)
        return atlas.error();
    std::filesystem::path bin = out;
    bin.replace_extension(".bin");
    const std::string binName = bin.filename().string();
    std::vector<uint8_t> bytes = std::move(atlas.value());
    nlohmann::json j = header(volume, r, options.half, binName, bytes.size());
    if (r.volume.hasVisibility()) {
        const std::vector<uint8_t> vis = packVisibility(r.volume);
        j["visibility"] = visibilityJson(r.volume.desc.grid, bytes.size(), vis.size());
        bytes.insert(bytes.end(), vis.begin(), vis.end());
    }
    ExportResult result;
    result.files.push_back({out, bytesOf(j.dump(2) + "\n")});
    result.files.push_back({bin, std::move(bytes)});
    const glm::uvec3 res = r.volume.desc.grid.resolution();
    std::string grid =
        std::to_string(res.x) + "x" + std::to_string(res.y) + "x" + std::to_string(res.z);
    if (r.resampled)
        result.notes.push_back("resampled to a dense " + grid + " grid: irradiance error " +
                               "rel RMS " + std::to_string(r.relRms) + ", rel max " +
                               std::to_string(r.relMax));
    else
        result.notes.push_back("dense " + grid + " grid exported as it is (" +
                               std::string(toString(volume.desc.grid.mode())) +
                               " mode), no resampling");
    if (r.volume.hasVisibility())
        result.notes.push_back("visibility exported: apply it with probekit-three.js's "
                               "visibility chunk (three.js alone interpolates plainly)");
    else if (volume.hasVisibility())
        result.notes.push_back("visibility dropped: it belongs to the source's probes, not the "
                               "resampled grid");
    return result;
}

} // namespace probekit::exporters
