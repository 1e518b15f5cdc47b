// Tests of the punctual-light model (formats/include/probekit/formats/light.hpp) against values
// derived by hand from its formulas: the inverse-square law, the receiver's cosine, the range
// window, the spot cone's inner and outer edges and its ramp, and directional lights. The
// geometry uses 3-4-5 triangles and power-of-two intensities so every expected value is a short
// fraction.
#include <cmath>
#include <limits>
#include <optional>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "probekit/formats/light.hpp"

using namespace probekit;

namespace {

// Most expected values here come out exact in float; the rest carry a few roundings of
// quantities near 1 (a square root, a division, a dot product), about 1e-7 relative each, and
// the spot ramp multiplies the rounding of its cosine by its slope (4 here) and by 2 (t^2):
// 1e-5 relative bounds all of them with a wide margin, and is far below any formula error
// (a wrong exponent or cosine changes values by 10% or more).
constexpr float kRelative = 1e-5f;

void expectNear(glm::vec3 got, glm::vec3 want, const char* what) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(got[c], want[c], kRelative * std::abs(want[c]))
            << what << ", channel " << c << ": got (" << got.x << ", " << got.y << ", " << got.z
            << "), want (" << want.x << ", " << want.y << ", " << want.z << ")";
    }
}

const glm::vec3 kIntensity(2.0f, 4.0f, 8.0f); // W/sr

PunctualLight pointAtOrigin() {
    PunctualLight light;
    light.type = LightType::Point;
    light.position = glm::vec3(0.0f);
    light.intensity = kIntensity;
    return light;
}

// A spot at the origin pointing down (-y) with cos(inner) = 0.75 and cos(outer) = 0.5: the ramp
// t = (cos - 0.5) / 0.25 has slope 4.
PunctualLight spotDown() {
    PunctualLight light = pointAtOrigin();
    light.type = LightType::Spot;
    light.direction = glm::vec3(0.0f, -1.0f, 0.0f);
    light.innerConeCos = 0.75f;
    light.outerConeCos = 0.5f;
    return light;
}

const glm::vec3 kUp(0.0f, 1.0f, 0.0f);

TEST(PunctualLight, PointFollowsTheInverseSquareLaw) {
    const PunctualLight light = pointAtOrigin();
    // Straight below, facing the light: E = I / d^2.
    expectNear(irradianceAt(light, glm::vec3(0, -2, 0), kUp), kIntensity / 4.0f, "d = 2");
    expectNear(irradianceAt(light, glm::vec3(0, -4, 0), kUp), kIntensity / 16.0f, "d = 4");
    expectNear(normalIrradianceAt(light, glm::vec3(0, -4, 0)), kIntensity / 16.0f, "facing");
    // The light has no preferred direction: above it, with the normal turned down, the same.
    expectNear(irradianceAt(light, glm::vec3(0, 2, 0), -kUp), kIntensity / 4.0f, "above");
}

TEST(PunctualLight, PointIsWeightedByTheReceiversCosine) {
    const PunctualLight light = pointAtOrigin();
    // At (3, -4, 0): d = 5, the direction to the light (-3, 4, 0) / 5 makes cos = 0.8 with +y.
    expectNear(irradianceAt(light, glm::vec3(3, -4, 0), kUp), kIntensity * (0.8f / 25.0f),
               "off axis");
    expectNear(normalIrradianceAt(light, glm::vec3(3, -4, 0)), kIntensity / 25.0f,
               "off axis, facing");
    // A normal 60 degrees from the light's direction: cos = 0.5.
    const glm::vec3 tilted(std::sqrt(3.0f) / 2.0f, 0.5f, 0.0f);
    expectNear(irradianceAt(light, glm::vec3(0, -2, 0), tilted), kIntensity * (0.5f / 4.0f),
               "tilted");
    // Grazing and facing away: nothing (one-sided: the caller turns two-sided normals).
    EXPECT_EQ(irradianceAt(light, glm::vec3(0, -2, 0), glm::vec3(1, 0, 0)), glm::vec3(0.0f));
    EXPECT_EQ(irradianceAt(light, glm::vec3(0, -2, 0), -kUp), glm::vec3(0.0f));
    // At the light itself there is no direction and no finite irradiance: zero.
    EXPECT_EQ(irradianceAt(light, glm::vec3(0.0f), kUp), glm::vec3(0.0f));
    EXPECT_EQ(normalIrradianceAt(light, glm::vec3(0.0f)), glm::vec3(0.0f));
}

