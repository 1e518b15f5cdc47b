// probekit::sh — see sh.hpp for the convention (Ramamoorthi-Hanrahan 2001 ordering and
// constants, no Condon-Shortley phase, glTF axes) and the deringing window (Sloan 2017).
#include "probekit/formats/sh.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <limits>

#include <Imath/half.h>

#include <glm/geometric.hpp>

namespace probekit::sh {

namespace {

// Loose enough for directions normalised in float and passed through a few transforms.
constexpr float kUnitLengthTolerance = 1e-3f;

// Largest finite binary16 value (volume.hpp's kHalfMax).
constexpr float kHalfLargest = 65504.0f;

[[maybe_unused]] bool isUnit(glm::vec3 dir) {
    return std::abs(glm::dot(dir, dir) - 1.0f) < kUnitLengthTolerance;
}

double windowScale(int band, double lambda) {
    const double l = band;
    return 1.0 / (1.0 + lambda * l * l * (l + 1.0) * (l + 1.0));
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

// ---- The exact minimum over the sphere (sh.hpp, minimumIrradiance) ----

// One channel's E on the unit sphere as e0 + b.n + n^T M n, with M = V diag(d) V^T, d
// ascending, and beta = V^T b: the form every minimisation below works in. The window scales b
// by s1 and M by s2, which leaves V alone, so one decomposition serves every window.
struct ChannelForm {
    double e0 = 0.0;                          // mean irradiance, pi Y00 L00
    std::array<double, 3> d{};                // eigenvalues of M, ascending (sum 0: M is traceless)
    std::array<double, 3> beta{};             // band 1 in M's eigenbasis
    std::array<std::array<double, 3>, 3> v{}; // v[i] = eigenvector i (world x, y, z)
    double w1 = 0.0; // |E_1|^2 and |E_2|^2 (sum of squared SH coefficients of E)
    double w2 = 0.0;
};

using Mat3 = std::array<std::array<double, 3>, 3>;

// Cyclic Jacobi on a symmetric 3x3 matrix (double): a <- diagonal, v columns <- eigenvectors.
// Each rotation zeroes one off-diagonal pair (Numerical Recipes' stable form of the angle);
// convergence is quadratic, and the loop ends once the off-diagonal part is below 1e-36 of
// the matrix's squared norm or is exactly zero.
void jacobiEigen(Mat3& a, Mat3& v) {
    v = Mat3{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    double norm2 = 0.0;
    for (const auto& row : a) {
        for (double x : row) {
            norm2 += x * x;
        }
    }
    constexpr int kMaxSweeps = 64;
    constexpr std::array<std::array<int, 2>, 3> kPairs = {{{0, 1}, {0, 2}, {1, 2}}};
    for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
        const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        if (off == 0.0 || off <= 1e-36 * norm2) {
            break;
        }
        for (const auto& pq : kPairs) {
            const int p = pq[0];
            const int q = pq[1];
            if (a[p][q] == 0.0) {
                continue;
            }
            const double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            const double t =
                (theta >= 0.0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
            const double c = 1.0 / std::sqrt(t * t + 1.0);
            const double s = t * c;
            // a <- G^T a G with G = I but G_pp = G_qq = c, G_pq = s, G_qp = -s.
            for (int k = 0; k < 3; ++k) {
                const double akp = a[k][p];
                const double akq = a[k][q];
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for (int k = 0; k < 3; ++k) {
                const double apk = a[p][k];
                const double aqk = a[q][k];
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            a[p][q] = 0.0;
            a[q][p] = 0.0;
            for (int k = 0; k < 3; ++k) {
                const double vkp = v[k][p];
                const double vkq = v[k][q];
                v[k][p] = c * vkp - s * vkq;
                v[k][q] = s * vkp + c * vkq;
            }
        }
    }
}

ChannelForm channelForm(const ShRgb& sh, Order order, int channel) {
    const auto l = [&](int i) { return double(sh.rgb[i][channel]); };
    const double a0 = kCosineLobe[0];
    const double a1 = kCosineLobe[1];
    const double a2 = kCosineLobe[2];
    ChannelForm f;
    f.e0 = a0 * double(kY00) * l(0);
    // Band 1: A1 kY1 (L1-1 y + L10 z + L11 x).
    const std::array<double, 3> b = {a1 * double(kY1) * l(3), a1 * double(kY1) * l(1),
                                     a1 * double(kY1) * l(2)};
    f.w1 = 0.0;
    for (int i = 1; i < 4; ++i) {
        f.w1 += a1 * a1 * l(i) * l(i);
    }
    Mat3 m{};
    if (order == Order::L2) {
        // Band 2 on the sphere (x^2 + y^2 + z^2 = 1 folds Y20's -1 into a traceless form):
        // kY2 (L2-2 xy + L2-1 yz + L21 xz) + kY20 L20 (2z^2 - x^2 - y^2) + kY22 L22 (x^2 - y^2).
        const double y2 = double(kY2) * 0.5;
        const double y20 = double(kY20) * l(6);
        const double y22 = double(kY22) * l(8);
        m = Mat3{{{a2 * (-y20 + y22), a2 * y2 * l(4), a2 * y2 * l(7)},
                  {a2 * y2 * l(4), a2 * (-y20 - y22), a2 * y2 * l(5)},
                  {a2 * y2 * l(7), a2 * y2 * l(5), a2 * 2.0 * y20}}};
        for (int i = 4; i < 9; ++i) {
            f.w2 += a2 * a2 * l(i) * l(i);
        }
    }
    Mat3 v{};
    jacobiEigen(m, v);
    std::array<int, 3> idx = {0, 1, 2};
    std::sort(idx.begin(), idx.end(), [&](int i, int j) { return m[i][i] < m[j][j]; });
    for (int k = 0; k < 3; ++k) {
        const int i = idx[size_t(k)];
        f.d[size_t(k)] = m[i][i];
        for (int r = 0; r < 3; ++r) {
            f.v[size_t(k)][size_t(r)] = v[r][i];
        }
        f.beta[size_t(k)] =
            f.v[size_t(k)][0] * b[0] + f.v[size_t(k)][1] * b[1] + f.v[size_t(k)][2] * b[2];
    }
    return f;
}

struct SphereMin {
    double value = 0.0;        // lower bound of min over |n| = 1 of n^T D n + g.n
    std::array<double, 3> n{}; // unit point (eigenbasis) where the value is (nearly) taken
};

// |n(t)|^2 with n_i(t) = -g_i / (2 (d_i - d_0 + t)), and its derivative in t when asked.
double sphereNorm2(const std::array<double, 3>& d, const std::array<double, 3>& g, double t,
                   double* derivative) {
    double sum = 0.0;
    double dsum = 0.0;
    for (int i = 0; i < 3; ++i) {
        const double gap = d[size_t(i)] - d[0] + t;
        const double ni2 = g[size_t(i)] * g[size_t(i)] / (4.0 * gap * gap);
        sum += ni2;
        dsum -= 2.0 * ni2 / gap;
    }
    if (derivative != nullptr) {
        *derivative = dsum;
    }
    return sum;
}

// The dual q(t) = d_0 - t - sum_i g_i^2 / (4 (d_i - d_0 + t)).
double sphereDual(const std::array<double, 3>& d, const std::array<double, 3>& g, double at) {
    double value = d[0] - at;
    for (int i = 0; i < 3; ++i) {
        value -= g[size_t(i)] * g[size_t(i)] / (4.0 * (d[size_t(i)] - d[0] + at));
    }
    return value;
}

// The dual's maximiser t >= t_min (|n(t)| = 1, or t_min in the hard case); g is not zero.
double sphereDualRoot(const std::array<double, 3>& d, const std::array<double, 3>& g,
                      double gnorm) {
    // |n| <= 1 at t = |g| / 2 (each |n_i| <= |g_i| / |g|). Below t_min, t is rounding next to
    // the matrix's entries: if |n| <= 1 even there, the maximiser is the limit t -> 0 (the hard
    // case: the minimum is a ring or a point on the lowest eigenvector) and t_min is within
    // ~1e-17 of it in value.
    const double scale = std::max({std::abs(d[0]), std::abs(d[2]), gnorm});
    const double t_min = 1e-17 * scale;
    double t_hi = std::max(0.5 * gnorm, t_min); // |n| <= 1
    if (!(sphereNorm2(d, g, t_min, nullptr) > 1.0)) {
        return t_min; // |n| <= 1 (or NaN) already at t_min: the hard case
    }
    double t_lo = t_min; // |n| > 1
    double t = t_hi;
    // Newton on 1 / |n(t)| = 1 (nearly linear in t: Moré and Sorensen's secular equation),
    // safeguarded by the bracket; geometric bisection while the bracket spans decades.
    constexpr int kMaxSteps = 200;
    for (int step = 0; step < kMaxSteps; ++step) {
        double dsum = 0.0;
        const double sum = sphereNorm2(d, g, t, &dsum);
        (sum > 1.0 ? t_lo : t_hi) = t;
        if (std::abs(sum - 1.0) <= 4e-16) {
            break;
        }
        const double norm = std::sqrt(sum);
        const double psi = 1.0 / norm - 1.0;
        const double dpsi = -dsum / (2.0 * sum * norm);
        double next = dpsi != 0.0 ? t - psi / dpsi : 0.0;
        if (!(next > t_lo && next < t_hi)) {
            next = t_hi > 4.0 * t_lo ? std::sqrt(t_lo * t_hi) : 0.5 * (t_lo + t_hi);
        }
        if (!(next > t_lo && next < t_hi)) {
            break; // the bracket is two adjacent doubles
        }
        t = next;
    }
    // The better of the last iterate and the last point with |n| <= 1.
    return sphereDual(d, g, t_hi) > sphereDual(d, g, t) ? t_hi : t;
}

// The dual value at t and the unit primal point n(t) that goes with it.
SphereMin spherePointAt(const std::array<double, 3>& d, const std::array<double, 3>& g, double t) {
    SphereMin out;
    // The dual value at any t > 0 is a lower bound of the minimum (weak duality).
    double value = d[0] - t;
    double sum_n2 = 0.0;
    for (int i = 0; i < 3; ++i) {
        const double gap = d[size_t(i)] - d[0] + t;
        value -= g[size_t(i)] * g[size_t(i)] / (4.0 * gap);
        out.n[size_t(i)] = -g[size_t(i)] / (2.0 * gap);
        sum_n2 += out.n[size_t(i)] * out.n[size_t(i)];
    }
    out.value = value;
    // The primal point n(t), |n| = 1 to rounding at the root; short of it (the hard case) the
    // rest goes along the lowest eigenvector.
    if (sum_n2 > 1.0) {
        const double inv = 1.0 / std::sqrt(sum_n2);
        for (double& x : out.n) {
            x *= inv;
        }
    } else {
        const double rest = std::sqrt(std::max(0.0, 1.0 - (sum_n2 - out.n[0] * out.n[0])));
        out.n[0] = out.n[0] < 0.0 ? -rest : rest;
    }
    return out;
}

// min over |n| = 1 of sum_i d_i n_i^2 + g_i n_i, d ascending, through the dual (sh.hpp), in
// t = d_0 - mu > 0: the dual is q(t) = d_0 - t - sum_i g_i^2 / (4 (d_i - d_0 + t)), and
// q'(t) = |n(t)|^2 - 1 with n_i(t) = -g_i / (2 (d_i - d_0 + t)), |n(t)| decreasing in t.
SphereMin minimiseOnSphere(const std::array<double, 3>& d, const std::array<double, 3>& g) {
    const double gnorm = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (gnorm == 0.0) {
        SphereMin out;
        out.value = d[0];
        out.n = {1.0, 0.0, 0.0};
        return out;
    }
    return spherePointAt(d, g, sphereDualRoot(d, g, gnorm));
}

// Exact minimum of E for the channel with band 1 scaled by s1 and band 2 by s2, and its
// derivative in s1 (envelope theorem: band 1 of E at the minimising normal, b.n).
struct WindowedMin {
    double value = 0.0;
    double slope1 = 0.0;
};
WindowedMin windowedMinimum(const ChannelForm& f, double s1, double s2) {
    const std::array<double, 3> d = {s2 * f.d[0], s2 * f.d[1], s2 * f.d[2]};
    const std::array<double, 3> g = {s1 * f.beta[0], s1 * f.beta[1], s1 * f.beta[2]};
    const SphereMin m = minimiseOnSphere(d, g);
    return {f.e0 + m.value, f.beta[0] * m.n[0] + f.beta[1] * m.n[1] + f.beta[2] * m.n[2]};
}

struct BandScales {
    double s1 = 1.0;
    double s2 = 1.0;
};

// The largest s1 in [0, 1] with min E >= target at this s2 (s1 = 0 must be feasible). min E is
// concave and even in s1, so feasibility is an interval around 0. Newton from s1 = 1 (outside
// it) on the concave min E stays outside and falls monotonically to the interval's end (the
// slope is the envelope derivative); the bracket [feasible, infeasible] falls back to
// bisection. Stops within 1e-12 of the mean of the target, on either side: the callers' target
// sits well above what they accept.
double largestBandOne(const ChannelForm& f, double s2, double target) {
    WindowedMin at = windowedMinimum(f, 1.0, s2);
    if (at.value >= target) {
        return 1.0;
    }
    double lo = 0.0; // feasible
    double hi = 1.0; // infeasible
    double s1 = 1.0;
    const double tolerance = 1e-12 * std::abs(f.e0);
    constexpr int kMaxSteps = 100;
    for (int step = 0; step < kMaxSteps; ++step) {
        double next = at.slope1 < 0.0 ? s1 - (at.value - target) / at.slope1 : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) {
            next = 0.5 * (lo + hi);
        }
        if (!(next > lo && next < hi)) {
            break;
        }
        s1 = next;
        at = windowedMinimum(f, s1, s2);
        (at.value >= target ? lo : hi) = s1;
        if (std::abs(at.value - target) <= tolerance) {
            return s1;
        }
    }
    return lo;
}

// The band window of least RMS change with min E >= target (target < e0), sh.hpp.
BandScales leastChangeWindow(const ChannelForm& f, Order order, double target) {
    BandScales best;
    const double slack = f.e0 - target; // > 0
    if (order == Order::L1) {
        // min E = e0 - s1 |b|.
        const double amplitude =
            std::sqrt(f.beta[0] * f.beta[0] + f.beta[1] * f.beta[1] + f.beta[2] * f.beta[2]);
        best.s1 = amplitude > slack ? slack / amplitude : 1.0;
        best.s2 = 1.0;
        return best;
    }
    // With s1 = 0, min E = e0 + s2 d_0 (d_0 <= 0): s2 may not exceed slack / -d_0. A hair less,
    // so that s1 = 0 stays feasible through rounding.
    double s2_max = 1.0;
    if (f.d[0] < 0.0 && slack < -f.d[0]) {
        s2_max = slack / -f.d[0] * (1.0 - 1e-12);
    }
    const auto cost = [&](double s2, double& s1) {
        s1 = largestBandOne(f, s2, target);
        return f.w1 * (1.0 - s1) * (1.0 - s1) + f.w2 * (1.0 - s2) * (1.0 - s2);
    };
    // Golden-section search: the cost is convex in s2 (the largest feasible s1 is a concave
    // function of s2, the upper edge of a convex set). 0.618^26 ~ 4e-6 of [0, s2_max]: the cost
    // is flat at its minimum, so it is then within ~1e-11 of it, relatively.
    const double kInvPhi = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = 0.0;
    double b = s2_max;
    double x1 = b - kInvPhi * (b - a);
    double x2 = a + kInvPhi * (b - a);
    double s1_1 = 0.0, s1_2 = 0.0;
    double c1 = cost(x1, s1_1);
    double c2 = cost(x2, s1_2);
    constexpr int kSteps = 26;
    for (int step = 0; step < kSteps; ++step) {
        if (c1 <= c2) {
            b = x2;
            x2 = x1;
            c2 = c1;
            s1_2 = s1_1;
            x1 = b - kInvPhi * (b - a);
            c1 = cost(x1, s1_1);
        } else {
            a = x1;
            x1 = x2;
            c1 = c2;
            s1_1 = s1_2;
            x2 = a + kInvPhi * (b - a);
            c2 = cost(x2, s1_2);
        }
    }
    // The upper end too: the optimum may sit on s2 = s2_max (e.g. s2_max = 1 and s1 = 1 there).
    double s1_end = 0.0;
    const double c_end = cost(s2_max, s1_end);
    if (c1 <= c2 && c1 <= c_end) {
        best = {s1_1, x1};
    } else if (c2 <= c_end) {
        best = {s1_2, x2};
    } else {
        best = {s1_end, s2_max};
    }
    return best;
}

// Largest |Y_i(n)| over the sphere per coefficient (sh.hpp's basis): a rounding bound below.
constexpr std::array<double, kMaxCoefficients> kBasisPeak = {
    double(kY00),      double(kY1),        double(kY1),       double(kY1), double(kY2) * 0.5,
    double(kY2) * 0.5, double(kY20) * 2.0, double(kY2) * 0.5, double(kY22)};

float roundValue(float x, Rounding rounding) {
    return rounding == Rounding::Float16 ? float(Imath::half(x)) : x;
}

bool storable(const ShRgb& sh, Order order, Rounding rounding) {
    for (int i = 0; i < coefficientCount(order); ++i) {
        for (int c = 0; c < 3; ++c) {
            const float x = sh.rgb[i][c];
            if (!std::isfinite(x) ||
                (rounding == Rounding::Float16 && std::abs(x) > kHalfLargest)) {
                return false;
            }
        }
    }
    return true;
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

IrradianceMinimum minimumIrradiance(const ShRgb& sh, Order order, int channel) {
    assert(channel >= 0 && channel < 3);
    const ChannelForm f = channelForm(sh, order, channel);
    const SphereMin m = minimiseOnSphere(f.d, f.beta);
    IrradianceMinimum out;
    out.value = f.e0 + m.value;
    glm::dvec3 n(0.0);
    for (int k = 0; k < 3; ++k) {
        n += m.n[size_t(k)] * glm::dvec3(f.v[size_t(k)][0], f.v[size_t(k)][1], f.v[size_t(k)][2]);
    }
    out.normal = glm::normalize(n);
    return out;
}

double meanIrradiance(const ShRgb& sh, int channel) {
    return double(kCosineLobe[0]) * double(kY00) * double(sh.rgb[0][channel]);
}

ShRgb roundTo(const ShRgb& sh, Rounding rounding) {
    if (rounding == Rounding::Float32) {
        return sh;
    }
    ShRgb out;
    for (int i = 0; i < kMaxCoefficients; ++i) {
        for (int c = 0; c < 3; ++c) {
            out.rgb[i][c] = roundValue(sh.rgb[i][c], rounding);
        }
    }
    return out;
}

ShRgb scaleBands(const ShRgb& sh, Order order, glm::vec3 band1, glm::vec3 band2) {
    ShRgb out = sh;
    for (int i = 1; i < coefficientCount(order); ++i) {
        out.rgb[i] *= bandOf(i) == 1 ? band1 : band2;
    }
    return out;
}

namespace {

// Zeroes channel c (mean <= 0 as stored: no window lifts it) unless it is all zeros already.
void zeroChannel(DeringResult& result, const ShRgb& stored, Order order, int c) {
    // A channel of zeros, E = 0, passes as it is.
    bool all_zero = true;
    for (int i = 0; i < coefficientCount(order); ++i) {
        all_zero = all_zero && stored.rgb[i][c] == 0.0f;
    }
    if (all_zero) {
        return;
    }
    result.changedChannels |= uint8_t(1u << c);
    result.zeroedChannels |= uint8_t(1u << c);
    for (int i = 0; i < kMaxCoefficients; ++i) {
        result.sh.rgb[i][c] = 0.0f;
    }
    result.band1Scale[c] = 0.0f;
    result.band2Scale[c] = order == Order::L2 ? 0.0f : 1.0f;
    result.minAfter[c] = 0.0;
}

// How far rounding channel c's windowed coefficients as stored can move its E.
double windowRoundingBound(const ShRgb& sh, Order order, int c, Rounding rounding) {
    // Per unit of sum A_l peak|Y| |L|: half an ulp relative (binary16: 2^-11, plus 2^-25
    // absolute below its normal range; float: 2^-24), and once more for the float product of
    // coefficient and scale.
    const double relative_rounding = rounding == Rounding::Float16 ? 0x1p-11 + 0x1p-24 : 0x1p-23;
    const double absolute_rounding = rounding == Rounding::Float16 ? 0x1p-25 : 0.0;
    double bound = 0.0;
    for (int i = 1; i < coefficientCount(order); ++i) {
        const double term = double(kCosineLobe[bandOf(i)]) * kBasisPeak[size_t(i)];
        bound += term * (relative_rounding * std::abs(double(sh.rgb[i][c])) + absolute_rounding);
    }
    return bound;
}

// Channel c's form as the window is solved on it: stored band 0 (the window leaves it alone)
// and the float bands 1..2.
ChannelForm deringForm(const ShRgb& sh, const ShRgb& stored, Order order, int c) {
    ShRgb channel = sh;
    for (int i = 0; i < kMaxCoefficients; ++i) {
        channel.rgb[i] = glm::vec3(i == 0 ? stored.rgb[0][c] : sh.rgb[i][c]);
    }
    return channelForm(channel, order, 0);
}

// Windows channel c, raising the target until its stored-rounded minimum clears the floor;
// false (result untouched) when no attempt does.
bool windowChannel(DeringResult& result, const ShRgb& sh, const ShRgb& stored, Order order,
                   Rounding rounding, int c, double mean) {
    const ChannelForm f = deringForm(sh, stored, order, c);
    const double rounding_bound = windowRoundingBound(sh, order, c, rounding);
    const double floor = kDeringMargin * mean;
    double target = std::min(2.0 * floor + rounding_bound, 0.5 * (floor + mean));
    const int count = coefficientCount(order);
    constexpr int kAttempts = 8; // each moves the target halfway to the mean
    for (int attempt = 0; attempt < kAttempts; ++attempt) {
        const BandScales w = leastChangeWindow(f, order, target);
        ShRgb windowed = result.sh;
        for (int i = 1; i < count; ++i) {
            const double scale = bandOf(i) == 1 ? w.s1 : w.s2;
            windowed.rgb[i][c] = roundValue(float(double(sh.rgb[i][c]) * scale), rounding);
        }
        windowed.rgb[0][c] = stored.rgb[0][c];
        const double min_after = minimumIrradiance(windowed, order, c).value;
        if (min_after >= floor) {
            result.sh = windowed;
            result.band1Scale[c] = float(w.s1);
            result.band2Scale[c] = order == Order::L2 ? float(w.s2) : 1.0f;
            result.minAfter[c] = min_after;
            return true;
        }
        target += 0.5 * (mean - target);
    }
    return false;
}

// The last resort for channel c: bands 1 and 2 zero, E = the mean everywhere.
void flattenChannel(DeringResult& result, const ShRgb& stored, Order order, int c, double mean) {
    for (int i = 1; i < kMaxCoefficients; ++i) {
        result.sh.rgb[i][c] = 0.0f;
    }
    result.sh.rgb[0][c] = stored.rgb[0][c];
    result.band1Scale[c] = 0.0f;
    result.band2Scale[c] = order == Order::L2 ? 0.0f : 1.0f;
    result.minAfter[c] = mean;
}

// Derings channel c of `result`: left alone when its minimum clears the margin, else zeroed,
// windowed or flattened.
void deringChannel(DeringResult& result, const ShRgb& sh, const ShRgb& stored, Order order,
                   Rounding rounding, int c) {
    const double mean = meanIrradiance(stored, c);
    const double min_before = minimumIrradiance(stored, order, c).value;
    result.minBefore[c] = min_before;
    result.minAfter[c] = min_before;
    if (mean > 0.0 && min_before >= kDeringMargin * mean) {
        return; // already non-negative with the margin: unchanged
    }
    if (!(mean > 0.0)) {
        zeroChannel(result, stored, order, c);
        return;
    }
    result.changedChannels |= uint8_t(1u << c);
    if (!windowChannel(result, sh, stored, order, rounding, c, mean)) {
        flattenChannel(result, stored, order, c, mean);
    }
}

// RMS change of E from `before` to `after` over the sphere, relative to the RMS of `before`'s.
float relativeIrradianceChange(const ShRgb& before, const ShRgb& after, Order order) {
    ShRgb change = after;
    for (int i = 0; i < kMaxCoefficients; ++i) {
        change.rgb[i] -= before.rgb[i];
    }
    const double energy = irradianceEnergy(before, order);
    return energy > 0.0 ? float(std::sqrt(irradianceEnergy(change, order) / energy)) : 0.0f;
}

} // namespace

DeringResult deringIrradiance(const ShRgb& sh, Order order, Rounding rounding) {
    DeringResult result;
    result.sh = sh;
    if (order == Order::L1) {
        result.band2Scale = glm::vec3(1.0f);
    }
    if (!storable(sh, order, rounding)) {
        return result; // makeVolume refuses it, naming the value
    }
    const ShRgb stored = roundTo(sh, rounding);
    for (int c = 0; c < 3; ++c) {
        deringChannel(result, sh, stored, order, rounding, c);
    }
    if (!result.changed()) {
        return result;
    }
    // The channels left alone keep their coefficients as they came; the changed ones are
    // stored-rounded already. Band 0 of a changed channel is its stored value.
    result.relativeChange = relativeIrradianceChange(sh, result.sh, order);
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
