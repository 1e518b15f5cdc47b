// Tests of the three.js exporter (exporters/include/probekit/exporters/three.hpp): the files are
// read back and decoded by the rules of three.js 0.187's LightProbeGrid shader (world -> uvw with
// the half-spacing normal offset and clamp to the outermost cell centres, one linear-filtered
// fetch per atlas sub-volume, SH -> irradiance with its constants), and with the visibility
// weights of integrations/three/probekit-three.js's chunk; the result must be the CPU sampler's
// irradiance (runtime/include/probekit/runtime/sampler.hpp) at the same sample point.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Imath/half.h>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../gpu/bricked_test_volume.hpp"
#include "../gpu/dense_test_volume.hpp"
#include "probekit/exporters/resample.hpp"
#include "probekit/exporters/three.hpp"
#include "probekit/formats/visibility.hpp"
#include "probekit/runtime/sampler.hpp"

using namespace probekit;

namespace {

// binary16 rounds to nearest with an 11-bit significand: each stored coefficient is within 2^-11
// of its value, relative (kHalfAbsolute covers the subnormal range below 6.1e-5). E is a sum of
// coefficients times the basis and the convex interpolation weights, so |dE| is at most 2^-11
// times the sum of |A_l Y_lm(n)| |L_lm| over the coefficients (kHalfRelative x absSum below).
constexpr float kHalfRelative = 1.0f / 2048.0f;
constexpr float kHalfAbsolute = 1.0e-7f;
// float32 rounding of the two evaluations (eight taps, nine terms, coordinates divided by the
// spacing), relative to the same absolute sum.
constexpr float kFloatRelative = 2.0e-5f;
constexpr int kSamples = 400;

using VolumeSpec = densetest::BasicVolumeSpec<4>;

// A smooth, different field per coefficient and channel whose irradiance stays positive.
sh::ShRgb smoothField(glm::vec3 w) {
    sh::ShRgb s;
    for (int k = 0; k < sh::kMaxCoefficients; ++k)
        for (int c = 0; c < 3; ++c)
            s.rgb[k][c] = (k == 0 ? 8.0f + float(c) : 0.6f / float(1 + k / 4)) *
                          std::sin(0.7f * w.x + 1.3f * w.y - 0.4f * w.z + 0.9f * float(k + 3 * c));
    for (int c = 0; c < 3; ++c)
        s.rgb[0][c] = std::abs(s.rgb[0][c]) + 6.0f;
    return s;
}

Volume denseVolume(const VolumeSpec& spec, std::vector<uint8_t> vis = {}) {
    const VolumeDesc desc = densetest::volumeDesc(spec);
    const auto probes =
        densetest::fieldProbes(desc, [](glm::uvec3, glm::vec3 w) { return smoothField(w); });
    Result<Volume> v = makeVolume(desc, probes, {}, vis);
    EXPECT_TRUE(v.ok()) << v.error().message;
    return std::move(v).value();
}

// The exported files as three.js and probekit-three.js read them.
struct ThreeFiles {
    nlohmann::json header;
    std::vector<uint8_t> bin;
    glm::vec3 min{0.0f}, max{0.0f};
    glm::uvec3 res{0};
    uint32_t depth = 0;
    bool half = true;
};

ThreeFiles readBack(const exporters::ExportResult& r) {
    ThreeFiles f;
    EXPECT_EQ(r.files.size(), 2u);
    const auto& json = r.files[0].bytes;
    f.header = nlohmann::json::parse(std::string(json.begin(), json.end()));
    f.bin = r.files[1].bytes;
    const auto& h = f.header;
    for (int a = 0; a < 3; ++a) {
        f.min[a] = h["bounds"]["min"][a].get<float>();
        f.max[a] = h["bounds"]["max"][a].get<float>();
        f.res[a] = h["resolution"][a].get<uint32_t>();
    }
    f.depth = h["atlas"]["depth"].get<uint32_t>();
    f.half = h["atlas"]["type"] == "half";
    EXPECT_EQ(f.depth, 7 * (f.res.z + 2));
    EXPECT_EQ(h["atlas"]["width"].get<uint32_t>(), f.res.x);
    EXPECT_EQ(h["atlas"]["byteLength"].get<size_t>(),
              size_t(f.res.x) * f.res.y * f.depth * 4 * (f.half ? 2 : 4));
    return f;
}

glm::vec4 atlasTexel(const ThreeFiles& f, glm::ivec3 t) {
    const size_t texel = (size_t(t.z) * f.res.y + size_t(t.y)) * f.res.x + size_t(t.x);
    glm::vec4 v;
    for (int j = 0; j < 4; ++j) {
        if (f.half) {
            uint16_t bits = 0;
            std::memcpy(&bits, &f.bin[(texel * 4 + size_t(j)) * 2], 2);
            Imath::half h;
            h.setBits(bits);
            v[j] = float(h);
        } else {
            std::memcpy(&v[j], &f.bin[(texel * 4 + size_t(j)) * 4], 4);
        }
    }
    return v;
}

// GL_LINEAR with CLAMP_TO_EDGE at normalised coordinate uvw (Data3DTexture's defaults).
glm::vec4 linearFetch(const ThreeFiles& f, glm::vec3 uvw) {
    const glm::ivec3 size(f.res.x, f.res.y, f.depth);
    const glm::vec3 s = uvw * glm::vec3(size) - 0.5f;
    const glm::vec3 lower = glm::floor(s);
    const glm::vec3 t = s - lower;
    glm::vec4 sum(0.0f);
    for (int corner = 0; corner < 8; ++corner) {
        glm::ivec3 at;
        float w = 1.0f;
        for (int a = 0; a < 3; ++a) {
            const int up = (corner >> a) & 1;
            at[a] = std::clamp(int(lower[a]) + up, 0, size[a] - 1);
            w *= up ? t[a] : 1.0f - t[a];
        }
        sum += w * atlasTexel(f, at);
    }
    return sum;
}

// The 27 floats of the seven sub-volume samples -> E(n), three.js's constants and its clamp.
glm::vec3 threeIrradiance(const glm::vec4 s[7], glm::vec3 n) {
    glm::vec3 c[9];
    for (int k = 0; k < 9; ++k)
        for (int ch = 0; ch < 3; ++ch)
            c[k][ch] = s[(3 * k + ch) / 4][(3 * k + ch) % 4];
    const float x = n.x, y = n.y, z = n.z;
    glm::vec3 e = c[0] * 0.886227f;
    e += c[1] * 2.0f * 0.511664f * y + c[2] * 2.0f * 0.511664f * z + c[3] * 2.0f * 0.511664f * x;
    e += c[4] * 2.0f * 0.429043f * x * y + c[5] * 2.0f * 0.429043f * y * z;
    e += c[6] * (0.743125f * z * z - 0.247708f) + c[7] * 2.0f * 0.429043f * x * z;
    e += c[8] * 0.429043f * (x * x - y * y);
    return glm::max(e, glm::vec3(0.0f));
}

glm::vec3 spacingOf(const ThreeFiles& f) {
    return (f.max - f.min) / glm::vec3(f.res);
}

// three.js's sample point p + n spacing / 2, or nothing where its bounds test leaves the
// fragment out of the grid (samples exactly on the bounds are avoided by the callers).
std::optional<glm::vec3> samplePoint(const ThreeFiles& f, glm::vec3 p, glm::vec3 n) {
    const glm::vec3 q = p + n * spacingOf(f) * 0.5f;
    if (glm::any(glm::lessThan(q, f.min)) || glm::any(glm::greaterThan(q, f.max)))
        return std::nullopt;
    return q;
}

// lightprobes_pars_fragment's getLightProbeGridIrradiance.
glm::vec3 decodePlain(const ThreeFiles& f, glm::vec3 q, glm::vec3 n) {
    const glm::vec3 res(f.res);
    const glm::vec3 uvw = glm::clamp((q - f.min) / (f.max - f.min), 0.5f / res, 1.0f - 0.5f / res);
    const float padded = res.z + 2.0f;
    glm::vec4 s[7];
    for (int t = 0; t < 7; ++t)
        s[t] =
            linearFetch(f, glm::vec3(uvw.x, uvw.y,
                                     (uvw.z * res.z + 1.0f + float(t) * padded) / float(f.depth)));
    return threeIrradiance(s, n);
}

// probekit-three.js's visibility chunk: the eight taps fetched one by one, each trilinear weight
// times (vis + floor), normalised.
glm::vec3 decodeVisible(const ThreeFiles& f, glm::vec3 q, glm::vec3 n) {
    const auto& vj = f.header["visibility"];
    const size_t vis_at = vj["byteOffset"].get<size_t>();
    const glm::ivec3 res(f.res);
    const glm::vec3 g =
        glm::clamp((q - f.min) / spacingOf(f) - 0.5f, glm::vec3(0.0f), glm::vec3(res - 1));
    const glm::ivec3 lower(glm::floor(g));
    glm::vec4 s[7] = {};
    float weight_sum = 0.0f;
    for (int corner = 0; corner < 8; ++corner) {
        glm::ivec3 at;
        float w = 1.0f;
        uint8_t qbytes[6];
        for (int a = 0; a < 3; ++a) {
            const int up = (corner >> a) & 1;
            at[a] = std::min(lower[a] + up, res[a] - 1);
            w *= up ? g[a] - float(lower[a]) : 1.0f - (g[a] - float(lower[a]));
        }
        const size_t layer = size_t(res.x) * size_t(res.y);
        const size_t in_layer = size_t(at.y) * size_t(res.x) + size_t(at.x);
        std::memcpy(qbytes, &f.bin[vis_at + 4 * (size_t(at.z) * layer + in_layer)], 4);
        std::memcpy(qbytes + 4, &f.bin[vis_at + 4 * ((size_t(res.z + at.z)) * layer + in_layer)],
                    2);
        w *= visibility::probeVisibility(qbytes, g - glm::vec3(at)) + visibility::kFloor;
        weight_sum += w;
        for (int t = 0; t < 7; ++t)
            s[t] += w * atlasTexel(f, {at.x, at.y, t * (res.z + 2) + 1 + at.z});
    }
    for (int t = 0; t < 7; ++t)
        s[t] /= weight_sum;
    return threeIrradiance(s, n);
}

// Sum over coefficients of |A_l Y_lm(n)| max over probes |L_lm|, per channel: what the rounding
// of every coefficient is relative to.
glm::vec3 absSum(const Volume& v, glm::vec3 n) {
    glm::vec3 sum(0.0f);
    for (int k = 0; k < sh::kMaxCoefficients; ++k) {
        sh::ShRgb unit;
        unit.rgb[k] = glm::vec3(1.0f);
        const float basis = std::abs(sh::irradiance(unit, sh::Order::L2, n).x);
        glm::vec3 largest(0.0f);
        for (size_t i = 0; i < v.probeCount(); ++i)
            largest = glm::max(largest, glm::abs(v.probe(i).rgb[k]));
        sum += basis * (largest + kHalfAbsolute);
    }
    return sum;
}

glm::vec3 randomNormal(std::mt19937& rng) {
    std::normal_distribution<float> d;
    for (;;) {
        const glm::vec3 n(d(rng), d(rng), d(rng));
        if (glm::length(n) > 1e-3f)
            return glm::normalize(n);
    }
}

// Random points of the exported box and normals: three.js's decoding (with or without the
// visibility chunk) against VolumeSet::irradiance at the same sample point. Returns how many
// samples were compared.
int compareWithSampler(const Volume& reference, const ThreeFiles& f, bool visible,
                       float tolerance_relative) {
    const runtime::VolumeSet set({reference});
    std::mt19937 rng(28);
    std::uniform_real_distribution<float> u(0.01f, 0.99f);
    int compared = 0;
    for (int i = 0; i < kSamples; ++i) {
        const glm::vec3 p = f.min + glm::vec3(u(rng), u(rng), u(rng)) * (f.max - f.min);
        const glm::vec3 n = randomNormal(rng);
        const std::optional<glm::vec3> q = samplePoint(f, p, n);
        if (!q)
            continue;
        const glm::vec3 three = visible ? decodeVisible(f, *q, n) : decodePlain(f, *q, n);
        const glm::vec3 expected = glm::max(set.irradiance(*q, n), glm::vec3(0.0f));
        const glm::vec3 bound = tolerance_relative * absSum(reference, n);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(three[c], expected[c], bound[c]) << "sample " << i << " channel " << c;
        ++compared;
    }
    return compared;
}

exporters::ExportResult exportOk(const Volume& v, exporters::ThreeOptions options = {}) {
    Result<exporters::ExportResult> r = exporters::exportThree(v, options, "grid.json");
    EXPECT_TRUE(r.ok()) << r.error().message;
    return std::move(r).value();
}

VolumeSpec specOf(grid::PositionMode mode) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(-1.0f, 0.0f, -2.0f), glm::vec3(3.0f, 2.0f, 2.0f)};
    spec.resolution = {8, 4, 4};
    spec.mode = mode;
    return spec;
}

} // namespace

