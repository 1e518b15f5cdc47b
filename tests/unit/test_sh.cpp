// Tests for probekit::sh: the basis against its definition, projection and irradiance against
// analytic answers, and the deringing window against its contract in sh.hpp.
//
// Quadratures here are exact, not Monte Carlo: Gauss-Legendre in cos(theta) times uniform phi,
// split at the equator of the axis where an integrand has a kink (max(0, n.d)), integrates every
// polynomial of the degrees involved exactly. What is left is float rounding and the six-decimal
// basis constants, which is what the tolerances below are sized for.
#include "probekit/formats/sh.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

namespace {

using probekit::sh::Coeffs;
using probekit::sh::Order;
using probekit::sh::ShRgb;
namespace sh = probekit::sh;

constexpr double kPi = 3.14159265358979323846;

// The constants are published to 6 decimals: each is off from its closed form by < 5e-7
// absolute, so a product of two basis functions integrated over the sphere (|Y| <= 1.1, area
// 4 pi) is off by a few 1e-6; float rounding of ~500 accumulated terms adds ~1e-6.
constexpr double kQuadratureTolerance = 1e-5;
// One basis function at one direction: constant rounding (< 5e-7 times |polynomial| <= 2 for
// Y20) plus float evaluation (a few ulp of values <= 1.1).
constexpr double kPointwiseBasisTolerance = 2e-6;
// A closed form (e.g. 1 / (2 sqrt(pi))) against its 6-decimal constant: half a unit in the
// last published place.
constexpr double kPublishedDigitsTolerance = 5e-7;
// Irradiance of a unit-irradiance delta: nine float terms of size <= 1 on top of the constant
// error above; 1e-5 leaves a decade of room and still catches any wrong A_l or sign.
constexpr double kIrradianceTolerance = 1e-5;

// ---- Quadrature -------------------------------------------------------------------------------

struct QuadraturePoint {
    glm::vec3 dir;
    double weight; // steradians
};

// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n; exact for degree <= 2n - 1).
void gaussLegendre(int n, std::vector<double>& nodes, std::vector<double>& weights) {
    nodes.resize(n);
    weights.resize(n);
    for (int k = 0; k < n; ++k) {
        double x = std::cos(kPi * (k + 0.75) / (n + 0.5));
        double derivative = 1.0;
        for (int iteration = 0; iteration < 100; ++iteration) {
            double p0 = 1.0;
            double p1 = x;
            for (int l = 2; l <= n; ++l) {
                const double p2 = ((2.0 * l - 1.0) * x * p1 - (l - 1.0) * p0) / l;
                p0 = p1;
                p1 = p2;
            }
            derivative = n * (x * p1 - p0) / (x * x - 1.0);
            const double step = p1 / derivative;
            x -= step;
            if (std::abs(step) < 1e-15) {
                break;
            }
        }
        nodes[k] = x;
        weights[k] = 2.0 / ((1.0 - x * x) * derivative * derivative);
    }
}

// Sphere quadrature in a frame whose pole is `axis`, with each hemisphere integrated separately
// so that integrands with a kink at axis.w = 0 (the clamped cosine) are still polynomial on each
// piece. 16 nodes per hemisphere and 32 azimuths: exact far beyond the degree-5 integrands used.
std::vector<QuadraturePoint> sphereQuadrature(glm::dvec3 axis) {
    constexpr int kNodes = 16;
    constexpr int kAzimuths = 32;
    std::vector<double> nodes;
    std::vector<double> weights;
    gaussLegendre(kNodes, nodes, weights);

    axis = glm::normalize(axis);
    const glm::dvec3 helper = std::abs(axis.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 tangent = glm::normalize(glm::cross(helper, axis));
    const glm::dvec3 bitangent = glm::cross(axis, tangent);

    std::vector<QuadraturePoint> points;
    for (const double hemisphere : {-1.0, 1.0}) {
        for (int k = 0; k < kNodes; ++k) {
            // Map [-1, 1] onto [0, 1] or [-1, 0]; the Jacobian halves the weight.
            const double cos_theta = hemisphere * 0.5 * (nodes[k] + 1.0);
            const double sin_theta = std::sqrt(1.0 - cos_theta * cos_theta);
            for (int j = 0; j < kAzimuths; ++j) {
                const double phi = 2.0 * kPi * (j + 0.5) / kAzimuths;
                const glm::dvec3 dir = sin_theta * std::cos(phi) * tangent +
                                       sin_theta * std::sin(phi) * bitangent + cos_theta * axis;
                points.push_back(
                    {glm::vec3(glm::normalize(dir)), 0.5 * weights[k] * 2.0 * kPi / kAzimuths});
            }
        }
    }
    return points;
}

// ---- Reference real SH from the associated Legendre recurrence --------------------------------

// P_l^m(x), m >= 0, without the Condon-Shortley phase (Numerical Recipes' recurrence with the
// (-1)^m dropped), so every P_m^m is non-negative.
double legendre(int l, int m, double x) {
    double pmm = 1.0;
    const double sin_theta = std::sqrt((1.0 - x) * (1.0 + x));
    for (int i = 1; i <= m; ++i) {
        pmm *= (2.0 * i - 1.0) * sin_theta;
    }
    if (l == m) {
        return pmm;
    }
    double pmm1 = x * (2.0 * m + 1.0) * pmm;
    for (int ll = m + 2; ll <= l; ++ll) {
        const double pll = ((2.0 * ll - 1.0) * x * pmm1 - (ll + m - 1.0) * pmm) / (ll - m);
        pmm = pmm1;
        pmm1 = pll;
    }
    return pmm1;
}

double factorial(int n) {
    return n <= 1 ? 1.0 : n * factorial(n - 1);
}

// Real SH Y_l^m with theta from +z and phi in the x-y plane from +x, so that Y_1^-1 ~ y,
// Y_1^0 ~ z, Y_1^1 ~ x as in the Ramamoorthi-Hanrahan table; coefficient index l(l+1)+m.
double referenceSh(int l, int m, glm::dvec3 dir) {
    const int abs_m = std::abs(m);
    const double k =
        std::sqrt((2.0 * l + 1.0) / (4.0 * kPi) * factorial(l - abs_m) / factorial(l + abs_m));
    const double phi = std::atan2(dir.y, dir.x);
    const double p = legendre(l, abs_m, dir.z);
    if (m > 0) {
        return std::sqrt(2.0) * k * std::cos(m * phi) * p;
    }
    if (m < 0) {
        return std::sqrt(2.0) * k * std::sin(abs_m * phi) * p;
    }
    return k * p;
}

double legendrePolynomial(int l, double x) {
    return legendre(l, 0, x);
}

// Fixed seed; uniform numbers from mt19937's raw output, whose sequence the standard fixes
// (std distributions are implementation-defined).
class RandomDirections {
public:
    glm::vec3 next() {
        const double z = 2.0 * uniform() - 1.0;
        const double phi = 2.0 * kPi * uniform();
        const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
        return glm::vec3(glm::normalize(glm::dvec3(r * std::cos(phi), r * std::sin(phi), z)));
    }
    double uniform() { return double(m_rng() >> 8) * 0x1p-24; }

private:
    std::mt19937 m_rng{20240611u};
};

ShRgb randomSh(RandomDirections& random) {
    ShRgb result;
    for (auto& c : result.rgb) {
        c = glm::vec3(random.uniform(), random.uniform(), random.uniform()) * 2.0f - 1.0f;
    }
    return result;
}

// Clamped-cosine convolution of a unit-irradiance delta at angle cos(t) from it, band-limited
// to l <= 2: sum_l A_l (2l+1)/(4 pi) P_l(t) (addition theorem), i.e. 1/4 + t/2 + 5/16 P_2(t).
double l2ClampedCosine(double t) {
    const double lobe[3] = {kPi, 2.0 * kPi / 3.0, kPi / 4.0};
    double e = 0.0;
    for (int l = 0; l <= 2; ++l) {
        e += lobe[l] * (2.0 * l + 1.0) / (4.0 * kPi) * legendrePolynomial(l, t);
    }
    return e;
}

// ---- Basis ------------------------------------------------------------------------------------

TEST(ShBasis, ConstantsMatchClosedForms) {
    EXPECT_NEAR(sh::kY00, 1.0 / (2.0 * std::sqrt(kPi)), kPublishedDigitsTolerance);
    EXPECT_NEAR(sh::kY1, std::sqrt(3.0 / (4.0 * kPi)), kPublishedDigitsTolerance);
    EXPECT_NEAR(sh::kY2, std::sqrt(15.0 / (4.0 * kPi)), kPublishedDigitsTolerance);
    EXPECT_NEAR(sh::kY20, std::sqrt(5.0 / (16.0 * kPi)), kPublishedDigitsTolerance);
    EXPECT_NEAR(sh::kY22, std::sqrt(15.0 / (16.0 * kPi)), kPublishedDigitsTolerance);
}

TEST(ShBasis, OrthonormalByQuadrature) {
    // An off-axis pole so that no basis function is aligned with the quadrature frame.
    const auto points = sphereQuadrature(glm::dvec3(0.3, -0.5, 0.8));
    double gram[9][9] = {};
    for (const auto& point : points) {
        const Coeffs y = sh::evalBasis(point.dir);
        for (int i = 0; i < 9; ++i) {
            for (int j = 0; j < 9; ++j) {
                gram[i][j] += point.weight * double(y[i]) * double(y[j]);
            }
        }
    }
    for (int i = 0; i < 9; ++i) {
        for (int j = 0; j < 9; ++j) {
            EXPECT_NEAR(gram[i][j], i == j ? 1.0 : 0.0, kQuadratureTolerance)
                << "<Y" << i << ", Y" << j << ">";
        }
    }
}

TEST(ShBasis, MatchesGeneralRecurrence) {
    // The six axis directions first (the poles are where atan2 and sin(theta) degenerate), then
    // random ones.
    std::vector<glm::vec3> directions = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                         {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
    RandomDirections random;
    for (int sample = 0; sample < 1000; ++sample) {
        directions.push_back(random.next());
    }
    for (const glm::vec3 dir : directions) {
        const Coeffs y = sh::evalBasis(dir);
        for (int l = 0; l <= 2; ++l) {
            for (int m = -l; m <= l; ++m) {
                EXPECT_NEAR(y[l * (l + 1) + m], referenceSh(l, m, glm::dvec3(dir)),
                            kPointwiseBasisTolerance)
                    << "l=" << l << " m=" << m << " dir=(" << dir.x << ", " << dir.y << ", "
                    << dir.z << ")";
            }
        }
    }
}

TEST(ShBasis, BandOfAndCoefficientCount) {
    const int expected_band[9] = {0, 1, 1, 1, 2, 2, 2, 2, 2};
    for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(sh::bandOf(i), expected_band[i]);
    }
    EXPECT_EQ(sh::coefficientCount(Order::L1), 4);
    EXPECT_EQ(sh::coefficientCount(Order::L2), 9);
}

// ---- Projection ---------------------------------------------------------------------------------

TEST(ShProjection, ConstantRadiance) {
    const glm::vec3 radiance(1.0f, 0.5f, 2.0f);
    ShRgb projected;
    for (const auto& point : sphereQuadrature(glm::dvec3(0, 0, 1))) {
        sh::addSample(projected, Order::L2, point.dir, radiance, float(point.weight));
    }
    const double sqrt_four_pi = std::sqrt(4.0 * kPi);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(projected.rgb[0][c], sqrt_four_pi * radiance[c],
                    kQuadratureTolerance * radiance[c]);
        for (int i = 1; i < 9; ++i) {
            EXPECT_NEAR(projected.rgb[i][c], 0.0, kQuadratureTolerance) << "index " << i;
        }
    }

    // Analytically: L00 = sqrt(4 pi) L exactly, and E = A_0 L00 Y00 = pi L for every normal.
    ShRgb analytic;
    analytic.rgb[0] = float(sqrt_four_pi) * radiance;
    RandomDirections random;
    for (int sample = 0; sample < 100; ++sample) {
        const glm::vec3 normal = random.next();
        for (const ShRgb* set : {&projected, &analytic}) {
            const glm::vec3 e = sh::irradiance(*set, Order::L2, normal);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(e[c], kPi * radiance[c], kIrradianceTolerance * kPi * radiance[c]);
            }
        }
    }
}

