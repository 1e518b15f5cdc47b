// Tests of probe visibility (formats/include/probekit/formats/visibility.hpp): the byte
// encoding, the per-tap weight, the CPU sampler's visibility-weighted interpolation (step V of
// runtime/include/probekit/runtime/sampler.hpp) against hand-computed values, and stitching of
// bricked volumes with visibility.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "../gpu/bricked_test_volume.hpp"
#include "probekit/formats/brick.hpp"
#include "probekit/formats/visibility.hpp"
#include "probekit/runtime/sampler.hpp"

using namespace probekit;

namespace {

// A sum of at most eight weighted values of magnitude ~1, normalised: a few float ulps.
constexpr float kWeightedRelative = 1e-6f;

sh::ShRgb constantSh(float v) {
    sh::ShRgb s;
    s.rgb[0] = glm::vec3(v, 2.0f * v, 3.0f * v);
    return s;
}

// A 2 x 1 x 1 centre-mode volume over x in [0, 2]: probe 0 at x = 0.5, probe 1 at x = 1.5,
// one cell between them (spacing 1 m), holding constant SH a and b.
Volume twoProbes(float a, float b, std::vector<uint8_t> visibility) {
    VolumeDesc desc;
    desc.name = "two";
    desc.grid = grid::GridLayout({glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 1.0f)},
                                 glm::uvec3(2, 1, 1), grid::PositionMode::Center);
    desc.storage = Storage::Float32;
    desc.shOrder = sh::Order::L1;
    const std::vector<sh::ShRgb> probes = {constantSh(a), constantSh(b)};
    Result<Volume> v = makeVolume(desc, probes, {}, visibility);
    EXPECT_TRUE(v.ok()) << v.error().message;
    return std::move(v).value();
}

float dc(const sh::ShRgb& s) {
    return s.rgb[0].x;
}

// A float bricked volume's description over a 2 x 2 x 1 m box.
VolumeDesc brickedDesc(glm::uvec3 top, brick::BrickLayout layout) {
    VolumeDesc desc;
    desc.name = "bricked";
    desc.grid = grid::GridLayout({glm::vec3(-1.0f, 0.5f, -3.0f), glm::vec3(2.0f, 2.0f, 1.0f)}, top,
                                 grid::PositionMode::Center);
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = std::move(layout);
    desc.storage = Storage::Float32;
    return desc;
}

} // namespace

TEST(VisibilityBytes, EncodeDecode) {
    EXPECT_EQ(visibility::encodeDistance(0.0f), 0);
    EXPECT_EQ(visibility::encodeDistance(1.0f), 255);
    EXPECT_EQ(visibility::encodeDistance(7.0f), 255); // beyond one cell: clear
    EXPECT_EQ(visibility::encodeDistance(-1.0f), 0);
    EXPECT_EQ(visibility::encodeDistance(std::nanf("")), 0);
    EXPECT_EQ(visibility::encodeDistance(0.5f), 128); // 127.5 rounds away from zero
    for (int q = 0; q < 256; ++q) {
        EXPECT_EQ(visibility::encodeDistance(visibility::decodeDistance(uint8_t(q))), q);
    }
}