TEST(ExportThree, WritesTheJsonAndTheBinBesideIt) {
    const exporters::ExportResult r = exportOk(denseVolume(specOf(grid::PositionMode::Center)));
    ASSERT_EQ(r.files.size(), 2u);
    EXPECT_EQ(r.files[0].path, "grid.json");
    EXPECT_EQ(r.files[1].path, "grid.bin");
    const ThreeFiles f = readBack(r);
    EXPECT_EQ(f.header["atlas"]["file"], "grid.bin");
    EXPECT_EQ(f.bin.size(), f.header["atlas"]["byteLength"].get<size_t>());
    EXPECT_FALSE(f.header.contains("visibility"));
    EXPECT_FALSE(f.header["source"]["resampled"].get<bool>());
}

TEST(ExportThree, CentreModeHalfDecodesToTheSamplerWithinHalfPrecision) {
    const Volume v = denseVolume(specOf(grid::PositionMode::Center));
    const ThreeFiles f = readBack(exportOk(v));
    EXPECT_EQ(f.min, glm::vec3(-1.0f, 0.0f, -2.0f));
    EXPECT_EQ(f.max, glm::vec3(3.0f, 2.0f, 2.0f));
    EXPECT_GT(compareWithSampler(v, f, false, kHalfRelative + kFloatRelative), kSamples / 2);
}

