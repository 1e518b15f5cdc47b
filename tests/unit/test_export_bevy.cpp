// Tests for the Bevy exporter (exporters/.../bevy.hpp): the KTX2 container read back by a
// reader written here from the KTX 2.0 and Khronos Data Format specifications (not from the
// writer), the texture decoded by Bevy's shader rules (bevy_pbr's irradiance_volume.wesl, as
// bevy.hpp describes them) and compared with probekit's CPU sampler, and the ambient-cube
// projection against its closed form on synthetic SH.
#include "probekit/exporters/bevy.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/packing.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "probekit/exporters/resample.hpp"
#include "probekit/runtime/sampler.hpp"

namespace {

using namespace probekit;
using exporters::AmbientCube;

constexpr double kPi = 3.14159265358979323846;

// A stored binary16 value is the float rounded to nearest: relative error at most 2^-11 in the
// normal range (and 2^-25 absolute below it). Bevy's sum is a trilinear blend (non-negative
// weights summing to 1) of n^2-weighted faces (summing to 1 for a unit normal), so the decoded
// value is off by at most 2^-11 of the largest face magnitude involved. The float arithmetic of
// both sides (SH interpolation, projection, evaluation: some ten roundings of terms no larger
// than a few times that magnitude) adds under 1e-5 of it.
constexpr double kHalfRelative = 1.0 / 2048.0;
constexpr double kFloatRelative = 1e-5;
constexpr double kHalfAbsolute = 1.0 / 33554432.0;

// ---- A KTX2 reader, from the specification ----

uint32_t u32(const std::vector<uint8_t>& b, size_t at) {
    uint32_t v = 0;
    for (int i = 3; i >= 0; --i)
        v = (v << 8) | b.at(at + i);
    return v;
}
uint64_t u64(const std::vector<uint8_t>& b, size_t at) {
    return u32(b, at) | (uint64_t(u32(b, at + 4)) << 32);
}

struct Ktx2 {
    uint32_t header[9] = {}; // vkFormat .. supercompressionScheme
    uint32_t dfdOffset = 0, dfdLength = 0, kvdOffset = 0, kvdLength = 0;
    uint64_t sgdOffset = 0, sgdLength = 0;
    uint64_t levelOffset = 0, levelLength = 0, levelUncompressed = 0;
    std::vector<uint32_t> dfd; // the words after dfdTotalSize
    std::map<std::string, std::string> keyValues;
    std::vector<uint16_t> texels; // the level's RGBA halves
    uint32_t width() const { return header[2]; }
    uint32_t height() const { return header[3]; }
    uint32_t depth() const { return header[4]; }
};

Ktx2 parseKtx2(const std::vector<uint8_t>& b) {
    Ktx2 k;
    for (int i = 0; i < 9; ++i)
        k.header[i] = u32(b, 12 + 4 * i);
    k.dfdOffset = u32(b, 48);
    k.dfdLength = u32(b, 52);
    k.kvdOffset = u32(b, 56);
    k.kvdLength = u32(b, 60);
    k.sgdOffset = u64(b, 64);
    k.sgdLength = u64(b, 72);
    k.levelOffset = u64(b, 80);
    k.levelLength = u64(b, 88);
    k.levelUncompressed = u64(b, 96);
    for (uint32_t at = k.dfdOffset + 4; at < k.dfdOffset + k.dfdLength; at += 4)
        k.dfd.push_back(u32(b, at));
    for (size_t at = k.kvdOffset; at < size_t(k.kvdOffset) + k.kvdLength;) {
        const uint32_t len = u32(b, at);
        const char* entry = reinterpret_cast<const char*>(&b.at(at + 4));
        const std::string key(entry);
        std::string value(entry + key.size() + 1, len - key.size() - 1);
        if (!value.empty() && value.back() == '\0')
            value.pop_back();
        k.keyValues[key] = value;
        at += 4 + (len + 3) / 4 * 4;
    }
    for (uint64_t at = k.levelOffset; at < k.levelOffset + k.levelLength; at += 2)
        k.texels.push_back(uint16_t(b.at(at) | (b.at(at + 1) << 8)));
    return k;
}

// ---- Bevy's sampling, following irradiance_volume.wesl line by line ----

struct BevyVolume {
    Ktx2 file;
    glm::vec3 translation{0.0f}, scale{1.0f};
};

BevyVolume loadBevy(const std::vector<uint8_t>& bytes) {
    BevyVolume v{parseKtx2(bytes)};
    const auto j = nlohmann::json::parse(v.file.keyValues.at("probekit.transform"));
    for (int a = 0; a < 3; ++a) {
        v.translation[a] = j["translation"][a].get<float>();
        v.scale[a] = j["scale"][a].get<float>();
    }
    return v;
}

glm::vec3 texel(const Ktx2& k, glm::ivec3 t) {
    const glm::ivec3 dims(k.width(), k.height(), k.depth());
    t = glm::clamp(t, glm::ivec3(0), dims - 1); // clamp-to-edge addressing
    const size_t i = 4 * (t.x + size_t(dims.x) * (t.y + size_t(dims.y) * t.z));
    return {glm::unpackHalf1x16(k.texels[i]), glm::unpackHalf1x16(k.texels[i + 1]),
            glm::unpackHalf1x16(k.texels[i + 2])};
}

// textureSampleLevel with a linear filter, level 0: the 8 texels around uvw * size - 0.5.
glm::vec3 sampleLinear(const Ktx2& k, glm::vec3 uvw) {
    const glm::vec3 c = uvw * glm::vec3(k.width(), k.height(), k.depth()) - 0.5f;
    const glm::vec3 base = glm::floor(c), f = c - base;
    glm::vec3 sum(0.0f);
    for (int corner = 0; corner < 8; ++corner) {
        const glm::ivec3 o(corner & 1, (corner >> 1) & 1, corner >> 2);
        const glm::vec3 w = glm::mix(1.0f - f, f, glm::vec3(o));
        sum += w.x * w.y * w.z * texel(k, glm::ivec3(base) + o);
    }
    return sum;
}

// irradiance_volume_light for one volume (weight and intensity 1), times pi: irradiance E.
glm::vec3 bevyIrradiance(const BevyVolume& v, glm::vec3 world, glm::vec3 n) {
    const glm::vec3 atlas(v.file.width(), v.file.height(), v.file.depth());
    const glm::vec3 resolution = atlas / glm::vec3(1.0f, 2.0f, 3.0f);
    const glm::vec3 unit_pos = (world - v.translation) / v.scale;
    const glm::vec3 stp =
        glm::clamp((unit_pos + 0.5f) * resolution, glm::vec3(0.5f), resolution - 0.5f);
    const glm::vec3 uvw = stp / atlas;
    const glm::vec3 neg(n.x < 0.0f ? 0.5f : 0.0f, n.y < 0.0f ? 0.5f : 0.0f,
                        n.z < 0.0f ? 0.5f : 0.0f);
    const glm::vec3 x = sampleLinear(v.file, uvw + glm::vec3(0.0f, neg.x, 0.0f));
    const glm::vec3 y = sampleLinear(v.file, uvw + glm::vec3(0.0f, neg.y, 1.0f / 3.0f));
    const glm::vec3 z = sampleLinear(v.file, uvw + glm::vec3(0.0f, neg.z, 2.0f / 3.0f));
    const glm::vec3 nn = n * n;
    return float(kPi) * (x * nn.x + y * nn.y + z * nn.z);
}

// ---- Volumes ----

// A sky of radiance `sky` plus one point light (exact SH, as `probekit synth` writes).
Volume skyAndLight(grid::PositionMode mode, glm::uvec3 res, sh::Order order, float sky,
                   float intensity) {
    VolumeDesc desc;
    desc.name = "test";
    desc.grid =
        grid::GridLayout({glm::vec3(-2.0f, 0.0f, -1.0f), glm::vec3(2.0f, 3.0f, 1.0f)}, res, mode);
    desc.shOrder = order;
    const glm::vec3 light(0.7f, 2.6f, 0.3f);
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        const glm::vec3 to = light - desc.grid.probeWorld(desc.grid.probeCoords(i));
        const float d2 = glm::dot(to, to) + 0.25f;
        probes[i] = sh::projectDelta(glm::normalize(to),
                                     glm::vec3(1.0f, 0.8f, 0.6f) * intensity / d2, order);
        probes[i].rgb[0] += glm::vec3(sky, 1.1f * sky, 1.3f * sky) * (2.0f * std::sqrt(sh::kPi));
    }
    return makeVolume(desc, probes).value();
}

