// The error measure shared by bricked refinement (bricked.cpp) and --target-error / --verify
// (target.cpp): irradiance at the six axis normals, all three channels.
#pragma once

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

} // namespace probekit::baker
