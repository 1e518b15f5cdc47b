#include <cmath>

#include <gtest/gtest.h>

#include "probekit/runtime/compare.hpp"

using namespace probekit;

namespace {
// Sums of a few thousand float products in double: relative rounding far below 1e-6.
constexpr double kMetricTolerance = 1e-6;

Volume makeUniform(glm::uvec3 res, std::vector<glm::vec3> radiance_per_probe,
                   std::vector<uint8_t> validity = {}) {
    VolumeDesc d;
    d.name = "v";
    d.grid = grid::GridLayout({glm::vec3(0), glm::vec3(1)}, res, grid::PositionMode::Center);
    d.storage = Storage::Float32;
    std::vector<sh::ShRgb> probes(d.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        // Uniform radiance L: L00 = sqrt(4 pi) L, so E = pi L for every normal.
        probes[i].rgb[0] = radiance_per_probe[i] * std::sqrt(4.0f * sh::kPi);
    }
    return makeVolume(d, probes, validity).value();
}
} // namespace

TEST(CompareVolumes, IdenticalSetsHaveZeroError) {
    const Volume v = makeUniform(glm::uvec3(2, 1, 1), {glm::vec3(1), glm::vec3(2)});
    auto e = runtime::compareVolumes(std::span(&v, 1), std::span(&v, 1));
    ASSERT_TRUE(e.ok());
    EXPECT_EQ(e.value().relRmse, 0.0);
    EXPECT_EQ(e.value().probesCompared, 2u);
}

TEST(CompareVolumes, ScaledSetHasExactRelativeError) {
    const Volume ref = makeUniform(glm::uvec3(2, 1, 1), {glm::vec3(1), glm::vec3(1)});
    // Probe 1 is 30% too bright, probe 0 exact: relRmse = sqrt(0.3^2 / 2).
    const Volume test = makeUniform(glm::uvec3(2, 1, 1), {glm::vec3(1), glm::vec3(1.3f)});
    auto e = runtime::compareVolumes(std::span(&test, 1), std::span(&ref, 1));
    ASSERT_TRUE(e.ok());
    EXPECT_NEAR(e.value().relRmse, std::sqrt(0.09 / 2.0), kMetricTolerance);
    EXPECT_NEAR(e.value().maxProbeErr, 0.3, kMetricTolerance);
    EXPECT_EQ(e.value().worstProbe, 1u);
    EXPECT_NEAR(e.value().maxAbsErr, 0.3 * sh::kPi, 1e-5);
}

TEST(CompareVolumes, InvalidProbesAreSkipped) {
    const Volume ref = makeUniform(glm::uvec3(2, 1, 1), {glm::vec3(1), glm::vec3(1)}, {1, 0});
    const Volume test = makeUniform(glm::uvec3(2, 1, 1), {glm::vec3(1), glm::vec3(9)});
    auto e = runtime::compareVolumes(std::span(&test, 1), std::span(&ref, 1));
    ASSERT_TRUE(e.ok());
    EXPECT_EQ(e.value().probesCompared, 1u);
    EXPECT_EQ(e.value().relRmse, 0.0);
}

TEST(CompareVolumes, MismatchedGridsAreAnError) {
    const Volume a = makeUniform(glm::uvec3(2, 1, 1), {glm::vec3(1), glm::vec3(1)});
    const Volume b = makeUniform(glm::uvec3(1, 1, 2), {glm::vec3(1), glm::vec3(1)});
    auto e = runtime::compareVolumes(std::span(&a, 1), std::span(&b, 1));
    ASSERT_FALSE(e.ok());
    EXPECT_NE(e.error().message.find("resolution differs"), std::string::npos);
    auto count = runtime::compareVolumes(std::span(&a, 1), std::span<const Volume>());
    EXPECT_FALSE(count.ok());
}

TEST(CompareVolumes, BrickedVolumesWithOtherBricksAreAnError) {
    // Same level-0 grid, different bricks: probe i is elsewhere in each, so comparing probe by
    // probe would be meaningless (and index past the smaller volume).
    auto bricked = [](uint32_t level) {
        VolumeDesc d;
        d.name = "b";
        d.grid = grid::GridLayout({glm::vec3(0), glm::vec3(1)}, glm::uvec3(1),
                                  grid::PositionMode::Center);
        d.storage = Storage::Float32;
        d.layout = VolumeLayout::Bricked;
        d.bricks = brick::uniformLayout(glm::uvec3(1), level);
        return makeVolume(d, std::vector<sh::ShRgb>(d.probeCount())).value();
    };
    const Volume coarse = bricked(0);
    const Volume fine = bricked(1);
    auto e = runtime::compareVolumes(std::span(&coarse, 1), std::span(&fine, 1));
    ASSERT_FALSE(e.ok());
    EXPECT_NE(e.error().message.find("layout or bricks differ"), std::string::npos);
    auto same = runtime::compareVolumes(std::span(&fine, 1), std::span(&fine, 1));
    ASSERT_TRUE(same.ok());
    EXPECT_EQ(same.value().probesCompared, 8u * brick::kBrickProbeCount);
}