TEST(ExportThree, CentreModeFloatDecodesToTheSamplerWithinFloatRounding) {
    const Volume v = denseVolume(specOf(grid::PositionMode::Center));
    const ThreeFiles f = readBack(exportOk(v, {glm::uvec3(0), false}));
    EXPECT_FALSE(f.half);
    EXPECT_GT(compareWithSampler(v, f, false, kFloatRelative), kSamples / 2);
}

TEST(ExportThree, CornerModeProbesAreThreeCellCentres) {
    // Corner-mode probes sit on the faces; the exported box is half a spacing larger on every
    // side so that three.js's cell centres are those probes.
    const Volume v = denseVolume(specOf(grid::PositionMode::Corner));
    const ThreeFiles f = readBack(exportOk(v));
    const glm::vec3 half_spacing = 0.5f * v.desc.grid.spacing();
    EXPECT_EQ(f.min, glm::vec3(-1.0f, 0.0f, -2.0f) - half_spacing);
    EXPECT_EQ(f.max, glm::vec3(3.0f, 2.0f, 2.0f) + half_spacing);
    EXPECT_GT(compareWithSampler(v, f, false, kHalfRelative + kFloatRelative), kSamples / 2);
}

TEST(ExportThree, BrickedVolumeIsResampledWithItsReportedError) {
    VolumeDesc desc;
    desc.name = "bricked";
    const glm::uvec3 top(2, 2, 2);
    desc.grid = grid::GridLayout({glm::vec3(-1.0f, 0.5f, -3.0f), glm::vec3(2.0f, 2.0f, 1.0f)}, top,
                                 grid::PositionMode::Center);
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = bricktest::mixedLayout(top);
    const Volume source = bricktest::makeBrickedVolume(desc, smoothField, true);
    // An explicit resolution keeps the test fast (resampling measures its error at many points).
    const glm::uvec3 resolution(16, 16, 8);
    Result<exporters::Resampled> dense = exporters::denseAxisAligned(source, resolution);
    ASSERT_TRUE(dense.ok()) << dense.error().message;
    const exporters::ExportResult r = exportOk(source, {resolution, true});
    const ThreeFiles f = readBack(r);
    const auto& src = f.header["source"];
    EXPECT_TRUE(src["resampled"].get<bool>());
    EXPECT_EQ(src["layout"], "bricked");
    EXPECT_DOUBLE_EQ(src["resampleRelRms"].get<double>(), dense.value().relRms);
    EXPECT_DOUBLE_EQ(src["resampleRelMax"].get<double>(), dense.value().relMax);
    ASSERT_FALSE(r.notes.empty());
    EXPECT_NE(r.notes[0].find("resampled"), std::string::npos) << r.notes[0];
    // What three.js draws is the resampled grid, to half precision ...
    EXPECT_GT(compareWithSampler(dense.value().volume, f, false, kHalfRelative + kFloatRelative),
              kSamples / 2);
    // ... and its error against the source is measured and reported: nonzero (the bricked
    // source interpolates its own probes, not the grid's), and a few percent at most for a smooth
    // field on a 16 x 16 x 8 grid.
    EXPECT_GT(dense.value().relRms, 0.0);
    EXPECT_LE(dense.value().relRms, dense.value().relMax);
    EXPECT_LT(dense.value().relMax, 0.1);
}

