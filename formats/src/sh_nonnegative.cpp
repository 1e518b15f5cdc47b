// The non-negative projection of SH irradiance (sh.hpp, projectNonNegative).
#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>

#include "probekit/formats/sh.hpp"

namespace probekit::sh {

namespace {

using Vec9 = std::array<double, kMaxCoefficients>;

constexpr int kSeedNormals = 256;    // spherical-Fibonacci seeds of the minimum search
constexpr int kRefinedSeeds = 4;     // the lowest seeds refined by projected gradient descent
constexpr int kDescentSteps = 40;
constexpr int kMaxActive = 24;       // constraint points of the projection
constexpr int kDualSweeps = 400;     // coordinate-descent sweeps of the dual problem

Vec9 basis(glm::dvec3 n, int count) {
    const double x = n.x, y = n.y, z = n.z;
    Vec9 b{double(kY00), double(kY1) * y, double(kY1) * z, double(kY1) * x,
           double(kY2) * x * y, double(kY2) * y * z, double(kY20) * (3.0 * z * z - 1.0),
           double(kY2) * x * z, double(kY22) * (x * x - y * y)};
    for (int i = count; i < kMaxCoefficients; ++i) {
        b[size_t(i)] = 0.0;
    }
    return b;
}

double dot9(const Vec9& a, const Vec9& b) {
    double s = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
        s += a[i] * b[i];
    }
    return s;
}

// E(n) = sum e_i Y_i(n) and its gradient in R^3 (the basis as polynomials in x, y, z).
double value(const Vec9& e, glm::dvec3 n) {
    return dot9(e, basis(n, kMaxCoefficients));
}
glm::dvec3 gradient(const Vec9& e, glm::dvec3 n) {
    const double k1 = kY1, k2 = kY2, k20 = kY20, k22 = kY22;
    return {e[3] * k1 + e[4] * k2 * n.y + e[7] * k2 * n.z + e[8] * k22 * 2.0 * n.x,
            e[1] * k1 + e[4] * k2 * n.x + e[5] * k2 * n.z - e[8] * k22 * 2.0 * n.y,
            e[2] * k1 + e[5] * k2 * n.y + e[6] * k20 * 6.0 * n.z + e[7] * k2 * n.x};
}

// Projected gradient descent on the unit sphere from `n`, with backtracking.
glm::dvec3 descend(const Vec9& e, glm::dvec3 n, double& best) {
    best = value(e, n);
    double step = 0.5;
    for (int s = 0; s < kDescentSteps && step > 1e-9; ++s) {
        const glm::dvec3 g = gradient(e, n);
        const glm::dvec3 tangent = g - glm::dot(g, n) * n;
        const double length = glm::length(tangent);
        if (!(length > 1e-300)) {
            break;
        }
        const glm::dvec3 candidate = glm::normalize(n - (step / length) * tangent);
        const double v = value(e, candidate);
        if (v < best) {
            best = v;
            n = candidate;
            step *= 1.5;
        } else {
            step *= 0.5;
        }
    }
    return n;
}

} // namespace

namespace {

double minIrradianceOverSphere(const Vec9& e, glm::dvec3& at) {
    std::array<std::pair<double, int>, kSeedNormals> seeds;
    for (int i = 0; i < kSeedNormals; ++i) {
        seeds[size_t(i)] = {value(e, glm::dvec3(fibonacciDirection(i, kSeedNormals))), i};
    }
    std::partial_sort(seeds.begin(), seeds.begin() + kRefinedSeeds, seeds.end());
    double best = seeds[0].first;
    at = glm::dvec3(fibonacciDirection(seeds[0].second, kSeedNormals));
    for (int k = 0; k < kRefinedSeeds; ++k) {
        double v = 0.0;
        const glm::dvec3 n =
            descend(e, glm::dvec3(fibonacciDirection(seeds[size_t(k)].second, kSeedNormals)), v);
        if (v < best) {
            best = v;
            at = n;
        }
    }
    return best;
}

} // namespace

NonNegativeResult projectNonNegative(const ShRgb& sh, Order order, float relative_margin) {
    NonNegativeResult result;
    result.sh = sh;
    const int count = coefficientCount(order);
    double change_energy = 0.0, energy = 0.0;
    for (int c = 0; c < 3; ++c) {
        // Irradiance coefficients e_i = A_l c_i: E(n) = sum e_i Y_i(n), and the L2 norm of E
        // over the sphere is the Euclidean norm of e (orthonormal basis).
        Vec9 e{};
        for (int i = 0; i < count; ++i) {
            e[size_t(i)] = double(kCosineLobe[size_t(bandOf(i))]) * double(sh.rgb[i][c]);
        }
        energy += dot9(e, e);
        const double margin =
            double(relative_margin) * std::max(0.0, e[0] * double(kY00)); // x the mean E
        glm::dvec3 at;
        double minimum = minIrradianceOverSphere(e, at);
        result.minIrradiance = std::min(result.minIrradiance, float(std::min(minimum, 0.0)));
        if (minimum >= margin) {
            continue;
        }
        // Active-set loop: minimise |e' - e|^2 subject to E'(n_k) >= margin at the points found
        // so far (its dual, a non-negative least-squares problem in lambda, solved by coordinate
        // descent: e' = e + sum lambda_k Y(n_k)), then look for the lowest point of E' again.
        std::vector<Vec9> active;
        Vec9 projected = e;
        for (int round = 0; round < kMaxActive && minimum < margin; ++round) {
            active.push_back(basis(at, count));
            const size_t k = active.size();
            std::vector<double> gram(k * k), lambda(k, 0.0), rhs(k);
            for (size_t a = 0; a < k; ++a) {
                rhs[a] = margin - dot9(active[a], e);
                for (size_t b = 0; b < k; ++b) {
                    gram[a * k + b] = dot9(active[a], active[b]);
                }
            }
            for (int sweep = 0; sweep < kDualSweeps; ++sweep) {
                for (size_t a = 0; a < k; ++a) {
                    double g = rhs[a];
                    for (size_t b = 0; b < k; ++b) {
                        g -= gram[a * k + b] * lambda[b];
                    }
                    lambda[a] = std::max(0.0, lambda[a] + g / gram[a * k + a]);
                }
            }
            projected = e;
            for (size_t a = 0; a < k; ++a) {
                for (size_t i = 0; i < projected.size(); ++i) {
                    projected[i] += lambda[a] * active[a][i];
                }
            }
            minimum = minIrradianceOverSphere(projected, at);
        }
        if (minimum < margin) {
            // Not reached within kMaxActive points: lift the constant band by what is missing,
            // which keeps every direction at or above the margin.
            projected[0] += (margin - minimum) / double(kY00);
        }
        for (int i = 0; i < count; ++i) {
            const double d = projected[size_t(i)] - e[size_t(i)];
            change_energy += d * d;
            result.sh.rgb[i][c] = float(projected[size_t(i)] / double(kCosineLobe[size_t(bandOf(i))]));
        }
        result.changed = true;
    }
    result.relativeChange = energy > 0.0 ? float(std::sqrt(change_energy / energy)) : 0.0f;
    return result;
}

} // namespace probekit::sh