// Projects max(0, n.axis) with addSample; by Funk-Hecke the result is A_l Y_lm(axis).
ShRgb projectClampedCosine(glm::vec3 axis) {
    ShRgb projected;
    for (const auto& point : sphereQuadrature(glm::dvec3(axis))) {
        const float cosine = std::max(0.0f, glm::dot(point.dir, axis));
        sh::addSample(projected, Order::L2, point.dir, glm::vec3(cosine), float(point.weight));
    }
    return projected;
}

TEST(ShProjection, ClampedCosineAboutZ) {
    // Ramamoorthi-Hanrahan's numbers: pi Y00, (2 pi / 3) Y10(+z), (pi / 4) Y20(+z).
    const double expected[9] = {0.886227, 0, 1.023327, 0, 0, 0, 0.495416, 0, 0};
    const ShRgb projected = projectClampedCosine(glm::vec3(0, 0, 1));
    for (int i = 0; i < 9; ++i) {
        EXPECT_NEAR(projected.rgb[i].x, expected[i], kQuadratureTolerance) << "index " << i;
    }
}

TEST(ShProjection, ClampedCosineAboutXAndY) {
    // The same lobe rotated: Y20(+x) = Y20(+y) = -kY20, Y22(+x) = kY22, Y22(+y) = -kY22.
    const double pi_over_4 = kPi / 4.0;
    const double y20 = -pi_over_4 * 0.315392;
    const double y22 = pi_over_4 * 0.546274;
    const double about_x[9] = {0.886227, 0, 0, 1.023327, 0, 0, y20, 0, y22};
    const double about_y[9] = {0.886227, 1.023327, 0, 0, 0, 0, y20, 0, -y22};
    const ShRgb projected_x = projectClampedCosine(glm::vec3(1, 0, 0));
    const ShRgb projected_y = projectClampedCosine(glm::vec3(0, 1, 0));
    for (int i = 0; i < 9; ++i) {
        EXPECT_NEAR(projected_x.rgb[i].x, about_x[i], kQuadratureTolerance) << "index " << i;
        EXPECT_NEAR(projected_y.rgb[i].x, about_y[i], kQuadratureTolerance) << "index " << i;
    }
}