TEST(ExportThree, HalfOverflowFailsAndSuggestsFloat) {
    VolumeSpec spec = specOf(grid::PositionMode::Center);
    const VolumeDesc desc = densetest::volumeDesc(spec);
    auto probes =
        densetest::fieldProbes(desc, [](glm::uvec3, glm::vec3 w) { return smoothField(w); });
    probes[5].rgb[2].y = 70000.0f;
    Result<Volume> v = makeVolume(desc, probes);
    ASSERT_TRUE(v.ok()) << v.error().message;
    Result<exporters::ExportResult> as_half = exporters::exportThree(v.value(), {}, "grid.json");
    ASSERT_FALSE(as_half.ok());
    const std::string& message = as_half.error().message;
    EXPECT_NE(message.find("probe 5"), std::string::npos) << message;
    EXPECT_NE(message.find("--float"), std::string::npos) << message;
    EXPECT_TRUE(exporters::exportThree(v.value(), {glm::uvec3(0), false}, "grid.json").ok());
}

TEST(ExportThree, RefusesAHeaderNamedLikeItsData) {
    const Result<exporters::ExportResult> r =
        exporters::exportThree(denseVolume(specOf(grid::PositionMode::Center)), {}, "grid.bin");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("OUT.json"), std::string::npos) << r.error().message;
}

