// probekit::baker — small sampling helpers shared by the integrators (path reference, VPL).
//
// Header-only and allocation-free. Directions are world-space unit vectors; the maps take
// uniforms in [0, 1)^2 (rng.hpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace probekit::baker {

constexpr float kInvPi = std::numbers::inv_pi_v<float>;
constexpr float kTwoPi = 2.0f * std::numbers::pi_v<float>;
constexpr float kFourPi = 4.0f * std::numbers::pi_v<float>;

// Veach's power heuristic (beta = 2), pdf^2 / (pdf^2 + other^2), written so that huge pdfs (a
// grazing emitter) give 1 or 0 instead of inf / inf. Precondition: pdf > 0.
inline float powerHeuristic(float pdf, float other_pdf) {
    const float ratio = other_pdf / pdf;
    return 1.0f / (1.0f + ratio * ratio);
}

inline float maxComponent(glm::vec3 v) {
    return std::max(v.x, std::max(v.y, v.z));
}

inline bool isBlack(glm::vec3 v) {
    return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f;
}

// Rec. 709 luminance: the weight that matches how bright a light looks, used only to shape
// sampling densities and error measures (never to change an estimator's expectation).
inline double luminance(glm::vec3 c) {
    return 0.2126 * double(c.x) + 0.7152 * double(c.y) + 0.0722 * double(c.z);
}

// Equal-area map of the unit square onto the sphere: z = 1 - 2u, phi = 2 pi v.
inline glm::vec3 sphereDirection(glm::vec2 u) {
    const float z = 1.0f - 2.0f * u.x;
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = kTwoPi * u.y;
    return glm::vec3(r * std::cos(phi), r * std::sin(phi), z);
}

// Orthonormal basis (tangent, bitangent) completing unit `n`: the branchless construction of
// Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017).
inline void orthonormalBasis(glm::vec3 n, glm::vec3& tangent, glm::vec3& bitangent) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    tangent = glm::vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    bitangent = glm::vec3(b, sign + n.y * n.y * a, -n.y);
}

// Cosine-weighted direction about unit `n` (pdf cos / pi).
inline glm::vec3 cosineDirection(glm::vec3 n, glm::vec2 u) {
    glm::vec3 tangent, bitangent;
    orthonormalBasis(n, tangent, bitangent);
    const float r = std::sqrt(u.x);
    const float phi = kTwoPi * u.y;
    // 1 - u.x >= 2^-24, so the direction is never tangent to the surface.
    const float z = std::sqrt(1.0f - u.x);
    return glm::normalize(r * std::cos(phi) * tangent + r * std::sin(phi) * bitangent + z * n);
}

} // namespace probekit::baker