TEST(ShProjection, ClampedCosineAboutAnyAxisIsLobeTimesBasis) {
    RandomDirections random;
    for (int sample = 0; sample < 5; ++sample) {
        const glm::vec3 axis = random.next();
        const ShRgb projected = projectClampedCosine(axis);
        const Coeffs y = sh::evalBasis(axis);
        for (int i = 0; i < 9; ++i) {
            EXPECT_NEAR(projected.rgb[i].x, sh::kCosineLobe[sh::bandOf(i)] * y[i],
                        kQuadratureTolerance)
                << "index " << i;
        }
    }
}

TEST(ShProjection, DeltaIsIrradianceTimesBasis) {
    const glm::vec3 dir = glm::normalize(glm::vec3(0.2f, 0.7f, -0.4f));
    const glm::vec3 e(3.0f, 2.0f, 1.0f);
    const Coeffs y = sh::evalBasis(dir);
    const ShRgb l2 = sh::projectDelta(dir, e, Order::L2);
    const ShRgb l1 = sh::projectDelta(dir, e, Order::L1);
    for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(l2.rgb[i], e * y[i]);
        EXPECT_EQ(l1.rgb[i], i < 4 ? e * y[i] : glm::vec3(0.0f));
    }
}

TEST(ShProjection, AddSampleLeavesCoefficientsBeyondOrderUntouched) {
    ShRgb set;
    for (int i = 0; i < 9; ++i) {
        set.rgb[i] = glm::vec3(float(i));
    }
    const glm::vec3 dir = glm::normalize(glm::vec3(1.0f, 2.0f, 3.0f));
    const glm::vec3 radiance(1.0f, 2.0f, 3.0f);
    constexpr float kWeight = 0.25f;
    sh::addSample(set, Order::L1, dir, radiance, kWeight);
    const Coeffs y = sh::evalBasis(dir);
    for (int i = 0; i < 9; ++i) {
        const glm::vec3 expected =
            i < 4 ? glm::vec3(float(i)) + radiance * (y[i] * kWeight) : glm::vec3(float(i));
        EXPECT_EQ(set.rgb[i], expected) << "index " << i;
    }
}

// ---- Irradiance ---------------------------------------------------------------------------------

TEST(ShIrradiance, DirectionalDeltaMatchesL2ClampedCosine) {
    RandomDirections random;
    for (int light = 0; light < 20; ++light) {
        const glm::vec3 d = random.next();
        const ShRgb delta = sh::projectDelta(d, glm::vec3(1.0f), Order::L2);
        for (int sample = 0; sample < 200; ++sample) {
            const glm::vec3 n = random.next();
            const double t = glm::dot(glm::dvec3(n), glm::dvec3(d));
            const glm::vec3 e = sh::irradiance(delta, Order::L2, n);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(e[c], l2ClampedCosine(t), kIrradianceTolerance);
            }
        }
    }
}

TEST(ShIrradiance, DirectionalDeltaErrorAgainstExactClampedCosine) {
    // The L2 reconstruction 1/4 + t/2 + 5/16 P_2(t) minus max(0, t) is largest at the horizon,
    // t = 0: 1/4 - 5/32 = 3/32 = 0.09375 (the overshoot at t = 1 is only 1/16; the undershoot
    // at t = +-8/15 is 1/4 - 4/15 - 11/480 ~ -0.0396). As an L2 projection its squared error is
    // |max(0,t)|^2 - |E_L2|^2, averaged over the sphere 1/6 - (1/16 + 1/12 + 5/256) = 1/768:
    // RMS 1/sqrt(768) ~ 0.036084.
    constexpr double kExpectedMaxError = 3.0 / 32.0;
    const double expected_rms_error = 1.0 / std::sqrt(768.0);

    // Light along +y and an odd Fibonacci count: the points are a midpoint rule in y = n.d and
    // the middle one lies exactly on the horizon, so both numbers are hit to rounding.
    constexpr int kNormals = 20001;
    const ShRgb delta = sh::projectDelta(glm::vec3(0, 1, 0), glm::vec3(1.0f), Order::L2);
    double max_error = 0.0;
    double sum_squared_error = 0.0;
    for (int i = 0; i < kNormals; ++i) {
        const glm::vec3 n = sh::fibonacciDirection(i, kNormals);
        const double error = sh::irradiance(delta, Order::L2, n).x - std::max(0.0f, n.y);
        max_error = std::max(max_error, std::abs(error));
        sum_squared_error += error * error;
    }
    EXPECT_NEAR(max_error, kExpectedMaxError, kIrradianceTolerance);
    EXPECT_NEAR(std::sqrt(sum_squared_error / kNormals), expected_rms_error, kIrradianceTolerance);
}

