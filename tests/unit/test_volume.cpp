#include <cmath>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "probekit/formats/volume.hpp"

using namespace probekit;

namespace {
// binary16 has an 11-bit significand: round to nearest gives relative error <= 2^-11.
constexpr float kHalfRelative = 1.0f / 2048.0f;

VolumeDesc desc(sh::Order order, Storage storage, glm::uvec3 res = glm::uvec3(2, 4, 2)) {
    VolumeDesc d;
    d.name = "test";
    d.grid = grid::GridLayout({glm::vec3(0), glm::vec3(1)}, res, grid::PositionMode::Center);
    d.shOrder = order;
    d.storage = storage;
    return d;
}

// Every coefficient different, so a packing slip shows up.
sh::ShRgb distinctSh(size_t probe, sh::Order order) {
    sh::ShRgb s;
    for (int i = 0; i < sh::coefficientCount(order); ++i) {
        for (int c = 0; c < 3; ++c) {
            s.rgb[i][c] = float(probe) * 100.0f + float(i) * 10.0f + float(c) + 0.25f;
        }
    }
    return s;
}
} // namespace

TEST(VolumePacking, RoundTripsEveryCoefficientL1AndL2) {
    for (sh::Order order : {sh::Order::L1, sh::Order::L2}) {
        const sh::ShRgb s = distinctSh(3, order);
        glm::vec4 texels[7];
        packProbe(s, order, texels);
        EXPECT_EQ(unpackProbe(texels, order), s);
    }
}

TEST(VolumePacking, LayoutMatchesDocumentation) {
    const sh::ShRgb s = distinctSh(0, sh::Order::L2);
    glm::vec4 t[7];
    packProbe(s, sh::Order::L2, t);
    // plane c = (L00, L1-1, L10, L11) of channel c
    EXPECT_EQ(t[1], glm::vec4(s.rgb[0].y, s.rgb[1].y, s.rgb[2].y, s.rgb[3].y));
    // plane 3 = (L2-2.r, L2-2.g, L2-2.b, L2-1.r)
    EXPECT_EQ(t[3], glm::vec4(s.rgb[4].x, s.rgb[4].y, s.rgb[4].z, s.rgb[5].x));
    // plane 4 = (L2-1.g, L2-1.b, L20.r, L20.g)
    EXPECT_EQ(t[4], glm::vec4(s.rgb[5].y, s.rgb[5].z, s.rgb[6].x, s.rgb[6].y));
    // plane 5 = (L20.b, L21.r, L21.g, L21.b)
    EXPECT_EQ(t[5], glm::vec4(s.rgb[6].z, s.rgb[7].x, s.rgb[7].y, s.rgb[7].z));
    // plane 6 = (L22.r, L22.g, L22.b, 0)
    EXPECT_EQ(t[6], glm::vec4(s.rgb[8].x, s.rgb[8].y, s.rgb[8].z, 0.0f));
}

TEST(VolumeMake, FloatIsBitExactAndPlaneMajor) {
    VolumeDesc d = desc(sh::Order::L2, Storage::Float32);
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        probes[i] = distinctSh(i, sh::Order::L2);
    }
    auto v = makeVolume(d, probes);
    ASSERT_TRUE(v.ok()) << v.error().message;
    EXPECT_TRUE(validateVolume(v.value()).ok());
    EXPECT_EQ(v.value().texelsF32.size(), 7 * probes.size() * 4);
    EXPECT_EQ(v.value().texelBytes(), 7 * probes.size() * 16);
    for (size_t i = 0; i < probes.size(); ++i) {
        EXPECT_EQ(v.value().probe(i), probes[i]);
    }
    // texel (plane p, probe i) starts at 4 * (p * probeCount + i)
    EXPECT_EQ(v.value().texelsF32[4 * (2 * probes.size() + 5)], probes[5].rgb[0].z);
}