TEST(PunctualLight, RangeWindowsTheFalloff) {
    PunctualLight light = pointAtOrigin();
    light.range = 4.0f;
    // d = 2 of range 4: (d / range)^4 = 1/16, window (1 - 1/16)^2 = 225/256.
    EXPECT_EQ(rangeWindow(4.0f, 4.0f), 225.0f / 256.0f);
    expectNear(irradianceAt(light, glm::vec3(0, -2, 0), kUp), kIntensity * (225.0f / 256.0f / 4.0f),
               "d = range / 2");
    // At and beyond the range: nothing.
    EXPECT_EQ(irradianceAt(light, glm::vec3(0, -4, 0), kUp), glm::vec3(0.0f));
    EXPECT_EQ(irradianceAt(light, glm::vec3(0, -5, 0), kUp), glm::vec3(0.0f));
    // Range 0 is infinite.
    EXPECT_EQ(rangeWindow(0.0f, 1e6f), 1.0f);
}

TEST(PunctualLight, SpotConeIsFullInsideTheInnerConeAndRampsToTheOuter) {
    const PunctualLight light = spotDown();
    // On the axis: the full intensity, E = I / d^2.
    expectNear(irradianceAt(light, glm::vec3(0, -2, 0), kUp), kIntensity / 4.0f, "axis");
    // At (3, -4, 0) the cone angle has cos 0.8 >= cos(inner) = 0.75: still full, t = 1; the
    // floor's cosine is 0.8 as well.
    expectNear(normalIrradianceAt(light, glm::vec3(3, -4, 0)), kIntensity / 25.0f, "inner");
    expectNear(irradianceAt(light, glm::vec3(3, -4, 0), kUp), kIntensity * (0.8f / 25.0f),
               "inner, floor");
    // At (4, -3, 0) the cone cosine is 0.6: t = (0.6 - 0.5) x 4 = 0.4, falloff t^2 = 0.16.
    expectNear(normalIrradianceAt(light, glm::vec3(4, -3, 0)), kIntensity * (0.16f / 25.0f),
               "ramp");
    expectNear(irradianceAt(light, glm::vec3(4, -3, 0), kUp), kIntensity * (0.16f * 0.6f / 25.0f),
               "ramp, floor");
    // At (4, -2, 0) the cone cosine is 2 / sqrt(20) ~ 0.447 < cos(outer) = 0.5: dark; behind
    // the spot too.
    EXPECT_EQ(normalIrradianceAt(light, glm::vec3(4, -2, 0)), glm::vec3(0.0f));
    EXPECT_EQ(irradianceAt(light, glm::vec3(0, 2, 0), -kUp), glm::vec3(0.0f));
}

TEST(PunctualLight, SpotWithEqualConesIsAHardEdge) {
    // inner = outer: the ramp's slope is capped at 1 / 0.001, a hard edge in practice.
    PunctualLight light = spotDown();
    light.innerConeCos = 0.5f;
    expectNear(normalIrradianceAt(light, glm::vec3(3, -4, 0)), kIntensity / 25.0f, "inside");
    EXPECT_EQ(normalIrradianceAt(light, glm::vec3(4, -2, 0)), glm::vec3(0.0f));
}

TEST(PunctualLight, DirectionalIsTheSameEverywhereTimesTheCosine) {
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::vec3(0.0f, -1.0f, 0.0f); // travelling down
    sun.intensity = glm::vec3(1.0f, 2.0f, 3.0f);  // W/m^2
    expectNear(irradianceAt(sun, glm::vec3(0.0f), kUp), sun.intensity, "origin");
    expectNear(irradianceAt(sun, glm::vec3(100, -50, 7), kUp), sun.intensity, "far away");
    expectNear(normalIrradianceAt(sun, glm::vec3(3, 4, 5)), sun.intensity, "facing");
    const glm::vec3 tilted(0.0f, 0.5f, std::sqrt(3.0f) / 2.0f);
    expectNear(irradianceAt(sun, glm::vec3(0.0f), tilted), 0.5f * sun.intensity, "tilted");
    EXPECT_EQ(irradianceAt(sun, glm::vec3(0.0f), -kUp), glm::vec3(0.0f));
}

TEST(PunctualLight, DirectionToLightGivesTheShadowRay) {
    const std::optional<LightDirection> point =
        directionToLight(pointAtOrigin(), glm::vec3(3, -4, 0));
    ASSERT_TRUE(point.has_value());
    expectNear(point->direction, glm::vec3(-0.6f, 0.8f, 0.0f), "point direction");
    EXPECT_NEAR(point->distance, 5.0f, 5.0f * kRelative);
    EXPECT_FALSE(directionToLight(pointAtOrigin(), glm::vec3(0.0f)).has_value());

    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::vec3(0.0f, -1.0f, 0.0f);
    const std::optional<LightDirection> sky = directionToLight(sun, glm::vec3(1, 2, 3));
    ASSERT_TRUE(sky.has_value());
    expectNear(sky->direction, kUp, "directional direction");
    EXPECT_EQ(sky->distance, std::numeric_limits<float>::infinity());
}

} // namespace
