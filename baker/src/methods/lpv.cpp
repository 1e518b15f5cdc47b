#include "methods/lpv.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "probekit/formats/lpv_transport.hpp"
#include "probekit/formats/triangle_sampling.hpp"
#include "trace/parallel.hpp"
#include "trace/rng.hpp"
#include "trace/sampling.hpp"

namespace probekit::baker {

namespace {

constexpr double kPi = std::numbers::pi;
// Integral of Y00 over the sphere: the flux of an intensity is sqrt(4 pi) x its band 0.
const float kSqrtFourPi = float(std::sqrt(4.0 * kPi));
// Keys the escape-ray streams apart from every other use of the bake seed.
constexpr uint64_t kEscapeRayKey = 0x4c50565f657363ull;

// Neighbour directions (in the order of LpvTransfer's matrices), the L1 basis and the five
// faces of a transfer: formats/lpv_transport.hpp, shared with the runtime's dynamic GI.
using lpv::basisL1;
using lpv::Face;
using lpv::faces;
using lpv::kBandOneIndex;
using lpv::kDirections;

// T_d = sum_f keep_f W_f Y(w_f) Y(w_f)^T (file comment of lpv.hpp).
LpvTransfer::Matrix transferMatrix(int d, const std::array<float, 5>& keep) {
    LpvTransfer::Matrix m{};
    for (int f = 0; f < 5; ++f) {
        const Face& face = faces()[d][f];
        const std::array<float, 4> y = basisL1(face.direction);
        const float weight = keep[f] * face.solidAngle;
        for (int r = 0; r < 4; ++r) {
            for (int c = 0; c < 4; ++c) {
                m[4 * r + c] += weight * y[r] * y[c];
            }
        }
    }
    return m;
}

Sh1Rgb multiply(const LpvTransfer::Matrix& m, const Sh1Rgb& v) {
    Sh1Rgb out;
    for (int r = 0; r < 4; ++r) {
        out.c[r] = m[4 * r] * v.c[0] + m[4 * r + 1] * v.c[1] + m[4 * r + 2] * v.c[2] +
                   m[4 * r + 3] * v.c[3];
    }
    return out;
}

// The free transfer towards a neighbour along axis a: by the symmetry of its five faces only the
// diagonal and the pair (0, k), (k, 0) with k = kBandOneIndex[a] are non-zero (the other entries
// cancel exactly: every face has a mirror image with the opposite sign).
struct SparseTransfer {
    std::array<float, 4> diagonal;
    float coupling;
    int axisIndex;
};

SparseTransfer sparseOf(const LpvTransfer::Matrix& m, int d) {
    SparseTransfer t{};
    t.axisIndex = kBandOneIndex[d / 2];
    for (int k = 0; k < 4; ++k) {
        t.diagonal[k] = m[5 * k];
    }
    t.coupling = m[t.axisIndex];
    return t;
}

// Runs body(begin, end) over [0, count) in about `threads` ranges (parallel.hpp). Every result
// a body writes depends only on its own index, so the split never changes the output.
template <class Body>
void parallelRanges(size_t count, uint32_t threads, const Body& body) {
    const size_t workers = std::max<size_t>(1, std::min<size_t>(threads, count));
    parallelFor(count, uint32_t(workers), (count + workers - 1) / workers, body);
}

// Flux that crossed into each cell, summed over iterations: plane 3 d + ch for light travelling
// along direction d, channel ch.
using CrossingPlanes = std::array<std::vector<float>, 18>;

// Row `length` cells long of one free transfer `t` (direction d) from `current` at src_row into
// `next` at dst_row, for every channel; with `crossing`, the flux across the faces too.
inline void transferRow(const SparseTransfer& t, int d, const LpvField& current, LpvField& next,
                        size_t src_row, size_t dst_row, int length, CrossingPlanes* crossing) {
    const float inv_y00 = 1.0f / sh::kY00;
    const int o1 = t.axisIndex == 1 ? 2 : 1;
    const int o2 = t.axisIndex == 3 ? 2 : 3;
    for (int ch = 0; ch < 3; ++ch) {
        // Distinct planes: restrict lets the loop run in SIMD lanes.
        const float* __restrict c0 = current.plane(0, ch) + src_row;
        const float* __restrict ca = current.plane(t.axisIndex, ch) + src_row;
        const float* __restrict c1 = current.plane(o1, ch) + src_row;
        const float* __restrict c2 = current.plane(o2, ch) + src_row;
        float* __restrict n0 = next.plane(0, ch) + dst_row;
        float* __restrict na = next.plane(t.axisIndex, ch) + dst_row;
        float* __restrict n1 = next.plane(o1, ch) + dst_row;
        float* __restrict n2 = next.plane(o2, ch) + dst_row;
        const float d0 = t.diagonal[0];
        const float da = t.diagonal[t.axisIndex];
        const float d1 = t.diagonal[o1];
        const float d2 = t.diagonal[o2];
        const float k = t.coupling;
        for (int x = 0; x < length; ++x) {
            n0[x] += d0 * c0[x] + k * ca[x];
            na[x] += k * c0[x] + da * ca[x];
            n1[x] += d1 * c1[x];
            n2[x] += d2 * c2[x];
        }
        if (crossing) {
            float* __restrict cross = (*crossing)[3 * d + ch].data() + dst_row;
            const float k0 = d0 * inv_y00;
            const float ka = k * inv_y00;
            for (int x = 0; x < length; ++x) {
                cross[x] += k0 * c0[x] + ka * ca[x];
            }
        }
    }
}

// The free transfers of the six neighbours into every cell of slabs [z_begin, z_end), a row of
// cells along x at a time so the inner loops vectorise.
void freeTransfersInto(const LpvCascadeLayout& layout, const std::array<SparseTransfer, 6>& free,
                       const LpvField& current, LpvField& next, CrossingPlanes* crossing,
                       size_t z_begin, size_t z_end) {
    const glm::ivec3 n = layout.cells;
    for (int z = int(z_begin); z < int(z_end); ++z) {
        for (int y = 0; y < n.y; ++y) {
            const size_t row = layout.index(glm::ivec3(0, y, z));
            for (int d = 0; d < 6; ++d) {
                // The row the light comes from (cell - direction) and which x receive.
                const glm::ivec3 from(0, y - kDirections[d].y, z - kDirections[d].z);
                if (from.y < 0 || from.y >= n.y || from.z < 0 || from.z >= n.z) {
                    continue;
                }
                const int shift = kDirections[d].x; // destination x = source x + shift
                const int x_begin = std::max(0, shift);
                const int x_end = n.x + std::min(0, shift);
                const size_t src_row = layout.index(from) - size_t(shift) + size_t(x_begin);
                const size_t dst_row = row + size_t(x_begin);
                transferRow(free[d], d, current, next, src_row, dst_row, x_end - x_begin, crossing);
            }
        }
    }
}

// Corrections of the transfers a surface touches, for destinations in slabs [z_begin, z_end), in
// (destination, direction) order.
void correctionsInto(const LpvCascadeLayout& layout, const LpvTransfer& transfer,
                     const LpvField& current, LpvField& next, CrossingPlanes* crossing,
                     size_t z_begin, size_t z_end) {
    const float inv_y00 = 1.0f / sh::kY00;
    const size_t slab_cells = size_t(layout.cells.x) * size_t(layout.cells.y);
    auto first = std::lower_bound(
        transfer.corrections.begin(), transfer.corrections.end(), z_begin * slab_cells,
        [](const LpvTransfer::Correction& c, size_t cell) { return c.destination < cell; });
    for (auto c = first; c != transfer.corrections.end() && c->destination < z_end * slab_cells;
         ++c) {
        const Sh1Rgb delta = multiply(c->delta, current.at(c->source));
        next.add(c->destination, delta);
        if (crossing) {
            for (int ch = 0; ch < 3; ++ch) {
                (*crossing)[3 * c->direction + ch][c->destination] += delta.c[0][ch] * inv_y00;
            }
        }
    }
}

// The positivity pass over slabs [z_begin, z_end): a cell with negative band 0 is zeroed, its
// (negative) flux added to dropped_per_slab.
void zeroNegativeCells(const LpvCascadeLayout& layout, LpvField& next, size_t z_begin, size_t z_end,
                       std::vector<glm::dvec3>& dropped_per_slab) {
    const size_t slab = size_t(layout.cells.x) * size_t(layout.cells.y);
    for (size_t z = z_begin; z < z_end; ++z) {
        for (int ch = 0; ch < 3; ++ch) {
            float* planes[4] = {next.plane(0, ch), next.plane(1, ch), next.plane(2, ch),
                                next.plane(3, ch)};
            for (size_t i = z * slab; i < (z + 1) * slab; ++i) {
                if (planes[0][i] < 0.0f) {
                    dropped_per_slab[z][ch] += double(kSqrtFourPi * planes[0][i]);
                    for (float* p : planes) {
                        p[i] = 0.0f;
                    }
                }
            }
        }
    }
}

// The negative flux removed is taken back from the positive light in proportion, so the step
// conserves flux exactly.
void restoreFlux(LpvField& next, glm::dvec3 dropped, size_t count) {
    const glm::dvec3 kept = next.totalFlux();
    for (int ch = 0; ch < 3; ++ch) {
        if (kept[ch] > 0.0 && dropped[ch] < 0.0) {
            const float scale = float((kept[ch] + dropped[ch]) / kept[ch]);
            for (int k = 0; k < 4; ++k) {
                float* plane = next.plane(k, ch);
                for (size_t i = 0; i < count; ++i) {
                    plane[i] *= scale;
                }
            }
        }
    }
}

// One step. First every cell receives the free transfers of its six neighbours, then the
// corrections of blocked transfers, then the positivity pass (file comment of lpv.hpp). The flux
// a transfer carries across a face is row 0 of T_d I over Y00 (a beam of flux F has band 0
// F Y00). Work is split by z slab; every cell's sum is formed in the same order whatever the
// split, and the flux totals are summed in double in a fixed order. Returns the (negative) flux
// zeroed and redistributed.
glm::vec3 stepInto(const LpvCascadeLayout& layout, const LpvTransfer& transfer,
                   const LpvField& current, LpvField& next, CrossingPlanes* crossing,
                   uint32_t threads) {
    const glm::ivec3 n = layout.cells;
    const size_t count = layout.cellCount();
    next = LpvField(count);
    std::array<SparseTransfer, 6> free;
    for (int d = 0; d < 6; ++d) {
        free[d] = sparseOf(transfer.free[d], d);
    }
    std::vector<glm::dvec3> dropped_per_slab(size_t(n.z), glm::dvec3(0.0));
    parallelRanges(size_t(n.z), threads, [&](size_t z_begin, size_t z_end) {
        freeTransfersInto(layout, free, current, next, crossing, z_begin, z_end);
        correctionsInto(layout, transfer, current, next, crossing, z_begin, z_end);
        zeroNegativeCells(layout, next, z_begin, z_end, dropped_per_slab);
    });
    glm::dvec3 dropped(0.0);
    for (const glm::dvec3& d : dropped_per_slab) {
        dropped += d;
    }
    restoreFlux(next, dropped, count);
    return glm::vec3(dropped);
}

bool inRegion(glm::vec3 p, const LpvCascadeLayout* region, const LpvCascadeLayout* excluded) {
    return (!region || region->contains(p)) && !(excluded && excluded->contains(p));
}

} // namespace

Sh1Rgb& Sh1Rgb::operator+=(const Sh1Rgb& other) {
    for (int k = 0; k < 4; ++k) {
        c[k] += other.c[k];
    }
    return *this;
}

Sh1Rgb& Sh1Rgb::operator*=(float scale) {
    for (glm::vec3& v : c) {
        v *= scale;
    }
    return *this;
}

LpvField::LpvField(size_t cells) {
    for (std::vector<float>& plane : m_planes) {
        plane.assign(cells, 0.0f);
    }
}

Sh1Rgb LpvField::at(size_t cell) const {
    Sh1Rgb v;
    for (int k = 0; k < 4; ++k) {
        for (int ch = 0; ch < 3; ++ch) {
            v.c[k][ch] = m_planes[3 * k + ch][cell];
        }
    }
    return v;
}

void LpvField::add(size_t cell, const Sh1Rgb& value) {
    for (int k = 0; k < 4; ++k) {
        for (int ch = 0; ch < 3; ++ch) {
            m_planes[3 * k + ch][cell] += value.c[k][ch];
        }
    }
}

glm::dvec3 LpvField::totalFlux() const {
    glm::dvec3 sum(0.0);
    for (int ch = 0; ch < 3; ++ch) {
        for (float v : m_planes[ch]) {
            sum[ch] += double(v);
        }
    }
    return sum * std::sqrt(4.0 * kPi);
}

glm::vec3 totalFlux(const Sh1Rgb& intensity) {
    return kSqrtFourPi * intensity.c[0];
}

Sh1Rgb beamSh(glm::vec3 direction, glm::vec3 amount) {
    const std::array<float, 4> y = basisL1(direction);
    Sh1Rgb s;
    for (int k = 0; k < 4; ++k) {
        s.c[k] = y[k] * amount;
    }
    return s;
}

bool LpvCascadeLayout::contains(glm::vec3 p) const {
    return glm::all(glm::greaterThanEqual(p, origin)) && glm::all(glm::lessThanEqual(p, max()));
}

bool LpvCascadeLayout::containsCell(glm::ivec3 cell) const {
    return glm::all(glm::greaterThanEqual(cell, glm::ivec3(0))) &&
           glm::all(glm::lessThan(cell, cells));
}

glm::ivec3 LpvCascadeLayout::cellOf(glm::vec3 p) const {
    const glm::ivec3 cell(glm::floor((p - origin) / cellSize));
    return glm::clamp(cell, glm::ivec3(0), cells - 1);
}

float LpvCascadeLayout::insideDistance(glm::vec3 p) const {
    const glm::vec3 to_min = p - origin;
    const glm::vec3 to_max = max() - p;
    return std::min({to_min.x, to_min.y, to_min.z, to_max.x, to_max.y, to_max.z});
}

std::vector<LpvCascadeLayout> layoutLpvCascades(const grid::Aabb& volume, const grid::Aabb& scene,
                                                const LpvSettings& settings) {
    assert(settings.grid >= 4 && settings.cascades >= 1 && settings.cascadeRatio > 1.0f);
    const grid::Aabb both{glm::min(volume.min, scene.min), glm::max(volume.max, scene.max)};
    const glm::vec3 extent = both.size();
    const float longest = std::max({extent.x, extent.y, extent.z});
    assert(longest > 0.0f);
    // grid - 2 cells span the longest axis, plus the padding cell on each side.
    const float coarse_size = longest / float(settings.grid - 2);
    glm::ivec3 cells;
    for (int a = 0; a < 3; ++a) {
        // The tolerance keeps an axis that is a whole number of cells from gaining one.
        cells[a] =
            std::clamp(int(std::ceil(extent[a] / coarse_size - 1e-4f)), 1, int(settings.grid) - 2) +
            2;
    }
    const uint32_t count = settings.cascades;
    std::vector<LpvCascadeLayout> out(count);
    LpvCascadeLayout& coarse = out[count - 1];
    coarse.cells = cells;
    coarse.cellSize = coarse_size;
    coarse.origin = both.center() - 0.5f * glm::vec3(cells) * coarse_size;
    const glm::vec3 coarse_max = coarse.max();
    for (uint32_t k = count - 1; k-- > 0;) {
        LpvCascadeLayout& c = out[k];
        c.cells = cells;
        c.cellSize = coarse_size / std::pow(settings.cascadeRatio, float(count - 1 - k));
        const glm::vec3 half = 0.5f * glm::vec3(cells) * c.cellSize;
        glm::vec3 centre = volume.center();
        for (int a = 0; a < 3; ++a) {
            // Inside the coarsest cascade where it fits, so no fine cell is spent off the scene.
            const float lo = coarse.origin[a] + half[a];
            const float hi = coarse_max[a] - half[a];
            centre[a] = lo <= hi ? std::clamp(centre[a], lo, hi) : both.center()[a];
        }
        c.origin =
            coarse.origin + glm::round((centre - half - coarse.origin) / c.cellSize) * c.cellSize;
    }
    return out;
}

TriangleCorners triangleCorners(const Scene& scene, glm::uvec3 t) {
    const glm::vec3 a = scene.positions[t.x];
    const glm::vec3 b = scene.positions[t.y];
    const glm::vec3 c = scene.positions[t.z];
    return {a, b, c, glm::min(a, glm::min(b, c)), glm::max(a, glm::max(b, c))};
}

namespace {

// The geometry volume: SH blocking potential per geometry cell. Geometry cells are centred on
// the LPV cell corners: cells + 1 per axis.
struct GeometryVolume {
    glm::ivec3 size;
    std::vector<sh::Coeffs> blocking;