TEST(ShIrradiance, EqualsCosineConvolutionOfReconstructedRadiance) {
    // E(n) = integral of L(w) max(0, n.w) dw, with L the band-limited radiance the coefficients
    // describe; the quadrature about n is exact for it, so this checks every A_l independently.
    RandomDirections random;
    for (const Order order : {Order::L1, Order::L2}) {
        for (int trial = 0; trial < 10; ++trial) {
            const ShRgb set =
                order == Order::L1 ? sh::truncateToL1(randomSh(random)) : randomSh(random);
            const glm::vec3 n = random.next();
            glm::dvec3 convolved(0.0);
            for (const auto& point : sphereQuadrature(glm::dvec3(n))) {
                const double cosine = std::max(0.0, glm::dot(glm::dvec3(point.dir), glm::dvec3(n)));
                convolved +=
                    glm::dvec3(sh::evalRadiance(set, order, point.dir)) * cosine * point.weight;
            }
            const glm::vec3 e = sh::irradiance(set, order, n);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(e[c], convolved[c], kQuadratureTolerance);
            }
        }
    }
}

TEST(ShIrradiance, IsRadianceOfLobeScaledCoefficients) {
    RandomDirections random;
    for (const Order order : {Order::L1, Order::L2}) {
        const ShRgb set = randomSh(random);
        ShRgb scaled = set;
        for (int i = 0; i < 9; ++i) {
            scaled.rgb[i] *= sh::kCosineLobe[sh::bandOf(i)];
        }
        for (int sample = 0; sample < 100; ++sample) {
            const glm::vec3 n = random.next();
            const glm::vec3 e = sh::irradiance(set, order, n);
            const glm::vec3 radiance = sh::evalRadiance(scaled, order, n);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(e[c], radiance[c], kIrradianceTolerance);
            }
        }
        // The order argument, not the stored zeros, limits the sum.
        const glm::vec3 n = random.next();
        EXPECT_EQ(sh::evalRadiance(set, Order::L1, n),
                  sh::evalRadiance(sh::truncateToL1(set), Order::L2, n));
    }
}

TEST(ShTruncate, ZeroesBandTwoAndKeepsBandsZeroAndOne) {
    RandomDirections random;
    const ShRgb set = randomSh(random);
    const ShRgb l1 = sh::truncateToL1(set);
    for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(l1.rgb[i], i < 4 ? set.rgb[i] : glm::vec3(0.0f)) << "index " << i;
    }
}

// ---- The exact minimum and deringing ---------------------------------------------------------

// E of one channel at unit normal n as the runtime evaluates it (sh::irradiance, float).
double channelIrradiance(const ShRgb& set, Order order, glm::vec3 n, int channel) {
    return double(sh::irradiance(set, order, n)[channel]);
}

// Smallest E of one channel over n spherical-Fibonacci normals, evaluated in float as above.
double sampledMinimum(const ShRgb& set, Order order, int channel, int n) {
    double min_e = std::numeric_limits<double>::infinity();
    for (int i = 0; i < n; ++i) {
        min_e =
            std::min(min_e, channelIrradiance(set, order, sh::fibonacciDirection(i, n), channel));
    }
    return min_e;
}

// Largest |E| of a channel's terms, sum_i A_l |L_i| peak|Y_i|: the scale of its rounding.
double irradianceScale(const ShRgb& set, Order order, int channel) {
    constexpr double kPeak[9] = {0.282095, 0.488603, 0.488603, 0.488603, 0.546274,
                                 0.546274, 0.630784, 0.546274, 0.546274};
    double sum = 0.0;
    for (int i = 0; i < sh::coefficientCount(order); ++i) {
        sum += double(sh::kCosineLobe[sh::bandOf(i)]) * std::abs(double(set.rgb[i][channel])) *
               kPeak[i];
    }
    return sum;
}

// Relative RMS change of E over the sphere, by quadrature (independent of the coefficient
// identity DeringResult uses): sqrt(int |E_a - E_b|^2 / int |E_b|^2) over all channels.
double quadratureRelativeChange(const ShRgb& a, const ShRgb& b, Order order) {
    double num = 0.0;
    double den = 0.0;
    for (const QuadraturePoint& q : sphereQuadrature(glm::dvec3(0, 0, 1))) {
        const glm::dvec3 ea(sh::irradiance(a, order, q.dir));
        const glm::dvec3 eb(sh::irradiance(b, order, q.dir));
        num += q.weight * glm::dot(ea - eb, ea - eb);
        den += q.weight * glm::dot(eb, eb);
    }
    return std::sqrt(num / den);
}

// Float evaluation of E (sh::irradiance: nine float products and sums, constants of size ~1)
// next to the exact minimum in double: a few ulp of the largest term.
constexpr double kFloatEvaluationTolerance = 1e-6;
// 200001 Fibonacci normals are ~0.008 rad apart: the sampled minimum misses the exact one by at
// most (curvature <= 3 x the terms' scale) x (half the spacing)^2 / 2 ~ 3e-5 of the scale;
// the bound leaves 3x.
constexpr int kDenseNormals = 200001;
constexpr double kDenseSamplingGap = 1e-4;

