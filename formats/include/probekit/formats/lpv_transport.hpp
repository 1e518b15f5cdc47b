// probekit::lpv — the light propagation volume transport shared by the baker's offline LPV
// (baker/src/methods/lpv.hpp, where the file comment derives it) and the runtime's dynamic GI
// (runtime/src/gi_twin.hpp, the CPU twin of its compute shaders): the neighbour directions,
// the L1 basis, the five faces a transfer reaches, and radiance from one-sided irradiances.
// shaders/gi_common.glsl holds the same numbers for the GPU.
#pragma once

#include <array>
#include <cmath>
#include <numbers>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "probekit/formats/sh.hpp"

namespace probekit::lpv {

// Neighbour directions d = 0..5: +x, -x, +y, -y, +z, -z.
constexpr std::array<glm::ivec3, 6> kDirections = {glm::ivec3(1, 0, 0), glm::ivec3(-1, 0, 0),
                                                   glm::ivec3(0, 1, 0), glm::ivec3(0, -1, 0),
                                                   glm::ivec3(0, 0, 1), glm::ivec3(0, 0, -1)};

// SH index of the band-1 function along each axis (Y11 = x, Y1-1 = y, Y10 = z).
constexpr std::array<int, 3> kBandOneIndex = {3, 1, 2};

// The L1 basis (Y00, Y1-1, Y10, Y11) at unit w.
inline std::array<float, 4> basisL1(glm::vec3 w) {
    return {sh::kY00, sh::kY1 * w.y, sh::kY1 * w.z, sh::kY1 * w.x};
}

// One of the five faces a transfer towards a neighbour reaches: the direction from the source
// cell's centre to the face's centre, and the solid angle the face subtends.
struct Face {
    glm::vec3 direction;
    float solidAngle;
};
using DirectionFaces = std::array<Face, 5>;

// Per neighbour d: the far face first (a unit square at 1.5 cells: 4 asin(1/10) sr), then the
// four side faces in axis order, +0.5 before -0.5, each (4 pi / 6 - far) / 4, so the five tile
// the shared face.
inline const std::array<DirectionFaces, 6>& faces() {
    static const std::array<DirectionFaces, 6> table = [] {
        const double far_solid_angle = 4.0 * std::asin(0.1);
        const double side_solid_angle = (4.0 * std::numbers::pi / 6.0 - far_solid_angle) / 4.0;
        std::array<DirectionFaces, 6> t{};
        for (size_t d = 0; d < 6; ++d) {
            const glm::dvec3 main(kDirections[d]);
            t[d][0] = Face{glm::vec3(main), float(far_solid_angle)};
            size_t slot = 1;
            for (int other = 0; other < 3; ++other) {
                if (kDirections[d][other] != 0) {
                    continue;
                }
                for (double side : {0.5, -0.5}) {
                    glm::dvec3 to_centre = main;
                    to_centre[other] = side;
                    t[d][slot++] =
                        Face{glm::vec3(glm::normalize(to_centre)), float(side_solid_angle)};
                }
            }
        }
        return t;
    }();
    return table;
}

// The one-sided irradiance at a cell's centre from side d (light travelling along d ^ 1): the
// mean of the flux that crossed into the cell from c + d and on into c - d, over the face area;
// at the grid's border only one of the two exists. `inside(cell)` says whether a cell is in the
// grid, `crossed(cell, travel)` gives the flux (W per channel) summed into that cell along
// direction `travel`.
template <class Inside, class Crossed>
glm::vec3 oneSidedIrradiance(glm::ivec3 cell, int d, float inv_area, const Inside& inside,
                             const Crossed& crossed) {
    const int travel = d ^ 1;
    const bool from_inside = inside(cell + kDirections[size_t(d)]);
    const glm::ivec3 onward = cell - kDirections[size_t(d)];
    if (!inside(onward)) {
        return inv_area * crossed(cell, travel);
    }
    if (!from_inside) {
        return inv_area * crossed(onward, travel);
    }
    return 0.5f * inv_area * (crossed(cell, travel) + crossed(onward, travel));
}

// The L1 radiance SH (coefficient k per channel) whose irradiance facing each axis direction d
// is e[d]: L00 = sum e / (6 pi Y00), L1 along an axis = (e(+a) - e(-a)) / (2 (2 pi / 3) Y1).
inline std::array<glm::vec3, 4> radianceFromOneSided(const std::array<glm::vec3, 6>& e) {
    const float band0 = 1.0f / (6.0f * sh::kCosineLobe[0] * sh::kY00);
    const float band1 = 1.0f / (2.0f * sh::kCosineLobe[1] * sh::kY1);
    std::array<glm::vec3, 4> r{};
    r[0] = band0 * (e[0] + e[1] + e[2] + e[3] + e[4] + e[5]);
    for (size_t axis = 0; axis < 3; ++axis) {
        r[size_t(kBandOneIndex[axis])] = band1 * (e[2 * axis] - e[2 * axis + 1]);
    }
    return r;
}

} // namespace probekit::lpv
