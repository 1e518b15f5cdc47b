// The display mapping of probekit render's 8-bit images (runtime/include/probekit/runtime/
// tonemap.hpp): the ACES filmic fit against values worked out by hand from its formula, its
// monotonicity, the sRGB encoding, and the automatic exposure rule (log-average luminance to
// middle grey), which must give a scene lit a thousand times brighter the same picture.
#include <cmath>
#include <vector>

#include <glm/vec4.hpp>
#include <gtest/gtest.h>

#include "probekit/runtime/tonemap.hpp"

using namespace probekit;

namespace {

// The curve is a ratio of two quadratics evaluated in float: a few roundings of quantities
// near 1, about 1e-7 relative each; 1e-6 leaves room and is far below any error in a
// coefficient (the smallest, 0.03, moves f(0.1) by 2%).
constexpr float kCurveRelative = 1e-6f;

} // namespace

TEST(ToneMap, AcesFilmicMatchesItsFormula) {
    EXPECT_EQ(runtime::acesFilmic(0.0f), 0.0f);
    // f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)
    // f(1) = 2.54 / 3.16; f(0.18) = 0.0867564 / 0.3248132 (middle grey).
    EXPECT_NEAR(runtime::acesFilmic(1.0f), 2.54f / 3.16f, kCurveRelative);
    EXPECT_NEAR(runtime::acesFilmic(0.18f),
                (0.18f * (2.51f * 0.18f + 0.03f)) / (0.18f * (2.43f * 0.18f + 0.59f) + 0.14f),
                kCurveRelative);
    // It reaches 1 at x = (0.56 + sqrt(0.56^2 + 4 x 0.08 x 0.14)) / 0.16 = 7.2419 and clamps.
    EXPECT_LT(runtime::acesFilmic(7.2f), 1.0f);
    EXPECT_EQ(runtime::acesFilmic(7.3f), 1.0f);
    EXPECT_EQ(runtime::acesFilmic(1e30f), 1.0f);
    EXPECT_EQ(runtime::acesFilmic(-1.0f), 0.0f) << "negative radiance is black";
}

TEST(ToneMap, IsMonotone) {
    // Strictly increasing up to the clamp at 7.24, flat after it, over 1e-4 .. 100 in ratio
    // steps of 1.001 (the 8-bit output must never get darker as radiance grows).
    float previous = runtime::acesFilmic(0.0f);
    for (float x = 1e-4f; x < 100.0f; x *= 1.001f) {
        const float y = runtime::acesFilmic(x);
        if (x < 7.2f) {
            ASSERT_GT(y, previous) << "at x = " << x;
        } else {
            ASSERT_GE(y, previous) << "at x = " << x;
        }
        previous = y;
    }
}

TEST(ToneMap, SrgbEncodingFollowsTheStandard) {
    EXPECT_EQ(runtime::srgbEncode(0.0f), 0.0f);
    EXPECT_NEAR(runtime::srgbEncode(1.0f), 1.0f, 1e-6f);
    EXPECT_NEAR(runtime::srgbEncode(0.002f), 12.92f * 0.002f, 1e-7f); // the linear toe
    EXPECT_NEAR(runtime::srgbEncode(0.5f), 1.055f * std::pow(0.5f, 1.0f / 2.4f) - 0.055f, 1e-6f);
    EXPECT_NEAR(runtime::srgbEncode(2.0f), 1.0f, 1e-6f) << "clamped";
}

TEST(ToneMap, AutoExposureBringsTheLogAverageToMiddleGrey) {
    // Two pixels of luminance 2 and 8 (grey, so luminance = the value): log-average 4, and
    // black pixels (no light, or background) do not count.
    const std::vector<glm::vec4> frame = {glm::vec4(2.0f, 2.0f, 2.0f, 1.0f),
                                          glm::vec4(8.0f, 8.0f, 8.0f, 1.0f), glm::vec4(0.0f)};
    EXPECT_NEAR(runtime::autoExposureEv(frame), std::log2(runtime::kAutoExposureKey / 4.0f), 1e-5f);
    EXPECT_EQ(runtime::autoExposureEv(std::vector<glm::vec4>(3, glm::vec4(0.0f))), 0.0f)
        << "an all-black frame keeps EV 0";
    EXPECT_NEAR(runtime::luminance(glm::vec3(1.0f, 0.0f, 0.0f)), 0.2126f, 1e-7f);
    EXPECT_NEAR(runtime::luminance(glm::vec3(1.0f)), 1.0f, 1e-6f);
}

TEST(ToneMap, AutoExposureGivesA2049LuxSunAndA1LuxRoomTheSameImage) {
    // The same varied picture (a ramp over four decades, coloured) at two absolute levels:
    // a sunlit scene (2,049 W/m^2 sun, the exporters' common value: radiance ~ 2049 x 0.8 / pi)
    // and a dim interior at 1 W/m^2. Auto exposure scales both to the same log-average, so the
    // tone-mapped pixels agree; the only difference is float rounding of the scale (1e-5).
    std::vector<glm::vec4> dim, sunlit;
    for (int i = 0; i < 1000; ++i) {
        const float l = 0.8f / 3.14159265f * std::pow(10.0f, -2.0f + 4.0f * float(i) / 999.0f);
        const glm::vec4 c(l, 0.8f * l, 0.5f * l, 1.0f);
        dim.push_back(c);
        sunlit.push_back(glm::vec4(glm::vec3(c) * 2049.0f, 1.0f));
    }
    const float ev_dim = runtime::autoExposureEv(dim);
    const float ev_sun = runtime::autoExposureEv(sunlit);
    EXPECT_NEAR(ev_dim - ev_sun, std::log2(2049.0f), 1e-4f);
    double mean_dim = 0.0, mean_sun = 0.0;
    for (size_t i = 0; i < dim.size(); ++i) {
        const glm::vec3 a = runtime::toneMap(glm::vec3(dim[i]), ev_dim);
        const glm::vec3 b = runtime::toneMap(glm::vec3(sunlit[i]), ev_sun);
        ASSERT_NEAR(a.x, b.x, 1e-4f) << i;
        mean_dim += a.x + a.y + a.z;
        mean_sun += b.x + b.y + b.z;
    }
    EXPECT_NEAR(mean_dim / mean_sun, 1.0, 1e-4);
    // Without auto exposure (EV 0) the sunlit one is blown out: most pixels clip to 1.
    size_t clipped = 0;
    for (const glm::vec4& c : sunlit) {
        clipped += runtime::toneMap(glm::vec3(c), 0.0f).x == 1.0f ? 1 : 0;
    }
    EXPECT_GT(clipped, sunlit.size() / 2);
}