    const sh::Coeffs& at(glm::ivec3 g) const { return blocking[index(g)]; }
    size_t index(glm::ivec3 g) const {
        return size_t(g.x) + size_t(size.x) * (size_t(g.y) + size_t(size.y) * size_t(g.z));
    }
};

// Splats every triangle's area into the geometry cells around it as the SH of (n.w)^2 per unit
// cell face area.
GeometryVolume buildGeometryVolume(const Scene& scene, const LpvCascadeLayout& layout) {
    const float s = layout.cellSize;
    GeometryVolume gv;
    gv.size = layout.cells + 1;
    gv.blocking.assign(size_t(gv.size.x) * size_t(gv.size.y) * size_t(gv.size.z), sh::Coeffs{});
    const grid::Aabb box{layout.origin - 0.5f * s, layout.max() + 0.5f * s};
    // Funk-Hecke: the SH of (n.w)^2 are lambda_l Y_lm(n), lambda = 2 pi int t^2 P_l(t) dt.
    constexpr std::array<float, 3> kLambda = {4.0f / 3.0f * sh::kPi, 0.0f, 8.0f / 15.0f * sh::kPi};
    const float per_area = 1.0f / (s * s);
    for (const glm::uvec3& t : scene.triangles) {
        const auto [a, b, c, lo, hi] = triangleCorners(scene, t);
        const glm::vec3 cross = glm::cross(b - a, c - a);
        const float length = glm::length(cross);
        if (!(length > 0.0f) || glm::any(glm::lessThan(hi, box.min)) ||
            glm::any(glm::greaterThan(lo, box.max))) {
            continue;
        }
        const sh::Coeffs y = sh::evalBasis(cross / length);
        sh::Coeffs per_unit_area{};
        for (int k = 0; k < sh::kMaxCoefficients; ++k) {
            per_unit_area[k] = per_area * kLambda[sh::bandOf(k)] * y[k];
        }
        sampleTriangleInBox(a, b, c, box, 0.5f * s, [&](glm::vec3 p, float area) {
            const glm::ivec3 g = glm::clamp(glm::ivec3(glm::floor((p - layout.origin) / s + 0.5f)),
                                            glm::ivec3(0), gv.size - 1);
            sh::Coeffs& cell = gv.blocking[gv.index(g)];
            for (int k = 0; k < sh::kMaxCoefficients; ++k) {
                cell[k] += area * per_unit_area[k];
            }
        });
    }
    return gv;
}

// What a cell's faces let through: keep[d][f] for face f of direction d's transfer, and whether
// any face of direction d is blocked at all.
struct CellPassage {
    std::array<std::array<float, 5>, 6> keep;
    std::array<bool, 6> blocked{};
};

CellPassage cellPassage(const GeometryVolume& gv, glm::ivec3 cell,
                        const std::array<std::array<sh::Coeffs, 5>, 6>& face_basis,
                        float propagation_weight) {
    CellPassage out;
    for (int d = 0; d < 6; ++d) {
        // The plane of geometry-cell centres the face lies on, and the four centres at its
        // corners: bilinear weights 1/4 each at the face centre.
        const int axis = d / 2;
        glm::ivec3 g0 = cell;
        g0[axis] += kDirections[d][axis] > 0 ? 1 : 0;
        const int u = (axis + 1) % 3;
        const int v = (axis + 2) % 3;
        sh::Coeffs b{};
        for (int corner = 0; corner < 4; ++corner) {
            glm::ivec3 g = g0;
            g[u] += corner & 1;
            g[v] += corner >> 1;
            for (int k = 0; k < sh::kMaxCoefficients; ++k) {
                b[k] += 0.25f * gv.at(g)[k];
            }
        }
        for (int f = 0; f < 5; ++f) {
            float potential = 0.0f;
            for (int k = 0; k < sh::kMaxCoefficients; ++k) {
                potential += b[k] * face_basis[d][f][k];
            }
            const float pass = 1.0f - std::clamp(potential, 0.0f, 1.0f);
            out.keep[d][f] = propagation_weight * pass;
            out.blocked[d] = out.blocked[d] || pass < 1.0f;
        }
    }
    return out;
}

// Adds the corrections to the free transfer of `cell`'s blocked directions.
void addCorrections(const LpvCascadeLayout& layout, glm::ivec3 cell, const CellPassage& passage,
                    LpvTransfer& out) {
    for (int d = 0; d < 6; ++d) {
        if (!passage.blocked[d]) {
            continue;
        }
        LpvTransfer::Correction c{};
        const glm::ivec3 to = cell + kDirections[d];
        c.source = uint32_t(layout.index(cell));
        c.direction = uint32_t(d);
        c.delta = transferMatrix(d, passage.keep[d]);
        for (int k = 0; k < 16; ++k) {
            c.delta[k] -= out.free[d][k];
        }
        if (layout.containsCell(to)) {
            c.destination = uint32_t(layout.index(to));
            out.corrections.push_back(c);
        } else {
            out.border.push_back(c);
        }
    }
}

} // namespace

LpvTransfer buildLpvTransfer(const Scene& scene, const LpvCascadeLayout& layout,
                             const LpvSettings& settings) {
    LpvTransfer out;
    std::array<float, 5> free_keep;
    free_keep.fill(settings.propagationWeight);
    for (int d = 0; d < 6; ++d) {
        out.free[d] = transferMatrix(d, free_keep);
    }
    if (!settings.occlusion) {
        return out;
    }
    const GeometryVolume gv = buildGeometryVolume(scene, layout);
    std::array<std::array<sh::Coeffs, 5>, 6> face_basis;
    for (int d = 0; d < 6; ++d) {
        for (int f = 0; f < 5; ++f) {
            face_basis[d][f] = sh::evalBasis(faces()[d][f].direction);
        }
    }
    const glm::ivec3 n = layout.cells;
    for (int z = 0; z < n.z; ++z) {
        for (int y = 0; y < n.y; ++y) {
            for (int x = 0; x < n.x; ++x) {
                const glm::ivec3 cell(x, y, z);
                addCorrections(layout, cell,
                               cellPassage(gv, cell, face_basis, settings.propagationWeight), out);
            }
        }
    }
    std::sort(out.corrections.begin(), out.corrections.end(),
              [](const LpvTransfer::Correction& a, const LpvTransfer::Correction& b) {
                  return a.destination != b.destination ? a.destination < b.destination
                                                        : a.direction < b.direction;
              });
    return out;
}

LpvStepFlux propagateStep(const LpvCascadeLayout& layout, const LpvTransfer& transfer,
                          const LpvField& current, LpvField& next, uint32_t threads) {
    LpvStepFlux flux;
    flux.redistributed = stepInto(layout, transfer, current, next, nullptr, threads);
    // What the border cells send outwards, in a fixed order: the free part, then corrections.
    glm::dvec3 escaped(0.0);
    const glm::ivec3 n = layout.cells;
    for (int z = 0; z < n.z; ++z) {
        for (int y = 0; y < n.y; ++y) {
            for (int x = 0; x < n.x; ++x) {
                const glm::ivec3 cell(x, y, z);
                for (int d = 0; d < 6; ++d) {
                    if (!layout.containsCell(cell + kDirections[d])) {
                        const Sh1Rgb moved =
                            multiply(transfer.free[d], current.at(layout.index(cell)));
                        escaped += glm::dvec3(moved.c[0]);
                    }
                }
            }
        }
    }
    for (const LpvTransfer::Correction& c : transfer.border) {
        escaped += glm::dvec3(multiply(c.delta, current.at(c.source)).c[0]);
    }
    escaped *= 1.0 / double(sh::kY00);
    flux.escaped = glm::vec3(escaped);
    return flux;
}

std::vector<Sh1Rgb> propagateToRadiance(const LpvCascadeLayout& layout, const LpvTransfer& transfer,
                                        LpvField injected, uint32_t iterations, uint32_t threads) {
    LpvField current = std::move(injected);
    LpvField next;
    CrossingPlanes crossing;
    for (std::vector<float>& plane : crossing) {
        plane.assign(layout.cellCount(), 0.0f);
    }
    for (uint32_t it = 0; it < iterations; ++it) {
        stepInto(layout, transfer, current, next, &crossing, threads);
        std::swap(current, next);
    }
    // One-sided irradiances from the face crossings, then radiance (lpv_transport.hpp).
    const glm::ivec3 n = layout.cells;
    const float inv_area = 1.0f / (layout.cellSize * layout.cellSize);
    std::vector<Sh1Rgb> radiance(layout.cellCount());
    for (int z = 0; z < n.z; ++z) {
        for (int y = 0; y < n.y; ++y) {
            for (int x = 0; x < n.x; ++x) {
                const glm::ivec3 cell(x, y, z);
                const size_t i = layout.index(cell);
                std::array<glm::vec3, 6> e{};
                for (int d = 0; d < 6; ++d) {
                    e[size_t(d)] = lpv::oneSidedIrradiance(
                        cell, d, inv_area, [&](glm::ivec3 c) { return layout.containsCell(c); },
                        [&](glm::ivec3 c, int travel) {
                            const size_t k = layout.index(c);
                            return glm::vec3(crossing[size_t(3 * travel)][k],
                                             crossing[size_t(3 * travel + 1)][k],
                                             crossing[size_t(3 * travel + 2)][k]);
                        });
                }
                radiance[i].c = lpv::radianceFromOneSided(e);
            }
        }
    }
    return radiance;
}

LpvInjection traceLpvInjection(const RayTracer& tracer, std::vector<LpvSurfaceLight> lights,
                               std::vector<LpvPointLight> point_lights, float max_distance,
                               uint64_t seed, uint32_t threads) {
    LpvInjection out;
    out.lights = std::move(lights);
    out.pointLights = std::move(point_lights);
    out.directions.resize(out.lights.size());
    out.freeDistance.resize(out.lights.size());
    parallelRanges(out.lights.size(), threads, [&](size_t begin, size_t end) {
        const ScopedFloatMode float_mode;
        for (size_t i = begin; i < end; ++i) {
            const LpvSurfaceLight& light = out.lights[i];
            const glm::vec3 origin =
                RayTracer::offsetOrigin(light.position, light.normal, light.normal);
            Rng rng(hashKeys(seed, kEscapeRayKey, i));
            for (uint32_t r = 0; r < kEscapeRays; ++r) {
                // Jittered in kEscapeRays strata of the azimuth: unbiased, and balanced around
                // the normal so an unblocked light's rays average close to its cosine lobe.
                glm::vec2 u = rng.uniform2();
                u.y = (float(r) + u.y) / float(kEscapeRays);
                const glm::vec3 dir = cosineDirection(light.normal, u);
                const std::optional<Hit> hit = tracer.intersect(origin, dir, max_distance);
                out.directions[i][r] = dir;
                out.freeDistance[i][r] = hit ? hit->t : max_distance;
            }
        }
    });
    return out;
}

void injectLights(const LpvCascadeLayout& layout, const LpvInjection& injection,
                  const LpvCascadeLayout* region, const LpvCascadeLayout* excluded,
                  LpvField& cells) {
    const float reach = layout.cellSize;
    for (size_t i = 0; i < injection.lights.size(); ++i) {
        const LpvSurfaceLight& light = injection.lights[i];
        if (!inRegion(light.position, region, excluded)) {
            continue;
        }
        Sh1Rgb beams;
        const glm::vec3 flux = light.flux * (1.0f / float(kEscapeRays));
        for (uint32_t r = 0; r < kEscapeRays; ++r) {
            if (injection.freeDistance[i][r] >= reach) {
                beams += beamSh(injection.directions[i][r], flux);
            }
        }
        const glm::vec3 at = light.position + 0.5f * layout.cellSize * light.normal;
        cells.add(layout.index(layout.cellOf(at)), beams);
    }
    for (const LpvPointLight& light : injection.pointLights) {
        if (inRegion(light.position, region, excluded)) {
            cells.add(layout.index(layout.cellOf(light.position)), light.intensity);
        }
    }
    if (region) {
        return;
    }
    const glm::ivec3 n = layout.cells;
    for (int d = 0; d < 6; ++d) {
        Sh1Rgb per_cell = injection.borderPerArea[d];
        if (isBlack(per_cell.c[0])) {
            continue;
        }
        per_cell *= layout.cellSize * layout.cellSize;
        // The side light travelling along d enters through: the low side for a positive d.
        const int axis = d / 2;
        const int layer = kDirections[d][axis] > 0 ? 0 : n[axis] - 1;
        const int u = (axis + 1) % 3;
        const int v = (axis + 2) % 3;
        for (int a = 0; a < n[u]; ++a) {
            for (int b = 0; b < n[v]; ++b) {
                glm::ivec3 cell;
                cell[axis] = layer;
                cell[u] = a;
                cell[v] = b;
                cells.add(layout.index(cell), per_cell);
            }
        }
    }
}

LpvCascades::LpvCascades(const Scene& scene, const LpvInjection& injection,
                         std::vector<LpvCascadeLayout> layouts, const LpvSettings& settings,
                         uint32_t threads)
    : m_layouts(std::move(layouts)), m_fadeCells(settings.fadeCells) {
    const size_t count = m_layouts.size();
    m_all.resize(count);
    m_outer.resize(count);
    for (size_t k = 0; k < count; ++k) {
        const LpvCascadeLayout& layout = m_layouts[k];
        const LpvTransfer transfer = buildLpvTransfer(scene, layout, settings);
        // The coarsest cascade takes every light (clamped into its border cells).
        const LpvCascadeLayout* region = k + 1 == count ? nullptr : &layout;
        LpvField all(layout.cellCount());
        injectLights(layout, injection, region, nullptr, all);
        m_all[k] =
            propagateToRadiance(layout, transfer, std::move(all), settings.iterations, threads);
        if (k > 0) {
            LpvField outer(layout.cellCount());
            injectLights(layout, injection, region, &m_layouts[k - 1], outer);
            m_outer[k] = propagateToRadiance(layout, transfer, std::move(outer),
                                             settings.iterations, threads);
        }
    }
}

Sh1Rgb LpvCascades::sampleField(size_t cascade, const std::vector<Sh1Rgb>& field,
                                glm::vec3 p) const {
    const LpvCascadeLayout& layout = m_layouts[cascade];
    // Cell centres at integer coordinates; clamp-to-edge like a 3D texture.
    const glm::vec3 g = glm::clamp((p - layout.origin) / layout.cellSize - 0.5f, glm::vec3(0.0f),
                                   glm::vec3(layout.cells - 1));
    const glm::ivec3 i0 = glm::min(glm::ivec3(glm::floor(g)), layout.cells - 1);
    const glm::ivec3 i1 = glm::min(i0 + 1, layout.cells - 1);
    const glm::vec3 t = g - glm::vec3(i0);
    Sh1Rgb out;
    for (int corner = 0; corner < 8; ++corner) {
        const glm::ivec3 pick((corner & 1) ? i1.x : i0.x, (corner & 2) ? i1.y : i0.y,
                              (corner & 4) ? i1.z : i0.z);
        const float w = ((corner & 1) ? t.x : 1.0f - t.x) * ((corner & 2) ? t.y : 1.0f - t.y) *
                        ((corner & 4) ? t.z : 1.0f - t.z);
        if (w > 0.0f) {
            Sh1Rgb v = field[layout.index(pick)];
            v *= w;
            out += v;
        }
    }
    return out;
}

sh::ShRgb LpvCascades::radiance(glm::vec3 p) const {
    const size_t count = m_layouts.size();
    // From the coarsest down: result = the combination so far, outer = sum of the outer fields
    // of the cascades coarser than j.
    Sh1Rgb result = sampleField(count - 1, m_all[count - 1], p);
    Sh1Rgb outer;
    for (size_t j = count - 1; j-- > 0;) {
        outer += sampleField(j + 1, m_outer[j + 1], p);
        const float inside = m_layouts[j].insideDistance(p);
        const float band = m_fadeCells * m_layouts[j].cellSize;
        const float w =
            band > 0.0f ? std::clamp(inside / band, 0.0f, 1.0f) : (inside >= 0.0f ? 1.0f : 0.0f);
        if (w <= 0.0f) {
            continue;
        }
        Sh1Rgb fine = sampleField(j, m_all[j], p);
        fine += outer;
        fine *= w;
        result *= 1.0f - w;
        result += fine;
    }
    sh::ShRgb out;
    for (int k = 0; k < 4; ++k) {
        out.rgb[k] = result.c[k];
    }
    return out;
}

} // namespace probekit::baker