// Random channels: a mean and bands of either sign, some lobes strong enough to ring.
ShRgb randomRinging(RandomDirections& random, Order order) {
    ShRgb set;
    for (int c = 0; c < 3; ++c) {
        // One to three delta lights of strengths over six decades, and an ambient term.
        const int lights = 1 + int(random.uniform() * 3.0);
        for (int k = 0; k < lights; ++k) {
            const float strength = float(std::pow(10.0, 6.0 * random.uniform() - 2.0));
            const ShRgb delta = sh::projectDelta(random.next(), glm::vec3(strength), order);
            for (int i = 0; i < 9; ++i) {
                set.rgb[i][c] += delta.rgb[i][c];
            }
        }
        set.rgb[0][c] += float(random.uniform() * random.uniform()) * set.rgb[0][c];
        // Noise on every coefficient, as Monte Carlo leaves it.
        for (int i = 1; i < sh::coefficientCount(order); ++i) {
            set.rgb[i][c] += float(0.1 * (2.0 * random.uniform() - 1.0)) * set.rgb[0][c];
        }
    }
    return set;
}

TEST(ShMinimum, DeltaLobeHasItsAnalyticRingMinimum) {
    // The hard case of the trust-region problem: the L2 lobe of a delta is axially symmetric and
    // takes its minimum on a ring, t = n.d = -8/15, where 1/4 + t/2 + 5/16 P2(t) = -19/480.
    const glm::vec3 d = glm::normalize(glm::vec3(0.3f, 0.8f, -0.5f));
    const ShRgb delta = sh::projectDelta(d, glm::vec3(1.0f, 10.0f, 0.01f), Order::L2);
    const double scale[3] = {1.0, 10.0, 0.01};
    for (int c = 0; c < 3; ++c) {
        const sh::IrradianceMinimum m = sh::minimumIrradiance(delta, Order::L2, c);
        EXPECT_NEAR(m.value, -19.0 / 480.0 * scale[c], kIrradianceTolerance * scale[c]);
        EXPECT_NEAR(glm::length(m.normal), 1.0, 1e-12);
        EXPECT_NEAR(glm::dot(m.normal, glm::dvec3(d)), -8.0 / 15.0, 1e-5);
        EXPECT_NEAR(channelIrradiance(delta, Order::L2, glm::vec3(m.normal), c), m.value,
                    kFloatEvaluationTolerance * scale[c]);
    }
    // L1: 1/4 + t/2, its minimum -1/4 straight opposite the light.
    const ShRgb l1 = sh::projectDelta(d, glm::vec3(1.0f), Order::L1);
    const sh::IrradianceMinimum m1 = sh::minimumIrradiance(l1, Order::L1, 0);
    EXPECT_NEAR(m1.value, -0.25, kIrradianceTolerance);
    // d is normalised in float, and the coefficients are float products of it: ~1e-7.
    EXPECT_NEAR(glm::dot(m1.normal, glm::dvec3(d)), -1.0, 1e-6);
}

TEST(ShMinimum, MatchesDenseSamplingAndIsTakenAtItsNormal) {
    RandomDirections random;
    double largest_gap = 0.0;
    for (int trial = 0; trial < 24; ++trial) {
        const Order order = trial % 4 == 0 ? Order::L1 : Order::L2;
        const ShRgb set = trial % 2 == 0 ? randomSh(random) : randomRinging(random, order);
        for (int c = 0; c < 3; ++c) {
            const double scale = irradianceScale(set, order, c);
            const sh::IrradianceMinimum m = sh::minimumIrradiance(set, order, c);
            const double sampled = sampledMinimum(set, order, c, kDenseNormals);
            // Never above any sampled value (it is a lower bound) but by float evaluation...
            EXPECT_LE(m.value, sampled + kFloatEvaluationTolerance * scale) << trial << " " << c;
            // ... never far below what the dense set finds...
            EXPECT_GE(m.value, sampled - kDenseSamplingGap * scale) << trial << " " << c;
            // ... and taken at its own normal.
            EXPECT_NEAR(channelIrradiance(set, order, glm::vec3(m.normal), c), m.value,
                        kFloatEvaluationTolerance * scale)
                << trial << " " << c;
            largest_gap = std::max(largest_gap, (sampled - m.value) / scale);
        }
    }
    std::printf("[sh minimum] dense sampling (%d normals) lies above the exact minimum by at most "
                "%.3g of the terms' scale\n",
                kDenseNormals, largest_gap);
}

