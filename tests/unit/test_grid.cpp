#include <gtest/gtest.h>

#include <glm/gtc/quaternion.hpp>

#include "probekit/formats/grid.hpp"

using namespace probekit;
using namespace probekit::grid;

namespace {
// Positions are sums and products of a few floats of magnitude <= 10: a few ulps at 10.
constexpr float kPositionTolerance = 1e-5f;
// Rotations go through quaternion products: a handful of float roundings.
constexpr float kRotationTolerance = 1e-5f;

void expectNear(glm::vec3 a, glm::vec3 b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}
} // namespace

TEST(GridResolution, AcceptsPowersOfTwoOneTo256) {
    for (uint32_t r = 1; r <= 256; r *= 2) {
        EXPECT_TRUE(validateResolution(glm::uvec3(r), PositionMode::Center).ok()) << r;
    }
}

TEST(GridResolution, RejectsNonPowerOfTwoNamingAxisAndValue) {
    auto r = validateResolution(glm::uvec3(4, 12, 4), PositionMode::Center);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code, ErrorCode::BadResolution);
    EXPECT_NE(r.error().message.find("resolution.y = 12"), std::string::npos) << r.error().message;
}

TEST(GridResolution, RejectsZeroAndAbove256) {
    auto zero = validateResolution(glm::uvec3(0, 4, 4), PositionMode::Center);
    ASSERT_FALSE(zero.ok());
    EXPECT_NE(zero.error().message.find("resolution.x = 0"), std::string::npos);
    auto big = validateResolution(glm::uvec3(4, 4, 512), PositionMode::Center);
    ASSERT_FALSE(big.ok());
    EXPECT_NE(big.error().message.find("resolution.z = 512"), std::string::npos);
}

TEST(GridResolution, CornerNeedsTwoProbesPerAxis) {
    auto r = validateResolution(glm::uvec3(2, 1, 2), PositionMode::Corner);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("resolution.y = 1"), std::string::npos);
    EXPECT_TRUE(validateResolution(glm::uvec3(2, 2, 2), PositionMode::Corner).ok());
}

TEST(GridBounds, RejectsInvertedEmptyAndNonFinite) {
    EXPECT_EQ(validateBounds({glm::vec3(0), glm::vec3(1, 0, 1)}).error().code,
              ErrorCode::OutOfRange);
    EXPECT_EQ(validateBounds({glm::vec3(0), glm::vec3(1, 1, -1)}).error().code,
              ErrorCode::OutOfRange);
    EXPECT_EQ(validateBounds({glm::vec3(0, NAN, 0), glm::vec3(1)}).error().code,
              ErrorCode::NonFinite);
    EXPECT_EQ(validateBounds({glm::vec3(0), glm::vec3(INFINITY, 1, 1)}).error().code,
              ErrorCode::NonFinite);
    // Finite ends whose difference is not (issue 31): the extent 6e38 overflows float.
    const Result<void> wide = validateBounds({glm::vec3(0, 0, -3e38f), glm::vec3(1, 1, 3e38f)});
    ASSERT_FALSE(wide.ok());
    EXPECT_EQ(wide.error().code, ErrorCode::NonFinite);
    EXPECT_TRUE(wide.error().message.starts_with("bounds.z extent max - min overflows float"))
        << wide.error().message;
    EXPECT_TRUE(validateBounds({glm::vec3(0, 0, -1e38f), glm::vec3(1, 1, 1e38f)}).ok());
}

TEST(GridLayout, CenterModePlacesProbesAtCellCentres) {
    GridLayout g({glm::vec3(-2, 0, 1), glm::vec3(2, 1, 9)}, glm::uvec3(4, 1, 8),
                 PositionMode::Center);
    // probe i at min + (i + 0.5) * size / res
    expectNear(g.probeLocal({0, 0, 0}), glm::vec3(-1.5f, 0.5f, 1.5f), kPositionTolerance);
    expectNear(g.probeLocal({3, 0, 7}), glm::vec3(1.5f, 0.5f, 8.5f), kPositionTolerance);
    expectNear(g.spacing(), glm::vec3(1.0f, 1.0f, 1.0f), kPositionTolerance);
}

TEST(GridLayout, SingleCentreProbeSitsAtBoxCentre) {
    GridLayout g({glm::vec3(-1, 2, 3), glm::vec3(5, 4, 7)}, glm::uvec3(1), PositionMode::Center);
    expectNear(g.probeLocal({0, 0, 0}), glm::vec3(2, 3, 5), kPositionTolerance);
}