TEST(VolumeMake, HalfWithinHalfPrecision) {
    VolumeDesc d = desc(sh::Order::L1, Storage::Float16);
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        probes[i] = distinctSh(i, sh::Order::L1);
    }
    auto v = makeVolume(d, probes);
    ASSERT_TRUE(v.ok()) << v.error().message;
    EXPECT_TRUE(v.value().texelsF32.empty());
    EXPECT_EQ(v.value().texelBytes(), 3 * probes.size() * 8);
    for (size_t i = 0; i < probes.size(); ++i) {
        const sh::ShRgb got = v.value().probe(i);
        for (int k = 0; k < 4; ++k) {
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(got.rgb[k][c], probes[i].rgb[k][c],
                            std::abs(probes[i].rgb[k][c]) * kHalfRelative);
            }
        }
    }
}

TEST(VolumeMake, HalfOverflowIsAnErrorNamingVolumeAndValue) {
    VolumeDesc d = desc(sh::Order::L2, Storage::Float16);
    d.name = "sunlit_hall";
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    probes[6].rgb[0].x = 70000.0f;
    probes[3].rgb[2].y = -90000.0f;
    auto v = makeVolume(d, probes);
    ASSERT_FALSE(v.ok());
    EXPECT_EQ(v.error().code, ErrorCode::OutOfRange);
    EXPECT_NE(v.error().message.find("sunlit_hall"), std::string::npos) << v.error().message;
    EXPECT_NE(v.error().message.find("90000"), std::string::npos) << v.error().message;
    EXPECT_NE(v.error().message.find("float"), std::string::npos) << v.error().message;
    // The same data stored as float is fine.
    d.storage = Storage::Float32;
    EXPECT_TRUE(makeVolume(d, probes).ok());
}

TEST(VolumeMake, RejectsNonFiniteAndWrongCounts) {
    VolumeDesc d = desc(sh::Order::L1, Storage::Float32);
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    probes[2].rgb[1].z = NAN;
    EXPECT_EQ(makeVolume(d, probes).error().code, ErrorCode::NonFinite);
    probes[2].rgb[1].z = 0.0f;
    std::vector<sh::ShRgb> short_probes(3);
    EXPECT_EQ(makeVolume(d, short_probes).error().code, ErrorCode::InconsistentSize);
    std::vector<uint8_t> validity(5, kProbeValid);
    EXPECT_EQ(makeVolume(d, probes, validity).error().code, ErrorCode::InconsistentSize);
}

TEST(VolumeMake, KeepsValidityAndCountsIt) {
    VolumeDesc d = desc(sh::Order::L1, Storage::Float32);
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    std::vector<uint8_t> validity(probes.size(), kProbeValid);
    validity[0] = validity[7] = kProbeInvalid;
    auto v = makeVolume(d, probes, validity);
    ASSERT_TRUE(v.ok());
    EXPECT_EQ(v.value().validCount(), probes.size() - 2);
}

TEST(VolumeValidate, CatchesInconsistentTexelsAndValidity) {
    VolumeDesc d = desc(sh::Order::L2, Storage::Float32);
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    Volume v = makeVolume(d, probes).value();
    v.texelsF32.pop_back();
    EXPECT_EQ(validateVolume(v).error().code, ErrorCode::InconsistentSize);
    v.texelsF32.push_back(0.0f);
    v.validity[1] = 7;
    EXPECT_EQ(validateVolume(v).error().code, ErrorCode::OutOfRange);
    v.validity[1] = kProbeValid;
    v.desc.fadeDistance = -1.0f;
    EXPECT_EQ(validateVolume(v).error().code, ErrorCode::OutOfRange);
}

namespace {
// Two level-0 bricks along x, the second split into eight level-1 bricks (max level 1).
VolumeDesc brickedDesc() {
    VolumeDesc d = desc(sh::Order::L1, Storage::Float32, glm::uvec3(2, 1, 1));
    d.name = "bricked_hall";
    d.layout = VolumeLayout::Bricked;
    d.bricks.maxLevel = 1;
    d.bricks.bricks.push_back({glm::uvec3(0, 0, 0), 0});
    for (uint32_t k = 0; k < 8; ++k) {
        d.bricks.bricks.push_back({glm::uvec3(2 + (k & 1), (k >> 1) & 1, k >> 2), 1});
    }
    return d;
}
} // namespace