std::vector<uint8_t> exportBytes(const Volume& v, std::vector<std::string>* notes = nullptr) {
    auto r = exporters::exportBevy(v, {}, "out.ktx2");
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    if (!r.ok())
        return {};
    if (notes)
        *notes = r.value().notes;
    return r.value().files.at(0).bytes;
}

} // namespace

namespace {

// Relative RMS and max of pi x ambient cube against E over `count` Fibonacci normals.
exporters::ProjectionError cubeError(const sh::ShRgb& s, sh::Order order, const AmbientCube& cube,
                                     int count = 4000) {
    double err2 = 0.0, ref2 = 0.0, worst = 0.0;
    for (int i = 0; i < count; ++i) {
        const glm::vec3 n = sh::fibonacciDirection(i, count);
        const glm::vec3 ref = sh::irradiance(s, order, n);
        const double e = glm::length(float(kPi) * exporters::evalAmbientCube(cube, n) - ref);
        err2 += e * e;
        ref2 += glm::dot(ref, ref);
        worst = std::max(worst, e);
    }
    const double rms = std::sqrt(ref2 / count);
    return {std::sqrt(err2 / count) / rms, worst / rms};
}

// The alternative projection: each face E(+-axis) / pi.
AmbientCube pointEvaluation(const sh::ShRgb& s, sh::Order order) {
    AmbientCube cube;
    for (int f = 0; f < 6; ++f) {
        glm::vec3 axis(0.0f);
        axis[f / 2] = f % 2 == 0 ? 1.0f : -1.0f;
        cube[f] = sh::irradiance(s, order, axis) / float(kPi);
    }
    return cube;
}

sh::ShRgb randomSh(std::mt19937& rng, float band1, float band2) {
    std::normal_distribution<float> g(0.0f, 1.0f);
    sh::ShRgb s;
    for (int i = 0; i < 9; ++i)
        for (int c = 0; c < 3; ++c)
            s.rgb[i][c] = i == 0 ? 3.0f + 0.3f * g(rng) : (i < 4 ? band1 : band2) * g(rng);
    return s;
}

TEST(ExportBevy, ContainerFieldsAndDataFormatDescriptor) {
    const Volume v = skyAndLight(grid::PositionMode::Center, {4, 2, 8}, sh::Order::L2, 0.5f, 1.0f);
    const std::vector<uint8_t> bytes = exportBytes(v);
    ASSERT_GE(bytes.size(), 104u);
    const uint8_t identifier[12] = {0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32,
                                    0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};
    EXPECT_EQ(std::memcmp(bytes.data(), identifier, 12), 0);
    const Ktx2 k = parseKtx2(bytes);
    // vkFormat R16G16B16A16_SFLOAT, typeSize 2, (Rx, 2 Ry, 3 Rz), not an array, one face, one
    // level, no supercompression.
    const uint32_t header[9] = {97, 2, 4, 4, 24, 0, 1, 1, 0};
    for (int i = 0; i < 9; ++i)
        EXPECT_EQ(k.header[i], header[i]) << "header word " << i;
    EXPECT_EQ(k.dfdOffset, 104u);
    EXPECT_EQ(k.dfdLength, 4u + 24u + 4u * 16u);
    EXPECT_EQ(u32(bytes, k.dfdOffset), k.dfdLength); // dfdTotalSize
    const std::vector<uint32_t> dfd = {0,
                                       2u | (88u << 16),
                                       1u | (1u << 8) | (1u << 16),
                                       0,
                                       8,
                                       0, // header of the Basic block
                                       0x00u | (15u << 16) | (0xC0u << 24),
                                       0,
                                       0xBF800000,
                                       0x3F800000, // R
                                       16u | (15u << 16) | (0xC1u << 24),
                                       0,
                                       0xBF800000,
                                       0x3F800000, // G
                                       32u | (15u << 16) | (0xC2u << 24),
                                       0,
                                       0xBF800000,
                                       0x3F800000, // B
                                       48u | (15u << 16) | (0xCFu << 24),
                                       0,
                                       0xBF800000,
                                       0x3F800000}; // A
    EXPECT_EQ(k.dfd, dfd);
    EXPECT_EQ(k.kvdOffset % 4, 0u);
    EXPECT_EQ(k.kvdOffset, k.dfdOffset + k.dfdLength);
    EXPECT_EQ(k.keyValues.at("KTXwriter"), "probekit");
    EXPECT_EQ(k.sgdOffset, 0u);
    EXPECT_EQ(k.sgdLength, 0u);
    EXPECT_EQ(k.levelOffset % 8, 0u); // lcm(texel block size 8, 4)
    EXPECT_GE(k.levelOffset, uint64_t(k.kvdOffset) + k.kvdLength);
    EXPECT_EQ(k.levelLength, 4u * 4u * 24u * 8u);
    EXPECT_EQ(k.levelUncompressed, k.levelLength);
    EXPECT_EQ(bytes.size(), k.levelOffset + k.levelLength);
    const auto t = nlohmann::json::parse(k.keyValues.at("probekit.transform"));
    EXPECT_EQ(t["translation"], nlohmann::json({0.0, 1.5, 0.0}));
    EXPECT_EQ(t["scale"], nlohmann::json({4.0, 3.0, 2.0}));
    EXPECT_EQ(glm::unpackHalf1x16(k.texels[3]), 1.0f); // alpha
}

// The shader's layout, not its doc comment's: a light from +X and nothing else puts its light
// in the first half of the X slices and leaves the second (-X) half at zero.
TEST(ExportBevy, PositiveFacesInTheFirstHalfNegativeInTheSecond) {
    VolumeDesc desc;
    desc.grid =
        grid::GridLayout({glm::vec3(0.0f), glm::vec3(1.0f)}, {2, 2, 2}, grid::PositionMode::Center);
    std::vector<sh::ShRgb> probes(8);
    for (sh::ShRgb& p : probes)
        p = sh::projectDelta({1.0f, 0.0f, 0.0f}, glm::vec3(1.0f), sh::Order::L2);
    const Ktx2 k = parseKtx2(exportBytes(makeVolume(desc, probes).value()));
    const AmbientCube cube = exporters::ambientCubeFromSh(probes[0], sh::Order::L2);
    EXPECT_GT(cube[0].x, 0.1f);
    EXPECT_EQ(cube[1].x, 0.0f); // the negative lobe of a lone light is clamped
    for (int y = 0; y < 4; ++y) {
        const float got = texel(k, {1, y, 1}).x; // z = 1 < Rz: an X slice
        EXPECT_EQ(got, y < 2 ? glm::unpackHalf1x16(glm::packHalf1x16(cube[0].x)) : 0.0f)
            << "t = " << y;
    }
    EXPECT_NEAR(texel(k, {0, 0, 2}).x, cube[2].x, kHalfRelative * cube[2].x); // +Y slice
    EXPECT_NEAR(texel(k, {0, 3, 5}).x, cube[5].x, kHalfRelative * cube[5].x); // -Z slice
}

TEST(ExportBevy, ConstantShIsExact) {
    sh::ShRgb s;
    s.rgb[0] = {1.0f, 2.0f, 0.5f};
    const AmbientCube cube = exporters::ambientCubeFromSh(s, sh::Order::L2);
    for (const glm::vec3& face : cube)
        EXPECT_EQ(face, sh::kY00 * s.rgb[0]);
    const auto e = cubeError(s, sh::Order::L2, cube);
    EXPECT_LT(e.relMax, 1e-6);
}

// Bands 0 and the diagonal of band 2 (Y20, Y22) lie in the span of n_x^2, n_y^2, n_z^2: exact.
TEST(ExportBevy, DiagonalBand2IsExact) {
    sh::ShRgb s;
    s.rgb[0] = glm::vec3(3.0f);
    s.rgb[6] = glm::vec3(0.4f, -0.2f, 0.1f);
    s.rgb[8] = glm::vec3(-0.3f, 0.5f, 0.2f);
    const auto e = cubeError(s, sh::Order::L2, exporters::ambientCubeFromSh(s, sh::Order::L2));
    EXPECT_LT(e.relMax, 2e-6);
}

// A linear field b.n projects onto n_a |n_a| with weight 5/4: the residual's RMS over the sphere
// is |b| sqrt((4 pi / 3 - 5 pi / 2 + 5 pi / 4) / (4 pi)) = |b| / sqrt(48), against |b| / sqrt(30)
// for point evaluation, whatever the direction of b.
TEST(ExportBevy, LinearShMatchesTheClosedForm) {
    sh::ShRgb s;
    s.rgb[0] = glm::vec3(10.0f);
    s.rgb[1] = glm::vec3(0.6f);
    s.rgb[3] = glm::vec3(-0.8f);
    const double b = (2.0 / 3.0) * kPi * sh::kY1 * 1.0; // |A1 kY1 L1| for |L1| = 1
    const double e0 = kPi * sh::kY00 * 10.0;
    const double rms = std::sqrt(e0 * e0 + b * b / 3.0); // RMS of E per channel
    const auto ls =
        cubeError(s, sh::Order::L1, exporters::ambientCubeFromSh(s, sh::Order::L1), 20000);
    const auto pe = cubeError(s, sh::Order::L1, pointEvaluation(s, sh::Order::L1), 20000);
    // 20000 Fibonacci points integrate these low-degree (kinked) polynomials to ~1e-4.
    EXPECT_NEAR(ls.relRms, b / std::sqrt(48.0) / rms, 2e-4);
    EXPECT_NEAR(pe.relRms, b / std::sqrt(30.0) / rms, 2e-4);
}

// Least squares is a minimum: moving any face of any channel either way raises the RMS error.
TEST(ExportBevy, LeastSquaresIsAMinimum) {
    std::mt19937 rng(7);
    for (int trial = 0; trial < 5; ++trial) {
        const sh::ShRgb s = randomSh(rng, 0.5f, 0.3f);
        const AmbientCube cube = exporters::ambientCubeFromSh(s, sh::Order::L2);
        const double best = cubeError(s, sh::Order::L2, cube).relRms;
        for (int f = 0; f < 6; ++f)
            for (float step : {-0.01f, 0.01f}) {
                AmbientCube moved = cube;
                moved[f] += glm::vec3(step);
                EXPECT_GT(cubeError(s, sh::Order::L2, moved).relRms, best) << "face " << f;
            }
    }
}

// The figures docs/engines.md#bevy quotes: least squares against point evaluation on
// random L2 probes and on a deringed lone light (the most directional probe a bake stores).
TEST(ExportBevy, LeastSquaresBeatsPointEvaluation) {
    std::mt19937 rng(11);
    double lsWorst = 0.0, peWorst = 0.0;
    for (int trial = 0; trial < 200; ++trial) {
        const sh::ShRgb s = randomSh(rng, 0.6f, 0.4f);
        const auto ls = cubeError(s, sh::Order::L2, exporters::ambientCubeFromSh(s, sh::Order::L2));
        const auto pe = cubeError(s, sh::Order::L2, pointEvaluation(s, sh::Order::L2));
        EXPECT_LE(ls.relRms, pe.relRms * (1.0 + 1e-6));
        lsWorst = std::max(lsWorst, ls.relRms);
        peWorst = std::max(peWorst, pe.relRms);
    }
    const sh::ShRgb light =
        sh::deringIrradiance(sh::projectDelta(glm::normalize(glm::vec3(0.3f, 0.8f, -0.5f)),
                                              glm::vec3(1.0f), sh::Order::L2),
                             sh::Order::L2)
            .sh;
    const auto ls =
        cubeError(light, sh::Order::L2, exporters::ambientCubeFromSh(light, sh::Order::L2));
    const auto pe = cubeError(light, sh::Order::L2, pointEvaluation(light, sh::Order::L2));
    std::printf("random L2 probes: worst relative RMS %.4f (least squares) vs %.4f (point "
                "evaluation)\nlone light: least squares %.4f RMS %.4f max, point evaluation "
                "%.4f RMS %.4f max\n",
                lsWorst, peWorst, ls.relRms, ls.relMax, pe.relRms, pe.relMax);
    EXPECT_LT(ls.relRms, pe.relRms);
}

} // namespace