TEST(VisibilityWeight, RampBeyondTheSurfaceOnTheSideOfTheOffset) {
    // +x surface at 0.5 cells, -x clear, +y at 0.2, -y at 0, z clear.
    const uint8_t q[6] = {
        visibility::encodeDistance(0.5f), 255, visibility::encodeDistance(0.2f), 0, 255, 255};
    const float d_x = visibility::decodeDistance(q[0]);
    const float d_y = visibility::decodeDistance(q[2]);
    const float ramp = visibility::kRamp;
    // Up to the surface: visible.
    EXPECT_EQ(visibility::probeVisibility(q, glm::vec3(d_x, 0, 0)), 1.0f);
    EXPECT_EQ(visibility::probeVisibility(q, glm::vec3(0.3f, 0.1f, 0.9f)), 1.0f);
    // Half the ramp beyond: one half; a whole ramp beyond: hidden.
    EXPECT_NEAR(visibility::probeVisibility(q, glm::vec3(d_x + 0.5f * ramp, 0, 0)), 0.5f, 1e-5f);
    EXPECT_EQ(visibility::probeVisibility(q, glm::vec3(d_x + ramp, 0, 0)), 0.0f);
    // The other side of the same axis is clear.
    EXPECT_EQ(visibility::probeVisibility(q, glm::vec3(-1.0f, 0, 0)), 1.0f);
    // -y at distance 0: any step down hides the probe beyond the ramp.
    EXPECT_NEAR(visibility::probeVisibility(q, glm::vec3(0, -0.25f * ramp, 0)), 0.75f, 1e-5f);
    EXPECT_EQ(visibility::probeVisibility(q, glm::vec3(0, -0.5f, 0)), 0.0f);
    // An offset of 0 on an axis never consults that axis (the probe's own plane).
    EXPECT_EQ(visibility::probeVisibility(q, glm::vec3(0, 0, 0)), 1.0f);
    // The smallest over axes.
    EXPECT_NEAR(visibility::probeVisibility(q, glm::vec3(d_x + 0.25f * ramp, d_y + 0.5f * ramp, 0)),
                0.5f, 1e-5f);
}

TEST(SamplerVisibility, HiddenTapKeepsOnlyItsFloorWeight) {
    const float a = 10.0f, b = 1.0f;
    // Probe 0 sees a surface at 0.25 cells towards +x; probe 1 is clear everywhere.
    std::vector<uint8_t> vis(12, 255);
    vis[0] = visibility::encodeDistance(0.25f);
    const float d = visibility::decodeDistance(vis[0]);
    const Volume v = twoProbes(a, b, vis);
    const Volume plain = twoProbes(a, b, {});
    for (const float t : {0.1f, 0.2f, d}) { // before the surface: trilinear
        const glm::vec3 p(0.5f + t, 0.5f, 0.5f);
        EXPECT_NEAR(dc(runtime::sampleVolumeSh(v, p)), (1 - t) * a + t * b, kWeightedRelative * a);
        EXPECT_NEAR(dc(runtime::sampleVolumeSh(v, p)), dc(runtime::sampleVolumeSh(plain, p)),
                    kWeightedRelative * a);
        EXPECT_NEAR(runtime::visibleWeight(v, p), 1.0f, 1e-6f);
    }
    for (const float t : {0.5f, 0.9f}) { // beyond it: probe 0 weighs (1 - t) kFloor
        const glm::vec3 p(0.5f + t, 0.5f, 0.5f);
        const float w0 = (1 - t) * visibility::kFloor, w1 = t * (1 + visibility::kFloor);
        EXPECT_NEAR(dc(runtime::sampleVolumeSh(v, p)), (w0 * a + w1 * b) / (w0 + w1),
                    kWeightedRelative * a);
        EXPECT_NEAR(runtime::visibleWeight(v, p), t, 1e-6f);
    }
    // In the ramp: vis 0.5 at half a ramp beyond.
    const float t = d + 0.5f * visibility::kRamp;
    const float w0 = (1 - t) * (0.5f + visibility::kFloor), w1 = t * (1 + visibility::kFloor);
    EXPECT_NEAR(dc(runtime::sampleVolumeSh(v, glm::vec3(0.5f + t, 0.5f, 0.5f))),
                (w0 * a + w1 * b) / (w0 + w1), 1e-4f * a);
}