TEST(ShDering, SingleDeltaCostIsStatedAndBounded) {
    // The least-change band window for a lone delta, solved on the continuous sphere (sh.hpp):
    // minimise (pi/3)(1 - s1)^2 + (5 pi/64)(1 - s2)^2 subject to
    // 1/4 - 5 s2 / 32 - 2 s1^2 / (15 s2) >= 0 (the minimum at the vertex t = -8 s1 / (15 s2))
    // gives s1 = 0.85789, s2 = 0.90940 and a relative RMS change of E of 0.10558. The margin
    // (1e-4 of the mean, targeted at 2e-4 plus rounding) moves that by ~1e-4.
    constexpr double kScale1 = 0.85789;
    constexpr double kScale2 = 0.90940;
    constexpr double kChange = 0.10558;
    constexpr double kMarginTolerance = 1e-3;
    // Sloan's window with its smallest lambda that makes E >= 0 (0.177732: band scales 0.5845,
    // 0.1352) changes E by 0.41875 RMS; the least-change window must do at least 3x better.
    constexpr double kSloanChange = 0.41875;
    for (const glm::vec3 d : {glm::vec3(0, 1, 0), glm::normalize(glm::vec3(0.3f, 0.8f, -0.5f)),
                              glm::normalize(glm::vec3(-0.6f, 0.1f, 0.7f))}) {
        const ShRgb delta = sh::projectDelta(d, glm::vec3(100.0f), Order::L2);
        const sh::DeringResult r = sh::deringIrradiance(delta, Order::L2);
        ASSERT_TRUE(r.changed());
        EXPECT_EQ(r.changedChannels, 7);
        EXPECT_NEAR(r.band1Scale.x, kScale1, kMarginTolerance);
        EXPECT_NEAR(r.band2Scale.x, kScale2, kMarginTolerance);
        EXPECT_NEAR(r.relativeChange, kChange, kMarginTolerance);
        EXPECT_LT(r.relativeChange, kSloanChange / 3.0);
        EXPECT_NEAR(quadratureRelativeChange(r.sh, delta, Order::L2), r.relativeChange, 1e-5);
        EXPECT_EQ(r.sh.rgb[0], delta.rgb[0]) << "band 0 is never changed";
        EXPECT_NEAR(r.minBefore.x, -19.0 / 480.0 * 100.0, 100.0 * kIrradianceTolerance);
        const double mean = sh::meanIrradiance(delta, 0);
        EXPECT_GE(r.minAfter.x, sh::kDeringMargin * mean);
        EXPECT_LE(r.minAfter.x, 4.0 * sh::kDeringMargin * mean) << "no more than it needs";
        std::printf("[dering delta] L2: s1 %.5f s2 %.5f, relative RMS change of E %.5f "
                    "(Sloan's smallest window: %.5f); min E %.4g -> %.3g W/m^2\n",
                    double(r.band1Scale.x), double(r.band2Scale.x), double(r.relativeChange),
                    kSloanChange, r.minBefore.x, r.minAfter.x);

        // L1: 1/4 + s1 t / 2 >= 0 needs s1 = 1/2 (less the margin); band 1 of E shrinks by
        // 1 - s1, so the change is (1 - s1) |E_1| / |E| = 0.5 sqrt((pi/3) / (pi/4 + pi/3)).
        const ShRgb l1 = sh::projectDelta(d, glm::vec3(100.0f), Order::L1);
        const sh::DeringResult r1 = sh::deringIrradiance(l1, Order::L1);
        const double l1_change = 0.5 * std::sqrt((kPi / 3.0) / (kPi / 4.0 + kPi / 3.0));
        EXPECT_NEAR(r1.band1Scale.x, 0.5, kMarginTolerance);
        EXPECT_LE(r1.band1Scale.x, 0.5f);
        EXPECT_NEAR(r1.relativeChange, l1_change, kMarginTolerance);
        EXPECT_NEAR(quadratureRelativeChange(r1.sh, l1, Order::L1), r1.relativeChange, 1e-5);
        for (int i = 4; i < 9; ++i) {
            EXPECT_EQ(r1.sh.rgb[i], glm::vec3(0.0f));
        }

        // Half storage: the window is solved so that the rounded values pass; that costs a little
        // more margin (the rounding bound) and hardly any error.
        const sh::DeringResult h = sh::deringIrradiance(delta, Order::L2, sh::Rounding::Float16);
        EXPECT_NEAR(h.relativeChange, r.relativeChange, 5e-3);
        EXPECT_EQ(sh::roundTo(h.sh, sh::Rounding::Float16), h.sh) << "changed values are stored";
    }
}

TEST(ShDering, EveryResultIsNonNegativeOverTheWholeSphere) {
    RandomDirections random;
    int changed = 0;
    int dense_checked = 0;
    double worst_dense = std::numeric_limits<double>::infinity();
    constexpr int kTrials = 600;
    for (int trial = 0; trial < kTrials; ++trial) {
        const Order order = trial % 3 == 0 ? Order::L1 : Order::L2;
        const sh::Rounding rounding =
            trial % 2 == 0 ? sh::Rounding::Float16 : sh::Rounding::Float32;
        const ShRgb set = randomRinging(random, order);
        const sh::DeringResult r = sh::deringIrradiance(set, order, rounding);
        changed += r.changed() ? 1 : 0;
        const ShRgb stored = sh::roundTo(r.sh, rounding);
        for (int c = 0; c < 3; ++c) {
            const double mean = sh::meanIrradiance(stored, c);
            ASSERT_GT(mean, 0.0);
            // Band 0 as stored is the input's as stored.
            EXPECT_EQ(stored.rgb[0][c], sh::roundTo(set, rounding).rgb[0][c]);
            // The exact minimum of the stored values keeps the margin...
            const sh::IrradianceMinimum m = sh::minimumIrradiance(stored, order, c);
            EXPECT_GE(m.value, sh::kDeringMargin * mean) << trial << " channel " << c;
            EXPECT_NEAR(m.value, r.minAfter[c], 1e-12 * irradianceScale(stored, order, c));
            // ... and E in float at the 2000 normals, and at 200001 for every 20th set, is >= 0.
            const int normals = trial % 20 == 0 ? kDenseNormals : 2000;
            const double sampled = sampledMinimum(stored, order, c, normals);
            EXPECT_GE(sampled, 0.0) << trial << " channel " << c;
            if (normals == kDenseNormals) {
                ++dense_checked;
                worst_dense = std::min(worst_dense, sampled / mean);
            }
        }
    }
    std::printf("[dering random] %d of %d ringing sets changed; over %d channels checked at %d "
                "normals the smallest E is %.3g of the mean\n",
                changed, kTrials, dense_checked, kDenseNormals, worst_dense);
    EXPECT_GT(changed, kTrials / 2) << "the sets must ring for the test to mean anything";
}