TEST(VolumeMake, BrickedBuildsTheIndirectionAndCounts64ProbesPerBrick) {
    const VolumeDesc d = brickedDesc();
    EXPECT_EQ(d.probeCount(), 9u * 64u);
    std::vector<sh::ShRgb> probes(d.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        probes[i] = distinctSh(i, sh::Order::L1);
    }
    auto made = makeVolume(d, probes);
    ASSERT_TRUE(made.ok()) << made.error().message;
    const Volume& v = made.value();
    // Finest cells 4 x 2 x 2: x 0..1 belong to brick 0, x = 2 + i to level-1 bricks 1 + i, ...
    const std::vector<uint32_t> expected = {0, 0, 1, 2, 0, 0, 3, 4, 0, 0, 5, 6, 0, 0, 7, 8};
    EXPECT_EQ(v.indirection, expected);
    EXPECT_EQ(v.gpuBytes(), v.texelBytes() + 16 * sizeof(uint32_t));
    EXPECT_EQ(v.probe(64 * 3 + 5), probes[64 * 3 + 5]) << "brick order is storage order";
    EXPECT_TRUE(validateVolume(v).ok());

    // Probe count is bricks * 64, not the grid's.
    std::vector<sh::ShRgb> grid_count(d.grid.probeCount());
    EXPECT_EQ(makeVolume(d, grid_count).error().code, ErrorCode::InconsistentSize);
}

TEST(VolumeMake, BrickedRejectsALayoutThatDoesNotTile) {
    VolumeDesc d = brickedDesc();
    d.bricks.bricks.pop_back();
    std::vector<sh::ShRgb> probes(d.probeCount());
    auto made = makeVolume(d, probes);
    ASSERT_FALSE(made.ok());
    EXPECT_EQ(made.error().code, ErrorCode::InconsistentSize);
    EXPECT_NE(made.error().message.find("volume 'bricked_hall': finest cell 3,1,1"),
              std::string::npos)
        << made.error().message;
}

TEST(VolumeValidate, CatchesBrickedInconsistencies) {
    const VolumeDesc d = brickedDesc();
    std::vector<sh::ShRgb> probes(d.probeCount());
    const Volume good = makeVolume(d, probes).value();

    Volume stale = good;
    stale.indirection[3] = 0;
    EXPECT_EQ(validateVolume(stale).error().code, ErrorCode::InconsistentSize);

    Volume corner = good;
    corner.desc.grid = grid::GridLayout({glm::vec3(0), glm::vec3(1)}, glm::uvec3(2, 2, 2),
                                        grid::PositionMode::Corner);
    EXPECT_EQ(validateVolume(corner).error().code, ErrorCode::BadEnum);

    Volume dense_with_bricks = good;
    dense_with_bricks.desc.layout = VolumeLayout::Dense;
    EXPECT_EQ(validateVolume(dense_with_bricks).error().code, ErrorCode::InconsistentSize);
}

// --- texel values (validateVolume checks every one) --------------------------------------------

namespace {

// A valid 2x4x2 L1 volume (16 probes, 3 planes) of the given storage.
Volume smallVolume(Storage storage) {
    const VolumeDesc d = desc(sh::Order::L1, storage);
    std::vector<sh::ShRgb> probes;
    for (size_t i = 0; i < d.grid.probeCount(); ++i) {
        probes.push_back(distinctSh(i, sh::Order::L1));
    }
    return makeVolume(d, probes).value();
}

// Index of component `component` of probe `probe`'s texel in plane `plane` (volume.hpp's
// plane-major order) in a 16-probe volume.
size_t texelIndex(uint32_t plane, size_t probe, int component) {
    return 4 * (size_t(plane) * 16 + probe) + size_t(component);
}

std::string validateMessage(const Volume& v) {
    const Result<void> r = validateVolume(v);
    return r ? std::string("(valid)") : r.error().message;
}

} // namespace

TEST(VolumeValidate, RejectsNonFiniteFloatTexelsNamingProbePlaneAndValue) {
    const size_t at = texelIndex(1, 5, 2);
    for (const auto& [value, text] :
         {std::pair{NAN, "nan"}, std::pair{INFINITY, "inf"}, std::pair{-INFINITY, "-inf"}}) {
        Volume v = smallVolume(Storage::Float32);
        v.texelsF32[at] = value;
        EXPECT_EQ(validateVolume(v).error().code, ErrorCode::NonFinite);
        EXPECT_EQ(validateMessage(v), std::string("volume 'test': probe 5 (plane 1, component 2) "
                                                  "holds ") +
                                          text + "; every texel must be finite");
    }
}

