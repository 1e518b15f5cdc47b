// probekit::sh — see sh.hpp for the convention (Ramamoorthi-Hanrahan 2001 ordering and
// constants, no Condon-Shortley phase, glTF axes) and the deringing window (Sloan 2017).
#include "probekit/formats/sh.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>

#include <glm/geometric.hpp>

namespace probekit::sh {

namespace {

// Loose enough for directions normalised in float and passed through a few transforms.
constexpr float kUnitLengthTolerance = 1e-3f;

[[maybe_unused]] bool isUnit(glm::vec3 dir) {
    return std::abs(glm::dot(dir, dir) - 1.0f) < kUnitLengthTolerance;
}

// Bisection brackets. Window strengths of interest (a lone delta light) are ~0.01..1; the search
// starts below that and doubles. At kMaxLambda band 1 is scaled by < 3e-7, i.e. only band 0
// is left in any float sense, so a set still negative there is past fixing by any window.
constexpr double kInitialLambda = 1.0 / 1024.0;
constexpr double kMaxLambda = 1024.0 * 1024.0;
constexpr double kLambdaRelativeTolerance = 1e-4; // as promised in sh.hpp
// Bisection from [0, kInitialLambda] could otherwise chase a vanishing lambda (a set whose
// minimum is a rounding-level negative) forever; 64 halvings is far below float resolution.
constexpr int kMaxBisectionSteps = 64;

double windowScale(int band, double lambda) {
    const double l = band;
    return 1.0 / (1.0 + lambda * l * l * (l + 1.0) * (l + 1.0));
}

using TestBasis = std::array<std::array<double, kMaxCoefficients>, kDeringTestNormals>;

// The basis at the test normals is the same for every call; a function-local static builds it
// once, thread-safely.
const TestBasis& testBasis() {
    static const TestBasis table = [] {
        TestBasis basis{};
        for (int i = 0; i < kDeringTestNormals; ++i) {
            const Coeffs y = evalBasis(fibonacciDirection(i, kDeringTestNormals));
            std::copy(y.begin(), y.end(), basis[i].begin());
        }
        return basis;
    }();
    return table;
}

// E at the test normals split by band, so that windowed E = b0 + s1 b1 + s2 b2: the basis is
// visited once per call and each bisection step costs two multiply-adds per normal and channel.
// Indexed [band][normal * 3 + channel]; double so that "non-negative" is decided well below float
// resolution (rounding the windowed coefficients to float then moves E by ~1e-7 of its peak).
using BandedIrradiance = std::array<std::array<double, 3 * kDeringTestNormals>, 3>;

BandedIrradiance bandedIrradiance(const ShRgb& sh, Order order) {
    const TestBasis& basis = testBasis();
    BandedIrradiance banded{};
    for (int n = 0; n < kDeringTestNormals; ++n) {
        for (int i = 0; i < coefficientCount(order); ++i) {
            const int band = bandOf(i);
            const double weight = double(kCosineLobe[band]) * basis[n][i];
            for (int c = 0; c < 3; ++c) {
                banded[band][3 * n + c] += weight * double(sh.rgb[i][c]);
            }
        }
    }
    return banded;
}

double minWindowedIrradiance(const BandedIrradiance& banded, double lambda) {
    const double s1 = windowScale(1, lambda);
    const double s2 = windowScale(2, lambda);
    double min_e = banded[0][0] + s1 * banded[1][0] + s2 * banded[2][0];
    for (std::size_t k = 1; k < banded[0].size(); ++k) {
        min_e = std::min(min_e, banded[0][k] + s1 * banded[1][k] + s2 * banded[2][k]);
    }
    return min_e;
}

// Squared L2 norm of E over the sphere up to the constant 1/(4 pi), which cancels in the
// ratio: E's SH coefficients are A_l L_lm, so by orthonormality this is exact.
double irradianceEnergy(const ShRgb& sh, Order order) {
    double sum = 0.0;
    for (int i = 0; i < coefficientCount(order); ++i) {
        for (int c = 0; c < 3; ++c) {
            const double e = double(kCosineLobe[bandOf(i)]) * double(sh.rgb[i][c]);
            sum += e * e;
        }
    }
    return sum;
}

} // namespace

ShRgb& ShRgb::operator+=(const ShRgb& other) {
    for (int i = 0; i < kMaxCoefficients; ++i) {
        rgb[i] += other.rgb[i];
    }
    return *this;
}

ShRgb& ShRgb::operator*=(float scale) {
    for (auto& c : rgb) {
        c *= scale;
    }
    return *this;
}

Coeffs evalBasis(glm::vec3 dir) {
    assert(isUnit(dir));
    const float x = dir.x;
    const float y = dir.y;
    const float z = dir.z;
    return {
        kY00,
        kY1 * y,
        kY1 * z,
        kY1 * x,
        kY2 * x * y,
        kY2 * y * z,
        kY20 * (3.0f * z * z - 1.0f),
        kY2 * x * z,
        kY22 * (x * x - y * y),
    };
}

void addSample(ShRgb& sh, Order order, glm::vec3 dir, glm::vec3 radiance, float weight) {
    const Coeffs y = evalBasis(dir);
    for (int i = 0; i < coefficientCount(order); ++i) {
        sh.rgb[i] += radiance * (y[i] * weight);
    }
}

ShRgb projectDelta(glm::vec3 dir, glm::vec3 irradiance, Order order) {
    const Coeffs y = evalBasis(dir);
    ShRgb sh;
    for (int i = 0; i < coefficientCount(order); ++i) {
        sh.rgb[i] = irradiance * y[i];
    }
    return sh;
}

glm::vec3 evalRadiance(const ShRgb& sh, Order order, glm::vec3 dir) {
    const Coeffs y = evalBasis(dir);
    glm::vec3 radiance(0.0f);
    for (int i = 0; i < coefficientCount(order); ++i) {
        radiance += sh.rgb[i] * y[i];
    }
    return radiance;
}

// Mirrored term for term by pk_sh_irradiance in shaders/probe_volume.glsl.
glm::vec3 irradiance(const ShRgb& sh, Order order, glm::vec3 normal) {
    const Coeffs y = evalBasis(normal);
    glm::vec3 e(0.0f);
    for (int i = 0; i < coefficientCount(order); ++i) {
        e += sh.rgb[i] * (kCosineLobe[bandOf(i)] * y[i]);
    }
    return e;
}

ShRgb truncateToL1(const ShRgb& sh) {
    ShRgb l1 = sh;
    std::fill(l1.rgb.begin() + coefficientCount(Order::L1), l1.rgb.end(), glm::vec3(0.0f));
    return l1;
}

ShRgb applyWindow(const ShRgb& sh, Order order, float lambda) {
    assert(lambda >= 0.0f);
    ShRgb windowed = sh;
    for (int i = 1; i < coefficientCount(order); ++i) {
        windowed.rgb[i] *= float(windowScale(bandOf(i), lambda));
    }
    return windowed;
}

DeringResult deringIrradiance(const ShRgb& sh, Order order) {
    DeringResult result;
    result.sh = sh;
    const BandedIrradiance banded = bandedIrradiance(sh, order);
    const double min_before = minWindowedIrradiance(banded, 0.0);
    result.minIrradiance = float(std::min(min_before, 0.0));
    if (min_before >= 0.0) {
        return result;
    }

    const auto non_negative = [&](double lambda) {
        return minWindowedIrradiance(banded, lambda) >= 0.0;
    };
    // Invariant: lo is infeasible (0 is, since min_before < 0) and hi is feasible once found.
    double lo = 0.0;
    double hi = kInitialLambda;
    bool feasible = non_negative(hi);
    while (!feasible && hi < kMaxLambda) {
        lo = hi;
        hi *= 2.0;
        feasible = non_negative(hi);
    }
    // Not feasible at kMaxLambda means band 0 alone is negative on some channel (L00 <= 0, or so
    // small against the other bands that it is lost in rounding), which no window fixes: the
    // strongest window is the closest we can get, and relativeChange reports what it cost.
    if (feasible) {
        for (int step = 0; step < kMaxBisectionSteps && hi - lo > kLambdaRelativeTolerance * hi;
             ++step) {
            const double mid = 0.5 * (lo + hi);
            (non_negative(mid) ? hi : lo) = mid;
        }
    }

    result.lambda = float(hi);
    result.sh = applyWindow(sh, order, result.lambda);

    ShRgb change = result.sh;
    for (int i = 0; i < kMaxCoefficients; ++i) {
        change.rgb[i] -= sh.rgb[i];
    }
    const double energy = irradianceEnergy(sh, order);
    result.relativeChange =
        energy > 0.0 ? float(std::sqrt(irradianceEnergy(change, order) / energy)) : 0.0f;
    return result;
}

glm::vec3 fibonacciDirection(int i, int n) {
    assert(n > 0 && i >= 0 && i < n);
    // Double: i * golden angle grows with i, and float would lose the angle for large sets.
    constexpr double kGoldenAngle = 2.39996322972865332; // pi * (3 - sqrt(5))
    const double y = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    const double phi = i * kGoldenAngle;
    return glm::vec3(float(r * std::cos(phi)), float(y), float(r * std::sin(phi)));
}

} // namespace probekit::sh