TEST(ShDering, LeastChangeAmongBandWindows) {
    // Against brute force: s2 on a grid of 201, the largest feasible s1 by bisection on the
    // exact minimum, the cost (1 - s1)^2 |E_1|^2 + (1 - s2)^2 |E_2|^2. The solver searches s2
    // continuously, so it may only be better, but for the grid's own optimum being between
    // points; and Sloan's one-parameter window, which is one curve in the same square, never
    // beats it.
    RandomDirections random;
    for (int trial = 0; trial < 12; ++trial) {
        const ShRgb set = randomRinging(random, Order::L2);
        const sh::DeringResult r = sh::deringIrradiance(set, Order::L2);
        for (int c = 0; c < 3; ++c) {
            if ((r.changedChannels & (1 << c)) == 0) {
                continue;
            }
            double w[3] = {0.0, 0.0, 0.0};
            for (int i = 1; i < 9; ++i) {
                const double e = double(sh::kCosineLobe[sh::bandOf(i)]) * set.rgb[i][c];
                w[sh::bandOf(i)] += e * e;
            }
            const double target = r.minAfter[c];
            const auto feasible = [&](double s1, double s2) {
                const ShRgb windowed =
                    sh::scaleBands(set, Order::L2, glm::vec3(float(s1)), glm::vec3(float(s2)));
                return sh::minimumIrradiance(windowed, Order::L2, c).value >= target;
            };
            double best = std::numeric_limits<double>::infinity();
            for (int k = 0; k <= 200 && feasible(0.0, k / 200.0); ++k) {
                const double s2 = k / 200.0;
                double lo = 0.0;
                double hi = 1.0;
                if (feasible(1.0, s2)) {
                    lo = 1.0;
                }
                for (int step = 0; step < 40 && lo < 1.0; ++step) {
                    const double mid = 0.5 * (lo + hi);
                    (feasible(mid, s2) ? lo : hi) = mid;
                }
                best = std::min(best, w[1] * (1 - lo) * (1 - lo) + w[2] * (1 - s2) * (1 - s2));
            }
            const double s1 = r.band1Scale[c];
            const double s2 = r.band2Scale[c];
            const double cost = w[1] * (1 - s1) * (1 - s1) + w[2] * (1 - s2) * (1 - s2);
            // A grid step of 0.005 in s2 costs at most ~(0.0025)^2 (w1 + w2) near the optimum.
            EXPECT_LE(cost, best + 1e-5 * (w[1] + w[2])) << trial << " channel " << c;

            double lo = 0.0;
            double hi = 1.0;
            while (sh::minimumIrradiance(sh::applyWindow(set, Order::L2, float(hi)), Order::L2, c)
                       .value < target) {
                lo = hi;
                hi *= 2.0;
            }
            for (int step = 0; step < 50; ++step) {
                const double mid = 0.5 * (lo + hi);
                (sh::minimumIrradiance(sh::applyWindow(set, Order::L2, float(mid)), Order::L2, c)
                             .value >= target
                     ? hi
                     : lo) = mid;
            }
            const double t1 = 1.0 / (1.0 + 4.0 * hi);
            const double t2 = 1.0 / (1.0 + 36.0 * hi);
            const double sloan = w[1] * (1 - t1) * (1 - t1) + w[2] * (1 - t2) * (1 - t2);
            EXPECT_LE(cost, sloan * (1.0 + 1e-6)) << trial << " channel " << c;
        }
    }
}

TEST(ShDering, NonNegativeSetIsUnchangedBitForBit) {
    // A constant, a mild directional lobe on a strong ambient, and what deringing returned
    // (deringing is idempotent): all come back as they went in, for both storages.
    ShRgb constant;
    constant.rgb[0] = glm::vec3(1.0f, 2.0f, 3.0f);
    ShRgb mild = sh::projectDelta(glm::normalize(glm::vec3(1, 2, 3)), glm::vec3(0.1f), Order::L2);
    mild.rgb[0] += glm::vec3(1.0f);
    const ShRgb deringed =
        sh::deringIrradiance(sh::projectDelta(glm::vec3(0, 0, 1), glm::vec3(5.0f), Order::L2),
                             Order::L2)
            .sh;
    const ShRgb deringed_half =
        sh::deringIrradiance(sh::projectDelta(glm::vec3(0, 0, 1), glm::vec3(5.0f), Order::L2),
                             Order::L2, sh::Rounding::Float16)
            .sh;
    for (const sh::Rounding rounding : {sh::Rounding::Float32, sh::Rounding::Float16}) {
        for (const ShRgb& set : {constant, mild, ShRgb{},
                                 rounding == sh::Rounding::Float32 ? deringed : deringed_half}) {
            const sh::DeringResult r = sh::deringIrradiance(set, Order::L2, rounding);
            EXPECT_FALSE(r.changed());
            EXPECT_EQ(r.sh, set);
            EXPECT_EQ(r.relativeChange, 0.0f);
            EXPECT_EQ(r.band1Scale, glm::vec3(1.0f));
            EXPECT_EQ(r.band2Scale, glm::vec3(1.0f));
        }
    }
}

TEST(ShDering, ChannelsAreWindowedEachOnItsOwn) {
    // A red-heavy light over a blue-heavy ambient: red rings most, green less, blue not at
    // all. Each channel gets its own window, and blue is left exactly as it was.
    const glm::vec3 d = glm::normalize(glm::vec3(0.5f, -0.2f, 0.4f));
    ShRgb set = sh::projectDelta(d, glm::vec3(4.0f, 2.0f, 1.0f), Order::L2);
    set.rgb[0] += glm::vec3(0.05f, 0.05f, 2.0f);
    const sh::DeringResult r = sh::deringIrradiance(set, Order::L2);
    EXPECT_EQ(r.changedChannels, 3); // red and green
    EXPECT_LT(r.band1Scale.x, r.band1Scale.y);
    EXPECT_EQ(r.band1Scale.z, 1.0f);
    EXPECT_EQ(r.band2Scale.z, 1.0f);
    for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(r.sh.rgb[i].z, set.rgb[i].z) << i;
    }
    EXPECT_EQ(r.sh.rgb[0], set.rgb[0]);
    for (int c = 0; c < 3; ++c) {
        EXPECT_GE(sh::minimumIrradiance(r.sh, Order::L2, c).value,
                  sh::kDeringMargin * sh::meanIrradiance(set, c));
    }
}

TEST(ShDering, ChannelWithoutPositiveMeanBecomesZero) {
    // L00 < 0 (noise) or = 0 under a non-zero lobe: no window helps, the channel becomes zero
    // (E = 0), and the other channels are unaffected. A channel of zeros stays as it is.
    RandomDirections random;
    ShRgb set = sh::projectDelta(random.next(), glm::vec3(1.0f), Order::L2);
    set.rgb[0] = glm::vec3(1.0f, -0.1f, 0.0f);
    const sh::DeringResult r = sh::deringIrradiance(set, Order::L2);
    EXPECT_EQ(r.zeroedChannels, 6); // green and blue
    for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(r.sh.rgb[i].y, 0.0f);
        EXPECT_EQ(r.sh.rgb[i].z, 0.0f);
        EXPECT_EQ(r.sh.rgb[i].x, set.rgb[i].x) << "red's E >= 0 already (mean 1 over a unit delta)";
    }
    EXPECT_EQ(r.minAfter.y, 0.0);

    const sh::DeringResult zero = sh::deringIrradiance(ShRgb{}, Order::L2);
    EXPECT_FALSE(zero.changed());
    EXPECT_EQ(zero.sh, ShRgb{});
}

