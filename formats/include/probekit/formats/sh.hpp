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

// ---- Deringing ----
//
// SH truncation rings: a strong light from one side gives negative irradiance on the other (a
// lone delta light's L2 irradiance dips to -0.04 of its peak, its L1 irradiance to -1/3).
// Deringing scales band 1 and band 2 of each channel by factors s1, s2 in [0, 1] (a band
// window, as Sloan's "Deringing Spherical Harmonics", SIGGRAPH Asia 2017, whose
// 1 / (1 + lambda l^2 (l + 1)^2) is one curve through that square) so that the irradiance is
// non-negative on the whole sphere, and among those windows takes the one that changes E least
// in RMS over the sphere. Band 0 (the mean) is never changed. Because E - E_windowed lives in
// bands 1..2 and the truncation error in bands >= 3, that is also the window that adds the least
// RMS error against any true irradiance whose projection the probe holds. For a lone delta
// light (the worst case) it changes E by 0.106 RMS (L2: s1 = 0.858, s2 = 0.909; L1: s1 = 1/2,
// 0.378 RMS), where Sloan's smallest sufficient lambda changes the L2 irradiance by 0.419.

// The exact minimum of one channel's E over the unit sphere. On the sphere E is
// e0 + b.n + n^T M n (band 0 a constant, band 1 linear, band 2 a traceless quadratic form;
// L1: M = 0), and its minimum is that of the trust-region problem min n^T M n + b.n, |n| = 1,
// solved through its Lagrangian dual (strong duality holds for one quadratic constraint):
// max over mu < d_min of mu - sum_i beta_i^2 / (4 (d_i - mu)), with M = V diag(d) V^T (cyclic
// Jacobi, double) and beta = V^T b. The dual is concave and its maximiser solves the secular
// equation sum_i beta_i^2 / (4 (d_i - mu)^2) = 1 in [d_min - |b| / 2, d_min]: Newton on
// 1 / |n(mu)| = 1 (Moré and Sorensen), safeguarded by that bracket with geometric bisection, to
// double resolution. The "hard case" (beta_min = 0: the ring-shaped minimum of an axially
// symmetric lobe, a lone light's) is the limit mu -> d_min, taken when |n| <= 1 still holds
// 1e-17 of the matrix's scale from d_min. `value` is the dual value at the mu found: by weak
// duality a lower bound of the minimum for any mu < d_min, so never above the true minimum but
// by rounding (~1e-16 of the terms), and below it by as little (tested against 200001 normals).
// `normal` is the primal point it gives (unit length), where E takes that value up to the same
// rounding. Coefficients are taken as double; the basis constants are the float ones
// sh::irradiance uses.
struct IrradianceMinimum {
    double value = 0.0;         // W/m^2
    glm::dvec3 normal{0, 1, 0}; // a unit normal where E takes (within rounding) that value
};
IrradianceMinimum minimumIrradiance(const ShRgb& sh, Order order, int channel);

// Mean irradiance over the sphere of one channel, pi * kY00 * L00 (W/m^2).
double meanIrradiance(const ShRgb& sh, int channel);

// What deringing guarantees, per channel: the minimum of E over the sphere (as above, of the
// coefficients as stored) is at least kDeringMargin x the channel's mean irradiance. The margin
// keeps the float rounding of evaluating and interpolating stored probes (a few 1e-7 of the
// mean: the coefficients of a non-negative E are bounded by a small multiple of its mean) from
// reaching below zero, and costs nothing visible (1e-4 of the mean). Interpolation with
// non-negative weights keeps the guarantee: E and the mean are both linear in the
// coefficients.
constexpr double kDeringMargin = 1e-4;

// The storage the coefficients go to: deringing checks them after its rounding.
enum class Rounding : uint8_t {
    Float32, // the floats as they are
    Float16, // IEEE binary16, round-to-nearest-even, as makeVolume stores half texels
};

// The coefficients as stored with `rounding` and read back (Float32: unchanged). Values beyond
// the half range become infinite (makeVolume refuses them).
ShRgb roundTo(const ShRgb& sh, Rounding rounding);

struct DeringResult {
    ShRgb sh;                    // deringed coefficients (rounded as stored where changed)
    glm::vec3 band1Scale{1.0f};  // s1 per channel (1 where nothing changed)
    glm::vec3 band2Scale{1.0f};  // s2 per channel (L2 only; 1 for L1)
    glm::dvec3 minBefore{0.0};   // exact minimum of E per channel before, as stored
    glm::dvec3 minAfter{0.0};    // and after (>= kDeringMargin x the channel's mean)
    uint8_t changedChannels = 0; // bit c: channel c was windowed or zeroed
    uint8_t zeroedChannels = 0;  // bit c: channel c's mean <= 0 as stored: all zero now
    float relativeChange = 0.0f; // RMS change of E over the sphere / RMS of E (all channels)
    bool changed() const { return changedChannels != 0; }
};

// Deringing of one probe. Each channel is checked on the coefficients rounded as stored: when
// its exact minimum is at least kDeringMargin x its mean it is left as it is, bit for bit
// (a probe whose every channel passes comes back identical). Otherwise:
//  * mean <= 0 as stored (a probe of zeros, or a negative mean from noise): no window helps,
//    and the channel becomes zero (E = 0), band 0 included;
//  * else (s1, s2) minimise (1 - s1)^2 |E_1|^2 + (1 - s2)^2 |E_2|^2 (the squared RMS change)
//    subject to min E >= a target a little above the margin: a convex problem (E is linear in
//    (s1, s2), so the feasible set is convex; it is symmetric in s1, as band 1 is odd and band 2
//    even). For each s2 the largest feasible s1 is found by bisection on the exact minimum
//    above, and the best s2 by golden-section search over [0, the largest s2 with s1 = 0
//    feasible]; L1 has the closed form s1 = (mean - target) / |E_1 amplitude|. The windowed
//    coefficients are rounded as stored and checked again; if the rounding took the minimum
//    below the margin the target is raised and the window solved again, and as the last resort
//    bands 1 and 2 of the channel are zeroed (E = its mean, which always passes).
// Non-finite coefficients, or Float16 ones beyond the half range, are returned unchanged
// (makeVolume refuses them with a message). Deterministic: pure double arithmetic.
DeringResult deringIrradiance(const ShRgb& sh, Order order, Rounding rounding = Rounding::Float32);

// Scales band 1 of channel c by band1[c] and band 2 by band2[c] (each in [0, 1]).
ShRgb scaleBands(const ShRgb& sh, Order order, glm::vec3 band1, glm::vec3 band2);

// Sloan's window: scales band l by 1 / (1 + lambda l^2 (l + 1)^2) (lambda >= 0) on every channel.
ShRgb applyWindow(const ShRgb& sh, Order order, float lambda);

// Spherical-Fibonacci direction i of n (the point set reference.json uses):
// y = 1 - (2i + 1) / n, phi = i * pi * (3 - sqrt(5)), dir = (sqrt(1 - y^2) cos phi, y,
// sqrt(1 - y^2) sin phi).
glm::vec3 fibonacciDirection(int i, int n);

} // namespace probekit::sh