TEST(SamplerVisibility, EveryTapHiddenFallsBackToTrilinear) {
    // Both probes hidden towards each other: the floor weights are trilinear weights.
    std::vector<uint8_t> vis(12, 255);
    vis[0] = 0; // probe 0: +x at 0
    vis[1] = 0; // probe 1: -x at 0 (probe 1's -x byte is vis[6 + 1])
    vis[7] = 0;
    const Volume v = twoProbes(4.0f, 2.0f, vis);
    const glm::vec3 p(0.5f + 0.3f, 0.5f, 0.5f);
    EXPECT_NEAR(dc(runtime::sampleVolumeSh(v, p)), 0.7f * 4.0f + 0.3f * 2.0f,
                kWeightedRelative * 4.0f);
    EXPECT_NEAR(runtime::visibleWeight(v, p), 0.0f, 1e-6f);
}

TEST(SamplerVisibility, ClearBytesAreTrilinearOnDenseAndBricked) {
    // Every byte 255 (no surface within a cell): the same as no visibility data, at points
    // spread through the volume (and outside it, where clamping applies).
    const glm::uvec3 top(2, 1, 2);
    const VolumeDesc desc = brickedDesc(top, bricktest::nestedLayout(top));
    size_t counter = 0;
    const Volume plain = bricktest::makeBrickedVolume(
        desc,
        [&counter](glm::vec3) {
            ++counter;
            return constantSh(float(counter % 17) + 0.5f);
        },
        true);
    Volume clear = plain;
    clear.visibility.assign(plain.probeCount() * visibility::kBytesPerProbe, 255);
    for (int k = 0; k < 300; ++k) {
        const glm::vec3 t(std::fmod(0.1f + 0.618034f * float(k), 1.2f) - 0.1f,
                          std::fmod(0.3f + 0.414214f * float(k), 1.0f),
                          std::fmod(0.7f + 0.732051f * float(k), 1.0f));
        const grid::Aabb& box = desc.grid.bounds();
        const glm::vec3 p = box.min + t * box.size();
        EXPECT_NEAR(dc(runtime::sampleVolumeSh(clear, p)), dc(runtime::sampleVolumeSh(plain, p)),
                    kWeightedRelative * 17.0f)
            << k;
    }
}

TEST(SamplerVisibility, BrickedEqualsBrickInterpolateWithVisibility) {
    // The sampler's bricked path and brick::interpolate (which stitching uses) are two
    // implementations of the same weights: they must agree, with random bytes hiding probes.
    const glm::uvec3 top(2, 1, 2);
    const VolumeDesc desc = brickedDesc(top, bricktest::mixedLayout(top));
    size_t counter = 0;
    Volume v = bricktest::makeBrickedVolume(
        desc,
        [&counter](glm::vec3) {
            ++counter;
            return constantSh(float((counter * 7) % 23) + 1.0f);
        },
        false);
    uint32_t state = 12345u;
    v.visibility.resize(v.probeCount() * visibility::kBytesPerProbe);
    for (uint8_t& q : v.visibility) {
        state = state * 1664525u + 1013904223u;
        q = uint8_t(state >> 24);
    }
    std::vector<sh::ShRgb> probes(v.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        probes[i] = v.probe(i);
    }
    const glm::uvec3 cells = brick::finestCells(top, desc.bricks.maxLevel);
    int differs_from_trilinear = 0;
    for (int k = 0; k < 400; ++k) {
        const glm::vec3 t(std::fmod(0.1f + 0.618034f * float(k), 1.0f),
                          std::fmod(0.3f + 0.414214f * float(k), 1.0f),
                          std::fmod(0.7f + 0.732051f * float(k), 1.0f));
        const grid::Aabb& box = desc.grid.bounds();
        const glm::vec3 p = box.min + t * box.size();
        const brick::BrickSample at =
            brick::locate(top, desc.bricks, v.indirection, t * glm::vec3(cells));
        const auto brick_probes = std::span(probes).subspan(size_t(at.brick) * 64, 64);
        const auto brick_vis = std::span<const uint8_t>(v.visibility)
                                   .subspan(size_t(at.brick) * 64 * visibility::kBytesPerProbe,
                                            64 * visibility::kBytesPerProbe);
        const float expected = dc(brick::interpolate(brick_probes, at.local, brick_vis));
        EXPECT_NEAR(dc(runtime::sampleVolumeSh(v, p)), expected, 2e-5f * 23.0f) << k;
        differs_from_trilinear +=
            std::abs(expected - dc(brick::interpolate(brick_probes, at.local))) > 0.1f;
    }
    EXPECT_GT(differs_from_trilinear, 100) << "random bytes must hide probes often";
}

