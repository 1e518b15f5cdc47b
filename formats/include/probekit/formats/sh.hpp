// probekit::sh — real spherical harmonics up to band 2, the basis every .pvol file stores.
//
// Convention (fixed; see formats/CONVENTIONS.md, the one place it is written down):
//  * Real, orthonormal SH over the unit sphere: integral of Y_i * Y_j dw = delta_ij.
//  * Ramamoorthi-Hanrahan ordering and constants ("An Efficient Representation for Irradiance
//    Environment Maps", SIGGRAPH 2001), with x, y, z the glTF world axes (+Y up):
//        index 0  Y00  = 0.282095
//        index 1  Y1-1 = 0.488603 y
//        index 2  Y10  = 0.488603 z
//        index 3  Y11  = 0.488603 x
//        index 4  Y2-2 = 1.092548 xy
//        index 5  Y2-1 = 1.092548 yz
//        index 6  Y20  = 0.315392 (3z^2 - 1)
//        index 7  Y21  = 1.092548 xz
//        index 8  Y22  = 0.546274 (x^2 - y^2)
//    No Condon-Shortley phase: every coefficient above is positive.
//  * Files store *radiance* SH L_lm (W/(sr m^2) per RGB channel). Irradiance on a Lambertian
//    receiver with unit normal n is E(n) = sum_lm A_l L_lm Y_lm(n), A = (pi, 2pi/3, pi/4)
//    (Ramamoorthi-Hanrahan 2001, eq. 8), in W/m^2, not divided by pi.
//  * L1 = bands 0..1 (4 coefficients); L2 = bands 0..2 (9 coefficients).
//
// Every function here is pure, allocation-free and thread-safe. Directions must be unit
// vectors (checked with assert in debug builds).
#pragma once

#include <array>
#include <cstdint>

#include <glm/vec3.hpp>

namespace probekit::sh {

enum class Order : uint8_t {
    L1 = 1, // bands 0..1, 4 coefficients
    L2 = 2, // bands 0..2, 9 coefficients
};

constexpr int coefficientCount(Order order) {
    return order == Order::L1 ? 4 : 9;
}
constexpr int kMaxCoefficients = 9;

// Basis constants (Ramamoorthi-Hanrahan 2001, to 6 decimals as published).
constexpr float kY00 = 0.282095f; // 1 / (2 sqrt(pi))
constexpr float kY1 = 0.488603f;  // sqrt(3 / (4 pi))
constexpr float kY2 = 1.092548f;  // sqrt(15 / (4 pi)): Y2-2, Y2-1, Y21
constexpr float kY20 = 0.315392f; // sqrt(5 / (16 pi))
constexpr float kY22 = 0.546274f; // sqrt(15 / (16 pi))

constexpr float kPi = 3.14159265358979323846f;

// Clamped-cosine convolution constants A_l per band (Ramamoorthi-Hanrahan 2001, eq. 8):
// convolving radiance with max(0, n.w) scales band l by A_l, so E(n) = sum A_l L_lm Y_lm(n).
constexpr std::array<float, 3> kCosineLobe = {kPi, 2.0f * kPi / 3.0f, kPi / 4.0f};

// Band index l of coefficient index i (0 -> 0, 1..3 -> 1, 4..8 -> 2).
constexpr int bandOf(int index) {
    return index == 0 ? 0 : (index < 4 ? 1 : 2);
}

// Scalar SH coefficients (one channel). Unused entries of an L1 set are zero.
using Coeffs = std::array<float, kMaxCoefficients>;

// RGB SH coefficients: coefficient i of channel c is rgb[i][c]. Unused L1 entries are zero.
struct ShRgb {
    std::array<glm::vec3, kMaxCoefficients> rgb{};

