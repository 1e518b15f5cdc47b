// The Bevy exporter (bevy.hpp): SH probes projected to ambient cubes, packed as Bevy's
// irradiance-volume texture, written as KTX2 (ktx2.hpp).
#include "probekit/exporters/bevy.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <Imath/half.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "ktx2.hpp"
#include "probekit/exporters/resample.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit::exporters {
namespace {

constexpr const char* kFaceNames[6] = {"+X", "-X", "+Y", "-Y", "+Z", "-Z"};
constexpr uint32_t kErrorSeed = 2028u;
constexpr int kErrorSamples = 4096;

// Where Bevy's unit cube goes: the box whose centre-mode voxel centres are the probes.
struct ProbeTransform {
    glm::vec3 translation{0.0f};
    glm::vec3 scale{1.0f};
};

// Corner-mode probes sit on the box's faces; the box grown by half a spacing on every side has
// its voxel centres (Bevy's, centre mode) on them.
ProbeTransform transformOf(const grid::GridLayout& g) {
    grid::Aabb box = g.bounds();
    if (g.mode() == grid::PositionMode::Corner) {
        box.min -= 0.5f * g.spacing();
        box.max += 0.5f * g.spacing();
    }
    return {box.center(), box.size()};
}

std::string vecText(glm::vec3 v) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "(%.6g, %.6g, %.6g)", v.x, v.y, v.z);
    return buf;
}

std::string transformJson(const ProbeTransform& t) {
    const nlohmann::json j = {{"translation", {t.translation.x, t.translation.y, t.translation.z}},
                              {"rotation", {0.0, 0.0, 0.0, 1.0}},
                              {"scale", {t.scale.x, t.scale.y, t.scale.z}},
                              {"intensity", 1.0},
                              {"units", "E/pi, W/(sr m^2)"}};
    return j.dump();
}

// Texel index of voxel v's face f in Bevy's (Rx, 2 Ry, 3 Rz) texture (bevy.hpp).
size_t texelIndex(glm::uvec3 r, glm::uvec3 v, int f) {
    const size_t t = v.y + (f % 2 == 1 ? r.y : 0u);
    const size_t p = v.z + size_t(f / 2) * r.z;
    return v.x + size_t(r.x) * (t + size_t(2 * r.y) * p);
}

// Every probe's ambient cube as half texels; fails on a value beyond binary16.
Result<std::vector<uint16_t>> packTexels(const Volume& dense) {
    const grid::GridLayout& g = dense.desc.grid;
    const glm::uvec3 r = g.resolution();
    std::vector<uint16_t> texels(size_t(6) * 4 * g.probeCount(), 0);
    for (size_t i = 0; i < g.probeCount(); ++i) {
        const glm::uvec3 v = g.probeCoords(i);
        const AmbientCube cube = ambientCubeFromSh(dense.probe(i), dense.desc.shOrder);
        for (int f = 0; f < 6; ++f) {
            const float m = std::max({cube[f].x, cube[f].y, cube[f].z});
            if (!(m <= kHalfMax))
                return Error{ErrorCode::OutOfRange, "voxel " + vecText(glm::vec3(v)) + " face " +
                                                        kFaceNames[f] +
                                                        ": E/pi = " + std::to_string(m) +
                                                        " W/(sr m^2) is beyond binary16's 65504"};
            uint16_t* out = &texels[4 * texelIndex(r, v, f)];
            for (int c = 0; c < 3; ++c)
                out[c] = Imath::half(cube[f][c]).bits();
            out[3] = Imath::half(1.0f).bits();
        }
    }
    return texels;
}

std::vector<std::string> notesFor(const Resampled& rs, const ProbeTransform& t,
                                  const ProjectionError& pe) {
    const grid::GridLayout& g = rs.volume.desc.grid;
    const glm::uvec3 r = g.resolution();
    char buf[256];
    std::vector<std::string> notes;
    std::snprintf(buf, sizeof buf,
                  "bevy: %ux%ux%u voxels as a %ux%ux%u RGBA16F 3D texture of ambient cubes "
                  "(E/pi, W/(sr m^2))",
                  r.x, r.y, r.z, r.x, 2 * r.y, 3 * r.z);
    notes.emplace_back(buf);
    notes.push_back("bevy: LightProbe transform: translation " + vecText(t.translation) +
                    ", scale " + vecText(t.scale) +
                    ", no rotation; IrradianceVolume intensity 1.0 keeps probekit's units");
    if (g.mode() == grid::PositionMode::Corner)
        notes.emplace_back("bevy: corner-mode probes: the box is grown by half a spacing so "
                           "that Bevy's voxel centres fall on the probes");
    if (rs.resampled) {
        std::snprintf(buf, sizeof buf,
                      "bevy: resampled to a dense axis-aligned grid: irradiance error %.3g RMS, "
                      "%.3g max (relative to RMS irradiance)",
                      rs.relRms, rs.relMax);
        notes.emplace_back(buf);
    }
    if (!rs.volume.visibility.empty())
        notes.emplace_back("bevy: visibility data dropped (Bevy interpolates without it)");
    std::snprintf(buf, sizeof buf,
                  "bevy: ambient-cube projection error %.3g RMS, %.3g max (relative to RMS "
                  "irradiance; half rounding adds at most 2^-11 of each value)",
                  pe.relRms, pe.relMax);
    notes.emplace_back(buf);
    return notes;
}

} // namespace