TEST(GridLayout, CornerModePlacesProbesOnFaces) {
    GridLayout g({glm::vec3(0), glm::vec3(4, 2, 1)}, glm::uvec3(8, 2, 4), PositionMode::Corner);
    // probe i at min + i * size / (res - 1)
    expectNear(g.probeLocal({0, 0, 0}), glm::vec3(0), kPositionTolerance);
    expectNear(g.probeLocal({7, 1, 3}), glm::vec3(4, 2, 1), kPositionTolerance);
    expectNear(g.probeLocal({1, 0, 1}), glm::vec3(4.0f / 7.0f, 0, 1.0f / 3.0f), kPositionTolerance);
}

TEST(GridLayout, LinearIndexIsXFastestAndInvertible) {
    GridLayout g({glm::vec3(0), glm::vec3(1)}, glm::uvec3(4, 2, 8), PositionMode::Center);
    EXPECT_EQ(g.probeCount(), 64u);
    EXPECT_EQ(g.linearIndex({1, 0, 0}), 1u);
    EXPECT_EQ(g.linearIndex({0, 1, 0}), 4u);
    EXPECT_EQ(g.linearIndex({0, 0, 1}), 8u);
    for (size_t i = 0; i < g.probeCount(); ++i) {
        EXPECT_EQ(g.linearIndex(g.probeCoords(i)), i);
    }
}

TEST(GridLayout, WorldGridRoundTripWithRotatedFrame) {
    RigidFrame frame;
    frame.rotation = glm::angleAxis(glm::radians(30.0f), glm::normalize(glm::vec3(1, 2, 3)));
    frame.translation = glm::vec3(5, -1, 2);
    for (PositionMode mode : {PositionMode::Center, PositionMode::Corner}) {
        GridLayout g({glm::vec3(-1), glm::vec3(3, 1, 2)}, glm::uvec3(8, 4, 2), mode, frame);
        for (size_t i = 0; i < g.probeCount(); ++i) {
            const glm::uvec3 c = g.probeCoords(i);
            expectNear(g.worldToGrid(g.probeWorld(c)), glm::vec3(c), 10 * kRotationTolerance);
        }
        const glm::vec3 p(0.3f, 0.7f, -0.2f);
        expectNear(g.gridToWorld(g.worldToGrid(p)), p, 10 * kRotationTolerance);
        // The frame is rigid: distances between probes are the local spacing.
        const float d = glm::length(g.probeWorld({1, 0, 0}) - g.probeWorld({0, 0, 0}));
        EXPECT_NEAR(d, g.spacing().x, kRotationTolerance);
    }
}

TEST(GridLayout, WorldBoundsEncloseTheRotatedBox) {
    RigidFrame frame;
    frame.rotation = glm::angleAxis(glm::radians(90.0f), glm::vec3(0, 1, 0));
    frame.translation = glm::vec3(10, 0, 0);
    GridLayout g({glm::vec3(-1, 0, -0.5f), glm::vec3(1, 1, 0.5f)}, glm::uvec3(2),
                 PositionMode::Center, frame);
    // +90 degrees about +Y maps local x to world -z and local z to world x.
    const Aabb b = g.worldBounds();
    expectNear(b.min, glm::vec3(9.5f, 0.0f, -1.0f), kRotationTolerance);
    expectNear(b.max, glm::vec3(10.5f, 1.0f, 1.0f), kRotationTolerance);
}

TEST(GridLayout, MakeRejectsBadFrame) {
    RigidFrame frame;
    frame.rotation = glm::quat(2.0f, 0.0f, 0.0f, 0.0f);
    auto g =
        GridLayout::make({glm::vec3(0), glm::vec3(1)}, glm::uvec3(2), PositionMode::Center, frame);
    ASSERT_FALSE(g.ok());
    EXPECT_EQ(g.error().code, ErrorCode::OutOfRange);
    frame.rotation = glm::quat(1, 0, 0, 0);
    frame.translation.y = NAN;
    EXPECT_EQ(
        GridLayout::make({glm::vec3(0), glm::vec3(1)}, glm::uvec3(2), PositionMode::Center, frame)
            .error()
            .code,
        ErrorCode::NonFinite);
}

// The constructor's preconditions (grid.hpp) are checked in every build type, Release included
// (ARCHITECTURE.md, "Preconditions"): a violation prints the failed validation with its message
// and aborts. Untrusted values go through GridLayout::make, which returns the error instead.
TEST(GridLayoutDeathTest, ConstructorChecksItsPreconditions) {
    const grid::Aabb box{glm::vec3(0.0f), glm::vec3(1.0f)};
    EXPECT_DEATH(grid::GridLayout(box, glm::uvec3(3, 4, 4), grid::PositionMode::Center),
                 "precondition failed in GridLayout: validateResolution.*resolution.x = 3 is not a "
                 "power of two");
    EXPECT_DEATH(
        grid::GridLayout({glm::vec3(1.0f), glm::vec3(0.0f)}, glm::uvec3(4),
                         grid::PositionMode::Center),
        "precondition failed in GridLayout: validateBounds.*bounds.x is empty or inverted");
}