TEST(ShDering, HalfStorageIsCheckedAsStored) {
    // Windows solved for float and then rounded to half dip below the margin on some sets (the
    // rounding moves E by ~2^-11 of its terms); solved for half, they never do.
    RandomDirections random;
    int float_window_fails_as_half = 0;
    for (int trial = 0; trial < 200; ++trial) {
        const ShRgb set = randomRinging(random, Order::L2);
        const ShRgb as_float = sh::deringIrradiance(set, Order::L2).sh;
        const ShRgb as_half = sh::roundTo(
            sh::deringIrradiance(set, Order::L2, sh::Rounding::Float16).sh, sh::Rounding::Float16);
        const ShRgb float_rounded = sh::roundTo(as_float, sh::Rounding::Float16);
        for (int c = 0; c < 3; ++c) {
            const double mean = sh::meanIrradiance(float_rounded, c);
            float_window_fails_as_half +=
                sh::minimumIrradiance(float_rounded, Order::L2, c).value < sh::kDeringMargin * mean
                    ? 1
                    : 0;
            EXPECT_GE(sh::minimumIrradiance(as_half, Order::L2, c).value,
                      sh::kDeringMargin * sh::meanIrradiance(as_half, c));
        }
    }
    std::printf("[dering half] %d channels deringed for float fall below the margin as half\n",
                float_window_fails_as_half);
    EXPECT_GT(float_window_fails_as_half, 0);
}

TEST(ShDering, UnstorableValuesAreLeftForMakeVolume) {
    ShRgb set = sh::projectDelta(glm::vec3(0, 1, 0), glm::vec3(1.0f), Order::L2);
    set.rgb[3].x = std::numeric_limits<float>::quiet_NaN();
    EXPECT_FALSE(sh::deringIrradiance(set, Order::L2).changed());
    ShRgb big = sh::projectDelta(glm::vec3(0, 1, 0), glm::vec3(1e6f), Order::L2);
    EXPECT_FALSE(sh::deringIrradiance(big, Order::L2, sh::Rounding::Float16).changed());
    EXPECT_TRUE(sh::deringIrradiance(big, Order::L2, sh::Rounding::Float32).changed());
}

TEST(ShDering, ScaleBandsScalesEachBandPerChannel) {
    RandomDirections random;
    const ShRgb set = randomSh(random);
    const glm::vec3 s1(0.5f, 0.25f, 1.0f);
    const glm::vec3 s2(0.1f, 1.0f, 0.0f);
    const ShRgb scaled = sh::scaleBands(set, Order::L2, s1, s2);
    for (int i = 0; i < 9; ++i) {
        const glm::vec3 expected = i == 0 ? glm::vec3(1.0f) : (sh::bandOf(i) == 1 ? s1 : s2);
        EXPECT_EQ(scaled.rgb[i], set.rgb[i] * expected) << i;
    }
    const ShRgb l1 = sh::scaleBands(set, Order::L1, s1, s2);
    for (int i = 4; i < 9; ++i) {
        EXPECT_EQ(l1.rgb[i], set.rgb[i]) << "L1 leaves the unused entries alone";
    }
}

TEST(ShDering, ApplyWindowScalesEachBand) {
    RandomDirections random;
    const ShRgb set = randomSh(random);
    constexpr float kLambda = 0.5f;
    const ShRgb windowed = sh::applyWindow(set, Order::L2, kLambda);
    const float expected_scale[3] = {1.0f, 1.0f / (1.0f + kLambda * 4.0f),
                                     1.0f / (1.0f + kLambda * 36.0f)};
    for (int i = 0; i < 9; ++i) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_FLOAT_EQ(windowed.rgb[i][c], set.rgb[i][c] * expected_scale[sh::bandOf(i)]);
        }
    }
    EXPECT_EQ(sh::applyWindow(set, Order::L2, 0.0f), set);
}

// ---- Fibonacci directions and ShRgb arithmetic --------------------------------------------------

TEST(ShFibonacci, MatchesFormulaAndIsUnitLength) {
    // Float output of a double formula: half an ulp of values <= 1, with room.
    constexpr double kDirectionTolerance = 1e-6;
    for (const int n : {1, 2, 7, 512, 100000}) {
        for (int i = 0; i < n; i += std::max(1, n / 97)) {
            const double y = 1.0 - (2.0 * i + 1.0) / n;
            const double phi = i * kPi * (3.0 - std::sqrt(5.0));
            const double r = std::sqrt(1.0 - y * y);
            const glm::vec3 dir = sh::fibonacciDirection(i, n);
            EXPECT_NEAR(dir.x, r * std::cos(phi), kDirectionTolerance) << i << " of " << n;
            EXPECT_NEAR(dir.y, y, kDirectionTolerance) << i << " of " << n;
            EXPECT_NEAR(dir.z, r * std::sin(phi), kDirectionTolerance) << i << " of " << n;
            EXPECT_NEAR(glm::length(glm::dvec3(dir)), 1.0, kDirectionTolerance);
        }
    }
}

TEST(ShRgbOps, AddAndScale) {
    ShRgb a;
    ShRgb b;
    for (int i = 0; i < 9; ++i) {
        a.rgb[i] = glm::vec3(float(i), 1.0f, -2.0f);
        b.rgb[i] = glm::vec3(0.5f, float(i), 4.0f);
    }
    ShRgb sum = a;
    EXPECT_EQ(&(sum += b), &sum);
    ShRgb scaled = a;
    EXPECT_EQ(&(scaled *= 2.0f), &scaled);
    for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(sum.rgb[i], glm::vec3(float(i) + 0.5f, 1.0f + float(i), 2.0f));
        EXPECT_EQ(scaled.rgb[i], glm::vec3(2.0f * float(i), 2.0f, -4.0f));
    }
    EXPECT_NE(sum, a);
    EXPECT_EQ(ShRgb{}, ShRgb{});
}

} // namespace