AmbientCube ambientCubeFromSh(const sh::ShRgb& s, sh::Order order) {
    const auto& c = s.rgb;
    const glm::vec3 mean = sh::kY00 * c[0];
    glm::vec3 q[3] = {glm::vec3(0.0f), glm::vec3(0.0f), glm::vec3(0.0f)};
    if (order == sh::Order::L2) {
        const glm::vec3 z20 = sh::kY20 * c[6], x22 = sh::kY22 * c[8];
        q[0] = -z20 + x22;
        q[1] = -z20 - x22;
        q[2] = 2.0f * z20;
    }
    const glm::vec3 odd[3] = {c[3], c[1], c[2]}; // L11 (x), L1-1 (y), L10 (z)
    AmbientCube cube;
    for (int a = 0; a < 3; ++a) {
        const glm::vec3 even = mean + 0.25f * q[a];
        const glm::vec3 d = (5.0f / 6.0f) * sh::kY1 * odd[a];
        cube[2 * a] = glm::max(even + d, glm::vec3(0.0f));
        cube[2 * a + 1] = glm::max(even - d, glm::vec3(0.0f));
    }
    return cube;
}

glm::vec3 evalAmbientCube(const AmbientCube& cube, glm::vec3 n) {
    const glm::vec3 nn = n * n;
    return nn.x * cube[n.x < 0.0f ? 1 : 0] + nn.y * cube[n.y < 0.0f ? 3 : 2] +
           nn.z * cube[n.z < 0.0f ? 5 : 4];
}

std::vector<ErrorSample> errorSamples(const grid::Aabb& box, uint32_t seed, int count) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<ErrorSample> samples(size_t(std::max(count, 0)));
    for (ErrorSample& s : samples) {
        // One draw per statement: the order of a constructor's arguments is unspecified.
        const float px = u(rng), py = u(rng), pz = u(rng);
        const float z = 2.0f * u(rng) - 1.0f, phi = 6.2831853f * u(rng);
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        s.position = box.min + glm::vec3(px, py, pz) * box.size();
        s.normal = glm::vec3(r * std::cos(phi), r * std::sin(phi), z);
    }
    return samples;
}

ProjectionError ambientCubeError(const Volume& dense, std::span<const ErrorSample> samples) {
    Volume plain = dense;
    plain.visibility.clear();
    const sh::Order order = plain.desc.shOrder;
    double sumErr2 = 0.0, sumRef2 = 0.0, maxErr = 0.0;
    for (const ErrorSample& s : samples) {
        const sh::ShRgb coeffs = runtime::sampleVolumeSh(plain, s.position);
        const glm::vec3 ref = sh::irradiance(coeffs, order, s.normal);
        const glm::vec3 got = sh::kPi * evalAmbientCube(ambientCubeFromSh(coeffs, order), s.normal);
        const double e = glm::length(got - ref);
        sumErr2 += e * e;
        sumRef2 += double(glm::dot(ref, ref));
        maxErr = std::max(maxErr, e);
    }
    const double n = double(samples.size());
    const double rms = n > 0.0 ? std::sqrt(sumRef2 / n) : 0.0;
    if (!(rms > 0.0))
        return {};
    return {std::sqrt(sumErr2 / n) / rms, maxErr / rms};
}

Result<ExportResult> exportBevy(const Volume& volume, const BevyOptions& options,
                                const std::filesystem::path& out) {
    Result<Resampled> rs = denseAxisAligned(volume, options.resolution);
    if (!rs)
        return rs.error();
    const Volume& dense = rs.value().volume;
    Result<std::vector<uint16_t>> texels = packTexels(dense);
    if (!texels)
        return Error{texels.error().code, "bevy export: " + texels.error().message};
    const glm::uvec3 r = dense.desc.grid.resolution();
    const ProbeTransform t = transformOf(dense.desc.grid);
    ktx2::Image3d image{r.x,
                        2 * r.y,
                        3 * r.z,
                        std::move(texels.value()),
                        {{"KTXwriter", "probekit"}, {"probekit.transform", transformJson(t)}}};
    const ProjectionError pe = ambientCubeError(
        dense, errorSamples(dense.desc.grid.worldBounds(), kErrorSeed, kErrorSamples));
    ExportResult result;
    result.files.push_back({out, ktx2::writeRgba16f(image)});
    result.notes = notesFor(rs.value(), t, pe);
    return result;
}

} // namespace probekit::exporters
