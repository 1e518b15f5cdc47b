// The error measure shared by bricked refinement (bricked.cpp) and --target-error / --verify
// (target.cpp): irradiance at the six axis normals, all three channels.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "probekit/formats/sh.hpp"

namespace probekit::baker {

inline constexpr glm::vec3 kAxisNormals[6] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                              {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};

// Sum over the six axis normals and the three channels of E(n)^2 for radiance SH `radiance`.
inline double squaredAxisIrradiance(const sh::ShRgb& radiance, sh::Order order) {
    double sum = 0.0;
    for (const glm::vec3& n : kAxisNormals) {
        const glm::vec3 e = sh::irradiance(radiance, order, n);
        sum += double(glm::dot(e, e));
    }
    return sum;
}

// The same for the difference a - b.
inline double squaredAxisIrradianceDifference(const sh::ShRgb& a, const sh::ShRgb& b,
                                              sh::Order order) {
    sh::ShRgb d = b;
    d *= -1.0f;
    d += a;
    return squaredAxisIrradiance(d, order);
}

// The bounded error measure (--verify, --target-error's prediction, the bricked prediction).
// A relative RMS error weights each point by its squared irradiance, and near a point light
// irradiance grows as 1/r^2, whose square has no finite mean over a volume: one or two points
// close to lights would carry all of it, and a figure over a few hundred points would be
// theirs. So a point whose squared irradiance is above kBrightPointCap^2 times the median
// point's counts as if it were that bright, with its own relative error: its terms are scaled
// by brightPointWeight. Below the cap the measure is the plain relative RMS error.
inline constexpr double kBrightPointCap = 4.0;

// The cap for these per-point squared irradiances: kBrightPointCap^2 times the median of
// those above 0 (unlit points carry no weight either way); infinity when none is.
inline double brightPointCap(std::vector<double> squares) {
    squares.erase(
        std::remove_if(squares.begin(), squares.end(), [](double v) { return !(v > 0.0); }),
        squares.end());
    if (squares.empty()) {
        return INFINITY;
    }
    const auto middle = squares.begin() + std::ptrdiff_t(squares.size() / 2);
    std::nth_element(squares.begin(), middle, squares.end());
    return kBrightPointCap * kBrightPointCap * *middle;
}

// The weight of a point of squared irradiance `square` under `cap`: 1 up to the cap, then
// cap / square, so the point's weighted squared irradiance is the cap's.
inline double brightPointWeight(double square, double cap) {
    return square > cap ? cap / square : 1.0;
}

} // namespace probekit::baker
