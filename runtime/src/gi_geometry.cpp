#include "gi_geometry.hpp"

#include <algorithm>
#include <cmath>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "probekit/formats/sh.hpp"
#include "probekit/formats/triangle_sampling.hpp"

namespace probekit::runtime {
namespace {

// Coefficients of the geometry cell's blocking: Y00 and band 2 (sh.hpp order 0, 4..8).
constexpr std::array<int, 6> kBlockingCoefficients = {0, 4, 5, 6, 7, 8};

// Funk-Hecke: the SH of (n.w)^2 are lambda_l Y_lm(n), lambda = (4 pi / 3, 0, 8 pi / 15).
constexpr float kLambda0 = 4.0f / 3.0f * sh::kPi;
constexpr float kLambda2 = 8.0f / 15.0f * sh::kPi;

// Rounded in float as the shader does (floor(v x 2^16 + 0.5)).
int32_t fixedPoint(float value) {
    return int32_t(std::floor(value * kGiFixedScale + 0.5f));
}

constexpr std::array<glm::ivec3, 6> kDirections = {glm::ivec3(1, 0, 0), glm::ivec3(-1, 0, 0),
                                                   glm::ivec3(0, 1, 0), glm::ivec3(0, -1, 0),
                                                   glm::ivec3(0, 0, 1), glm::ivec3(0, 0, -1)};

} // namespace

glm::vec3 giCanonicalNormal(glm::vec3 n) {
    const glm::vec3 a = glm::abs(n);
    const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    return n[axis] < 0.0f ? -n : n;
}

float giCellPotential(const GiGeometryCell& cell, glm::vec3 w) {
    const sh::Coeffs y = sh::evalBasis(w);
    float potential = 0.0f;
    for (size_t k = 0; k < kBlockingCoefficients.size(); ++k) {
        potential += float(cell.blocking[k]) / kGiFixedScale * y[kBlockingCoefficients[k]];
    }
    return potential;
}

std::vector<GiGeometryCell> buildGiGeometry(const GiCascadeLayout& layout,
                                            std::span<const RenderVertex> vertices,
                                            std::span<const uint32_t> indices) {
    const int gv = layout.geometryCells();
    std::vector<GiGeometryCell> cells(size_t(gv) * size_t(gv) * size_t(gv));
    const float s = layout.cellSize;
    const grid::Aabb box{layout.origin - 0.5f * s,
                         layout.origin + (float(layout.cells) + 0.5f) * s};
    const float per_area = 1.0f / (s * s);
    const float inv_s = 1.0f / s;
    for (size_t t = 0; t + 2 < indices.size(); t += 3) {
        if (indices[t] >= vertices.size() || indices[t + 1] >= vertices.size() ||
            indices[t + 2] >= vertices.size()) {
            continue;
        }
        const RenderVertex& va = vertices[indices[t]];
        const RenderVertex& vb = vertices[indices[t + 1]];
        const RenderVertex& vc = vertices[indices[t + 2]];
        const glm::vec3 cross = glm::cross(vb.position - va.position, vc.position - va.position);
        const float length = glm::length(cross);
        if (!(length > 0.0f)) {
            continue;
        }
        const glm::vec3 normal = giCanonicalNormal(cross / length);
        const bool front = normal == cross / length;
        const sh::Coeffs y = sh::evalBasis(cross / length);
        std::array<float, 6> per_unit_area{};
        for (size_t k = 0; k < kBlockingCoefficients.size(); ++k) {
            const int c = kBlockingCoefficients[k];
            per_unit_area[k] = per_area * (c == 0 ? kLambda0 : kLambda2) * y[c];
        }
        // The triangle's albedo: the mean of its corners' (the renderer interpolates them).
        const glm::vec3 albedo = (va.albedo + vb.albedo + vc.albedo) / 3.0f;
        sampleTriangleInBox(
            va.position, vb.position, vc.position, box, 0.5f * s, [&](glm::vec3 p, float area) {
                const glm::ivec3 g =
                    glm::clamp(glm::ivec3(glm::floor((p - layout.origin) / s + 0.5f)),
                               glm::ivec3(0), glm::ivec3(gv - 1));
                GiGeometryCell& cell = cells[layout.geometryIndex(g)];
                for (size_t k = 0; k < per_unit_area.size(); ++k) {
                    cell.blocking[k] += fixedPoint(area * per_unit_area[k]);
                }
                const float a = area * per_area;
                const glm::vec3 offset = (p - layout.origin) * inv_s - glm::vec3(g);
                cell.area += fixedPoint(a);
                if (front) {
                    cell.frontArea += fixedPoint(a);
                }
                for (int ch = 0; ch < 3; ++ch) {
                    cell.albedoArea[size_t(ch)] += fixedPoint(a * albedo[ch]);
                    cell.normalArea[size_t(ch)] += fixedPoint(a * normal[ch]);
                    cell.offsetArea[size_t(ch)] += fixedPoint(a * offset[ch]);
                }
            });
    }
    return cells;
}

float giFacePotential(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                      glm::ivec3 cell, int d, glm::vec3 w) {
    const int axis = d / 2;
    glm::ivec3 g0 = cell;
    g0[axis] += kDirections[size_t(d)][axis] > 0 ? 1 : 0;
    const int u = (axis + 1) % 3;
    const int v = (axis + 2) % 3;
    const sh::Coeffs y = sh::evalBasis(w);
    float potential = 0.0f;
    for (int corner = 0; corner < 4; ++corner) {
        glm::ivec3 g = g0;
        g[u] += corner & 1;
        g[v] += corner >> 1;
        if (glm::any(glm::lessThan(g, glm::ivec3(0))) ||
            glm::any(glm::greaterThanEqual(g, glm::ivec3(layout.geometryCells())))) {
            continue;
        }
        const GiGeometryCell& c = geometry[layout.geometryIndex(g)];
        for (size_t k = 0; k < kBlockingCoefficients.size(); ++k) {
            potential += 0.25f * float(c.blocking[k]) / kGiFixedScale * y[kBlockingCoefficients[k]];
        }
    }
    return potential;
}

float giFaceBlocking(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                     glm::ivec3 cell, int d, glm::vec3 w) {
    return std::clamp(giFacePotential(layout, geometry, cell, d, w), 0.0f, 1.0f);
}

} // namespace probekit::runtime