TEST(StitchVisibility, StitchedProbeTakesWhatTheCoarserSideShows) {
    // A nested layout, random field and random visibility: after stitching with visibility,
    // every replaced border probe equals the visibility-weighted value of the brick it was
    // stitched to (a coarser one, or an earlier one of its level) at its position.
    const glm::uvec3 top(2, 1, 2);
    VolumeDesc desc;
    desc.name = "nested";
    desc.grid = grid::GridLayout({glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 2.0f)}, top,
                                 grid::PositionMode::Center);
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = bricktest::nestedLayout(top);
    desc.storage = Storage::Float32;
    Result<std::vector<uint32_t>> indirection =
        brick::buildIndirection(top, desc.bricks, desc.name);
    ASSERT_TRUE(indirection.ok());
    const size_t count = desc.bricks.bricks.size() * 64;
    std::vector<sh::ShRgb> probes(count);
    std::vector<uint8_t> vis(count * visibility::kBytesPerProbe);
    uint32_t state = 777u;
    auto next = [&state] {
        state = state * 1664525u + 1013904223u;
        return state >> 8;
    };
    for (sh::ShRgb& p : probes) {
        p = constantSh(float(next() % 1000) / 100.0f);
    }
    for (uint8_t& q : vis) {
        q = uint8_t(next() & 0xff);
    }
    const std::vector<sh::ShRgb> raw = probes;
    brick::stitchBorders(top, desc.bricks, indirection.value(), probes, vis);
    int replaced = 0;
    for (size_t i = 0; i < count; ++i) {
        replaced += dc(probes[i]) != dc(raw[i]);
    }
    EXPECT_GT(replaced, 0);
    // Each replaced probe: some coarser brick's visibility-weighted interpolation at that
    // lattice point must give exactly its value.
    const uint32_t max_level = desc.bricks.maxLevel;
    int checked = 0;
    for (size_t bi = 0; bi < desc.bricks.bricks.size(); ++bi) {
        const brick::Brick& b = desc.bricks.bricks[bi];
        for (uint32_t k = 0; k < 64; ++k) {
            const size_t i = bi * 64 + k;
            if (dc(probes[i]) == dc(raw[i])) {
                continue;
            }
            const glm::uvec3 lattice =
                brick::latticeCoord(b, glm::uvec3(k % 4, (k / 4) % 4, k / 16), max_level);
            bool found = false;
            for (size_t ci = 0; ci < desc.bricks.bricks.size() && !found; ++ci) {
                const brick::Brick& c = desc.bricks.bricks[ci];
                if (c.level > b.level || ci == bi) {
                    continue; // the source is coarser, or an earlier brick of the same level
                }
                const uint32_t step = 1u << (max_level - c.level);
                const glm::vec3 local =
                    (glm::vec3(lattice) - glm::vec3(c.coord * (3u * step))) / float(step);
                if (glm::any(glm::lessThan(local, glm::vec3(0.0f))) ||
                    glm::any(glm::greaterThan(local, glm::vec3(3.0f)))) {
                    continue;
                }
                const float v = dc(brick::interpolate(
                    std::span<const sh::ShRgb>(probes).subspan(ci * 64, 64), local,
                    std::span<const uint8_t>(vis).subspan(ci * 64 * 6, 64 * 6)));
                found = std::abs(v - dc(probes[i])) <= kWeightedRelative * 10.0f;
            }
            EXPECT_TRUE(found) << "brick " << bi << " probe " << k;
            ++checked;
        }
    }
    EXPECT_EQ(checked, replaced);
}