namespace {

// The smallest and largest face values of the volume's probes (the largest is the half
// rounding's scale; the smallest must be above 0, where no face is clamped and the projection
// is linear).
std::pair<double, double> faceRange(const Volume& v) {
    double lo = 1e30, hi = 0.0;
    for (size_t i = 0; i < v.probeCount(); ++i)
        for (const glm::vec3& f : exporters::ambientCubeFromSh(v.probe(i), v.desc.shOrder)) {
            lo = std::min({lo, double(f.x), double(f.y), double(f.z)});
            hi = std::max({hi, double(f.x), double(f.y), double(f.z)});
        }
    return {lo, hi};
}

// The file decoded by Bevy's rules against the CPU sampler, at the points where the exporter
// measures its projection error (and beyond the outer voxel centres, where both clamp):
//  * per sample, against pi x the ambient cube of the sampler's SH at p: the two differ only by
//    half rounding and float arithmetic (the projection is linear and the faces of these
//    volumes are positive, so projecting then interpolating is interpolating then projecting);
//  * over all samples, against E itself: the relative RMS and max the exporter states, to
//    within what half rounding can move them (RMS and max are 1-Lipschitz in the largest
//    per-sample difference, sqrt(3) x the per-channel bound over three channels).
void checkAgainstSampler(const Volume& v) {
    std::vector<std::string> notes;
    const BevyVolume bevy = loadBevy(exportBytes(v, &notes));
    const Volume dense = exporters::denseAxisAligned(v, glm::uvec3(0)).value().volume;
    const auto [smallest, largest] = faceRange(dense);
    ASSERT_GT(smallest, 0.0) << "a clamped face: the projection is not linear here";
    const double scale = kPi * largest;
    const double perChannel = (kHalfRelative + kFloatRelative) * scale + kPi * kHalfAbsolute;
    grid::Aabb box = dense.desc.grid.worldBounds();
    box.min -= 0.2f * box.size(); // a margin outside: Bevy clamps as the sampler does
    box.max += 0.2f * box.size();
    const auto samples = exporters::errorSamples(box, 99, 3000);
    double err2 = 0.0, ref2 = 0.0, worst = 0.0;
    for (const auto& s : samples) {
        const sh::ShRgb coeffs = runtime::sampleVolumeSh(dense, s.position);
        const glm::vec3 got = bevyIrradiance(bevy, s.position, s.normal);
        const glm::vec3 want =
            float(kPi) * exporters::evalAmbientCube(
                             exporters::ambientCubeFromSh(coeffs, v.desc.shOrder), s.normal);
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(got[c], want[c], perChannel)
                << "at " << s.position.x << "," << s.position.y << "," << s.position.z;
        const glm::vec3 e = sh::irradiance(coeffs, v.desc.shOrder, s.normal);
        const double d = glm::length(got - e);
        err2 += d * d;
        ref2 += glm::dot(e, e);
        worst = std::max(worst, d);
    }
    const double rms = std::sqrt(ref2 / samples.size());
    const exporters::ProjectionError stated = exporters::ambientCubeError(dense, samples);
    const double slack = std::sqrt(3.0) * perChannel / rms;
    EXPECT_NEAR(std::sqrt(err2 / samples.size()) / rms, stated.relRms, slack);
    EXPECT_NEAR(worst / rms, stated.relMax, slack);
    std::printf("%s %s: projection error %.4f RMS %.4f max; decoder within %.2g of it\n",
                v.desc.grid.mode() == grid::PositionMode::Corner ? "corner" : "center",
                v.desc.shOrder == sh::Order::L2 ? "L2" : "L1", stated.relRms, stated.relMax, slack);
}

TEST(ExportBevy, DecodedByBevyRulesMatchesCpuSamplerCenterL2) {
    checkAgainstSampler(
        skyAndLight(grid::PositionMode::Center, {8, 4, 4}, sh::Order::L2, 0.6f, 2.0f));
}

TEST(ExportBevy, DecodedByBevyRulesMatchesCpuSamplerCornerL2) {
    checkAgainstSampler(
        skyAndLight(grid::PositionMode::Corner, {4, 8, 2}, sh::Order::L2, 0.6f, 2.0f));
}

TEST(ExportBevy, DecodedByBevyRulesMatchesCpuSamplerCenterL1) {
    // L1's lone-light lobe reaches further below its mean than L2's: a weaker light keeps every
    // face positive.
    checkAgainstSampler(
        skyAndLight(grid::PositionMode::Center, {4, 4, 4}, sh::Order::L1, 0.6f, 0.5f));
}

// A rotated volume goes through denseAxisAligned; its error joins the notes.
TEST(ExportBevy, RotatedVolumeIsResampledAndSaysSo) {
    Volume v = skyAndLight(grid::PositionMode::Center, {4, 4, 4}, sh::Order::L2, 0.6f, 2.0f);
    v.desc.grid.setFrame({glm::angleAxis(0.5f, glm::vec3(0.0f, 1.0f, 0.0f)), glm::vec3(1.0f)});
    std::vector<std::string> notes;
    const auto bytes = exportBytes(v, &notes);
    ASSERT_FALSE(bytes.empty());
    EXPECT_TRUE(std::any_of(notes.begin(), notes.end(), [](const std::string& n) {
        return n.find("resampled") != std::string::npos;
    }));
    EXPECT_EQ(parseKtx2(bytes).width(), 4u);
}

TEST(ExportBevy, ValuesBeyondHalfAreAnErrorNamingTheVoxel) {
    Volume v = skyAndLight(grid::PositionMode::Center, {2, 2, 2}, sh::Order::L2, 0.6f, 2.0f);
    std::vector<sh::ShRgb> probes(8);
    for (size_t i = 0; i < 8; ++i)
        probes[i] = v.probe(i);
    // E / pi = kY00 L00 on every face: 7e4 / kY00 puts it at 7e4 > 65504.
    probes[5].rgb[0] = glm::vec3(1.0f, 7e4f / sh::kY00, 1.0f);
    const Volume big = makeVolume(v.desc, probes).value();
    auto r = exporters::exportBevy(big, {}, "out.ktx2");
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code, ErrorCode::OutOfRange);
    EXPECT_NE(r.error().message.find("voxel (1, 0, 1) face +X"), std::string::npos)
        << r.error().message;
}

} // namespace