    ShRgb& operator+=(const ShRgb& other);
    ShRgb& operator*=(float scale);
    friend bool operator==(const ShRgb&, const ShRgb&) = default;
};

// The nine basis functions at unit direction `dir`. For L1 use the first four.
Coeffs evalBasis(glm::vec3 dir);

// Adds one radiance sample's contribution: coefficients += radiance * Y(dir) * weight.
// With N uniformly distributed directions over the sphere, weight = 4 pi / N gives an unbiased
// Monte Carlo projection. Coefficients beyond `order` are left untouched.
void addSample(ShRgb& sh, Order order, glm::vec3 dir, glm::vec3 radiance, float weight);

// Exact projection of a directional delta: radiance L(w) = e * delta(w - dir), where `e` is the
// irradiance the source delivers to a surface facing it (W/m^2, e.g. a directional light of
// `e` lux, or a point light I / d^2). Coefficients are e * Y(dir).
ShRgb projectDelta(glm::vec3 dir, glm::vec3 irradiance, Order order);

// Radiance reconstructed from the coefficients in direction `dir` (band-limited).
glm::vec3 evalRadiance(const ShRgb& sh, Order order, glm::vec3 dir);

// Irradiance E(n) = sum_lm A_l L_lm Y_lm(n) in W/m^2 for unit normal n. The GLSL function
// pk_sh_irradiance in shaders/probe_volume.glsl mirrors this term for term.
glm::vec3 irradiance(const ShRgb& sh, Order order, glm::vec3 normal);

// Keeps bands 0..1 and zeroes band 2.
ShRgb truncateToL1(const ShRgb& sh);

// Deringing: SH truncation rings, and a strong light from one side yields negative irradiance
// on the opposite side. The window scales band l by 1 / (1 + lambda * l^2 (l + 1)^2), the
// minimum-roughness (Laplacian-penalised) fit of Sloan, "Deringing Spherical Harmonics"
// (SIGGRAPH Asia 2017). deringIrradiance finds the smallest lambda (bisection, to 1e-4
// relative) for which E(n) >= 0 on every channel over a dense set of test normals
// (`kDeringTestNormals` spherical-Fibonacci points) and applies it. Band 0 is never changed,
// so the mean irradiance over the sphere is preserved exactly.
constexpr int kDeringTestNormals = 512;

struct DeringResult {
    ShRgb sh;                 // windowed coefficients
    float lambda = 0.0f;      // window strength applied (0 when nothing was negative)
    float minIrradiance = 0;  // most negative E over the test normals before windowing (<= 0)
    float relativeChange = 0; // RMS change of E over the sphere / RMS of E: the stated cost
};
DeringResult deringIrradiance(const ShRgb& sh, Order order);

// Applies the window above with a given lambda (>= 0).
ShRgb applyWindow(const ShRgb& sh, Order order, float lambda);

// The closest SH (in the L2 norm of irradiance over the sphere) whose irradiance is non-negative
// for every unit normal: per channel, minimise |E' - E|^2 subject to E'(n) >= margin for all n,
// margin = relative_margin x the channel's mean irradiance over the sphere (pi Y00 L00, at least
// 0), so that float rounding of interpolation and storage cannot dip below zero. Solved by an
// active-set loop: the lowest point of E' over the sphere (256 spherical-Fibonacci seeds, the
// lowest 4 refined by projected gradient descent) is added as a constraint and the projection
// onto all constraints so far (a 9-dimensional quadratic programme, solved through its
// non-negative least-squares dual) is recomputed, until the lowest point meets the margin; if
// 24 points do not suffice, band 0 is raised by what is missing. A probe that already meets the
// margin is returned unchanged, bit for bit. Unlike a window, the change is confined to where
// E was negative and its surroundings, so the sides facing the light keep their contrast.
struct NonNegativeResult {
    ShRgb sh;
    bool changed = false;
    float minIrradiance = 0.0f;  // the lowest E over the sphere before, over channels (<= 0)
    float relativeChange = 0.0f; // |E' - E| / |E| over the sphere, three channels together
};
NonNegativeResult projectNonNegative(const ShRgb& sh, Order order, float relative_margin);

// Spherical-Fibonacci direction i of n (the point set reference.json uses):
// y = 1 - (2i + 1) / n, phi = i * pi * (3 - sqrt(5)), dir = (sqrt(1 - y^2) cos phi, y,
// sqrt(1 - y^2) sin phi).
glm::vec3 fibonacciDirection(int i, int n);

} // namespace probekit::sh