TEST(ExportThree, VisibilityTextureReproducesTheSamplersWeights) {
    // Walls close to some probes on some half-axes, clear elsewhere: taps are hidden in places.
    for (grid::PositionMode mode : {grid::PositionMode::Center, grid::PositionMode::Corner}) {
        const VolumeSpec spec = specOf(mode);
        std::vector<uint8_t> vis(spec.resolution.x * spec.resolution.y * spec.resolution.z * 6);
        std::mt19937 rng(7);
        for (uint8_t& q : vis)
            q = rng() % 3 == 0 ? uint8_t(rng() % 200) : visibility::kClear;
        const Volume v = denseVolume(spec, vis);
        const exporters::ExportResult r = exportOk(v);
        const ThreeFiles f = readBack(r);
        ASSERT_TRUE(f.header.contains("visibility"));
        const auto& vj = f.header["visibility"];
        EXPECT_EQ(vj["byteOffset"].get<size_t>(), f.header["atlas"]["byteLength"].get<size_t>());
        EXPECT_EQ(f.bin.size(), vj["byteOffset"].get<size_t>() + vj["byteLength"].get<size_t>());
        EXPECT_EQ(vj["depth"].get<uint32_t>(), 2 * spec.resolution.z);
        EXPECT_GT(compareWithSampler(v, f, true, kHalfRelative + kFloatRelative), kSamples / 2);
    }
}
