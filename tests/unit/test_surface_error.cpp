// runtime::compareSurface and surfaceEdges (runtime/include/probekit/runtime/surface_error.hpp)
// on hand-made images whose figures are known exactly.
#include <cmath>

#include <gtest/gtest.h>

#include "probekit/runtime/surface_error.hpp"

namespace probekit::runtime {
namespace {

// A w x h view of one plane z = 0 facing +z, E = (1, 1, 1) everywhere, standard error `se`.
SurfaceReferenceImage plane(uint32_t w, uint32_t h, float se = 0.0f) {
    SurfaceReferenceImage r;
    r.width = w;
    r.height = h;
    const size_t n = size_t(w) * h;
    r.hit.assign(n, 1);
    r.normal.assign(n, glm::vec3(0.0f, 0.0f, 1.0f));
    r.irradiance.assign(n, glm::vec3(1.0f));
    r.standardError.assign(n, glm::vec3(se));
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; ++x) {
            r.position.push_back(glm::vec3(0.01f * float(x), -0.01f * float(y), 0.0f));
        }
    }
    return r;
}

TEST(SurfaceError, FiguresOfAKnownImage) {
    const SurfaceReferenceImage r = plane(10, 10, 0.02f);
    std::vector<glm::vec3> test(100, glm::vec3(1.0f));
    // 10 pixels at 0.4x (under half), 5 at 3x (over 2x), 2 negative, 20 at 1.1x; the rest exact.
    for (size_t i = 0; i < 10; ++i) {
        test[i] = glm::vec3(0.4f);
    }
    for (size_t i = 10; i < 15; ++i) {
        test[i] = glm::vec3(3.0f);
    }
    test[15] = glm::vec3(-0.5f, 1.0f, 1.0f);
    test[16] = glm::vec3(1.0f, 1.0f, -0.1f);
    for (size_t i = 20; i < 40; ++i) {
        test[i] = glm::vec3(1.1f);
    }
    Result<SurfaceError> e = compareSurface(test, r);
    ASSERT_TRUE(e.ok()) << e.error().message;
    const SurfaceError& s = e.value();
    EXPECT_EQ(s.surfacePixels, 100u);
    EXPECT_EQ(s.edgePixels, 0u); // one plane: the image border is no edge
    EXPECT_EQ(s.compared, 100u);
    EXPECT_DOUBLE_EQ(s.shareUnderHalf, 0.10);
    EXPECT_DOUBLE_EQ(s.shareOverTwo, 0.05);
    EXPECT_DOUBLE_EQ(s.shareNegative, 0.02);
    // 63 of the 100 pixels are exact, so the median of |ratio - 1| is 0.
    EXPECT_NEAR(s.medianAbsError, 0.0, 1e-12);
    // Mean ratio: (10 x 0.4 + 5 x 3 + 20 x 1.1 + 63 x 1 + the two negatives' Y ratios) / 100.
    const double y15 = 0.2126 * -0.5 + 0.7152 + 0.0722;
    const double y16 = 0.2126 + 0.7152 + 0.0722 * -0.1;
    EXPECT_NEAR(s.meanRatio, (4.0 + 15.0 + 22.0 + 63.0 + y15 + y16) / 100.0, 1e-6);
    EXPECT_NEAR(s.referenceNoise, 0.02, 1e-6);
    EXPECT_NEAR(s.noiseFloor, 0.6745 * 0.02, 1e-6);
}

TEST(SurfaceError, MedianOfAnEvenSetIsTheMeanOfTheMiddleTwo) {
    const SurfaceReferenceImage r = plane(4, 1);
    const std::vector<glm::vec3> test = {glm::vec3(1.1f), glm::vec3(1.2f), glm::vec3(0.7f),
                                         glm::vec3(1.0f)};
    Result<SurfaceError> e = compareSurface(test, r);
    ASSERT_TRUE(e.ok());
    EXPECT_NEAR(e.value().medianAbsError, 0.15, 1e-6); // {0, 0.1, 0.2, 0.3}
}

TEST(SurfaceError, EdgesAndBackgroundAndDarkPixelsAreLeftOut) {
    // A 12 x 6 view: the left half a plane at z = 0, the right half a plane 1 m behind it (a
    // step in depth), column 0 background, and one dark pixel.
    SurfaceReferenceImage r = plane(12, 6);
    for (uint32_t y = 0; y < 6; ++y) {
        for (uint32_t x = 6; x < 12; ++x) {
            r.position[x + 12 * y].z = -1.0f;
        }
        r.hit[12 * y] = 0;
    }
    r.irradiance[3 + 12 * 3] = glm::vec3(1e-6f);
    const std::vector<uint8_t> edge = surfaceEdges(r);
    for (uint32_t y = 0; y < 6; ++y) {
        for (uint32_t x = 0; x < 12; ++x) {
            const bool expected = x != 0 && (x <= 2 || (x >= 4 && x <= 7));
            EXPECT_EQ(edge[x + 12 * y] != 0, expected) << x << "," << y;
        }
    }
    std::vector<glm::vec3> test(72, glm::vec3(1.0f));
    Result<SurfaceError> e = compareSurface(test, r);
    ASSERT_TRUE(e.ok());
    EXPECT_EQ(e.value().surfacePixels, 66u);
    EXPECT_EQ(e.value().edgePixels, 36u); // columns 1, 2, 4..7
    EXPECT_EQ(e.value().darkPixels, 1u);
    EXPECT_EQ(e.value().compared, 29u); // columns 3, 8..11, minus the dark one
}

TEST(SurfaceError, MismatchedSizesAreRefused) {
    const SurfaceReferenceImage r = plane(4, 4);
    Result<SurfaceError> e = compareSurface(std::vector<glm::vec3>(15), r);
    ASSERT_FALSE(e.ok());
    EXPECT_NE(e.error().message.find("15 pixels"), std::string::npos);
}

} // namespace
} // namespace probekit::runtime
