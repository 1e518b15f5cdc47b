// probekit::runtime — the dynamic GI's geometry volume, CPU twin (docs/runtime.md#dynamic-gi).
//
// A cascade is a cube of `cells` cells of side `cellSize` from `origin`. Its geometry volume is
// offset by half a cell, as the offline LPV's (baker/src/methods/lpv.hpp, "Geometry volume"): cells
// + 1 per axis, centred on the LPV cell corners, so every face between two LPV cells lies on a
// plane of geometry-cell centres. Each geometry cell holds, summed over the surface inside it:
//  * blocking: bands 0 and 2 of A (n.w)^2 / s^2 (6 numbers: Y00 and the five band-2
//    coefficients; band 1 is zero since the function is even), the probability that light
//    crossing the cell along w meets the surface, as offline;
//  * for injection (gi_twin.hpp): area, albedo x area per channel, normal x area (each
//    triangle's normal turned to its canonical side: largest-magnitude component positive, the
//    first such axis on a tie) and offset x area (the sample's position minus the geometry
//    cell's centre, in cells), all in units of the cell's face area s^2; and the area of the
//    triangles that already faced their canonical side (frontArea), so that a closed thin box
//    (a wall, a slab: two faces of opposite normals in one cell) is told from a single
//    two-sided quad: each side of the cell's surface reflects with max(front, area - front).
// Triangles are sampled by sampleTriangleInBox (formats/triangle_sampling.hpp) with sub-triangle
// edges at most half a cell. Every sample's contribution is rounded to fixed point
// (kGiFixedScale) before it is summed, so the sums do not depend on the order triangles are
// visited: the compute shader adds the same integers with atomics and gets the same bytes.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/runtime/renderer.hpp"

namespace probekit::runtime {

// Fixed-point unit of every geometry sum: 2^-16 (areas in units of s^2, so a cascade's precision
// does not depend on its cell size).
constexpr float kGiFixedScale = 65536.0f;

struct GiCascadeLayout {
    glm::vec3 origin{0.0f}; // world min corner, metres
    float cellSize = 0.25f; // metres
    int cells = 32;         // per axis

    int geometryCells() const { return cells + 1; }
    size_t geometryIndex(glm::ivec3 g) const {
        const auto n = size_t(geometryCells());
        return size_t(g.x) + n * (size_t(g.y) + n * size_t(g.z));
    }
};

// 17 int32 per cell; the GPU buffer holds the same struct (std430, no padding).
struct GiGeometryCell {
    std::array<int32_t, 6> blocking{}; // fixed point: Y00 then Y2-2..Y22 coefficients
    int32_t area = 0;                  // fixed point, s^2
    std::array<int32_t, 3> albedoArea{};
    std::array<int32_t, 3> normalArea{};
    std::array<int32_t, 3> offsetArea{}; // offset in cells x area in s^2
    int32_t frontArea = 0;               // fixed point, s^2
    friend bool operator==(const GiGeometryCell&, const GiGeometryCell&) = default;
};
static_assert(sizeof(GiGeometryCell) == 68);

// The canonical side of a unit normal (above): n or -n.
glm::vec3 giCanonicalNormal(glm::vec3 n);

// The geometry volume of `layout` from indexed triangles (every three indices one triangle;
// out-of-range indices are the caller's error and are skipped).
std::vector<GiGeometryCell> buildGiGeometry(const GiCascadeLayout& layout,
                                            std::span<const RenderVertex> vertices,
                                            std::span<const uint32_t> indices);

// The probability, in [0, 1], that light crossing the face between LPV cell `cell` and its
// neighbour along axis direction `d` (0..5: +x, -x, +y, -y, +z, -z) in direction `w` meets a
// surface: giFacePotential clamped. The potential is the blocking evaluated at w, averaged over
// the four geometry cells at the face's corners (bilinear at its centre), unclamped.
float giFacePotential(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                      glm::ivec3 cell, int d, glm::vec3 w);
// Bands 0 and 2 of one geometry cell's blocking evaluated at unit w (unclamped).
float giCellPotential(const GiGeometryCell& cell, glm::vec3 w);
float giFaceBlocking(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                     glm::ivec3 cell, int d, glm::vec3 w);

} // namespace probekit::runtime