TEST(VolumeValidate, BoundsFloatTexelMagnitudeAt1e30) {
    Volume v = smallVolume(Storage::Float32);
    const size_t at = texelIndex(2, 15, 3); // the last component of the last plane
    for (const float fine : {kMaxTexelMagnitude, -kMaxTexelMagnitude}) {
        v.texelsF32[at] = fine;
        EXPECT_TRUE(validateVolume(v).ok()) << validateMessage(v);
    }
    v.texelsF32[at] = std::nextafter(kMaxTexelMagnitude, INFINITY);
    EXPECT_EQ(validateVolume(v).error().code, ErrorCode::OutOfRange);
    v.texelsF32[at] = -3e38f;
    EXPECT_EQ(validateVolume(v).error().code, ErrorCode::OutOfRange);
    EXPECT_EQ(validateMessage(v), "volume 'test': probe 15 (plane 2, component 3) holds -3e+38, "
                                  "more than the texel magnitude bound 1e+30");
}

TEST(VolumeValidate, RejectsHalfInfinityAndNan) {
    Volume v = smallVolume(Storage::Float16);
    const size_t at = texelIndex(0, 9, 1);
    v.texelsF16[at] = 0x7bff; // 65504, the largest finite half
    EXPECT_TRUE(validateVolume(v).ok()) << validateMessage(v);
    for (const auto& [bits, text] :
         {std::pair{uint16_t(0x7c00), "inf"}, std::pair{uint16_t(0xfc00), "-inf"},
          std::pair{uint16_t(0x7e00), "nan"}, std::pair{uint16_t(0xfd01), "nan"}}) {
        v.texelsF16[at] = bits;
        EXPECT_EQ(validateVolume(v).error().code, ErrorCode::NonFinite);
        EXPECT_EQ(validateMessage(v), std::string("volume 'test': probe 9 (plane 0, component 1) "
                                                  "holds ") +
                                          text + "; every texel must be finite");
    }
}

TEST(VolumeMake, RejectsACoefficientBeyondTheTexelBound) {
    VolumeDesc d = desc(sh::Order::L1, Storage::Float32);
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    probes[7].rgb[2].y = -2e30f;
    const Result<Volume> made = makeVolume(d, probes);
    ASSERT_FALSE(made.ok());
    EXPECT_EQ(made.error().code, ErrorCode::OutOfRange);
    EXPECT_EQ(made.error().message, "volume 'test': probe 7 has the SH coefficient -2e+30, more "
                                    "than the texel magnitude bound 1e+30");
    probes[7].rgb[2].y = -1e30f;
    EXPECT_TRUE(makeVolume(d, probes).ok());
}

TEST(VolumeBounds, WorldBoundsHoldEveryVolumeAndAreEmptyWithoutOne) {
    std::vector<Volume> volumes;
    for (const grid::Aabb box :
         {grid::Aabb{glm::vec3(0.0f), glm::vec3(1.0f, 2.0f, 3.0f)},
          grid::Aabb{glm::vec3(-4.0f, 1.0f, 1.0f), glm::vec3(-3.0f, 5.0f, 2.0f)}}) {
        VolumeDesc d;
        d.grid = grid::GridLayout(box, glm::uvec3(2), grid::PositionMode::Corner);
        d.shOrder = sh::Order::L1;
        const std::vector<sh::ShRgb> probes(8);
        Result<Volume> v = makeVolume(d, probes);
        ASSERT_TRUE(v.ok()) << v.error().message;
        volumes.push_back(std::move(v.value()));
    }
    const grid::Aabb both = worldBounds(volumes);
    EXPECT_EQ(both.min, glm::vec3(-4.0f, 0.0f, 0.0f));
    EXPECT_EQ(both.max, glm::vec3(1.0f, 5.0f, 3.0f));
    const grid::Aabb none = worldBounds({});
    EXPECT_EQ(none.min, glm::vec3(INFINITY));
    EXPECT_EQ(none.max, glm::vec3(-INFINITY));
}
