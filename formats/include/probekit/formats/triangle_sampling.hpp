// probekit::formats — deterministic area samples of a triangle inside a box, shared by the
// baker's offline LPV geometry volume (baker/src/methods/lpv.cpp) and the runtime's dynamic GI
// geometry volume (runtime/src/gi_geometry.cpp), whose compute shader follows the same arithmetic.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "probekit/formats/grid.hpp"

namespace probekit {

// Deterministic area samples of a triangle clipped to a box: Sutherland-Hodgman against the six
// planes, the polygon fanned into triangles, each split into m^2 congruent sub-triangles
// (m = ceil(longest edge / max_edge)), one sample at the centroid of each with its area.
template <class Emit>
inline void sampleTriangleInBox(glm::vec3 a, glm::vec3 b, glm::vec3 c, const grid::Aabb& box,
                                float max_edge, const Emit& emit) {
    std::vector<glm::vec3> polygon = {a, b, c};
    std::vector<glm::vec3> clipped;
    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            const float bound = side == 0 ? box.min[axis] : box.max[axis];
            const float sign = side == 0 ? 1.0f : -1.0f; // inside: sign (p - bound) >= 0
            clipped.clear();
            for (size_t i = 0; i < polygon.size(); ++i) {
                const glm::vec3 p = polygon[i];
                const glm::vec3 q = polygon[(i + 1) % polygon.size()];
                const float dp = sign * (p[axis] - bound);
                const float dq = sign * (q[axis] - bound);
                if (dp >= 0.0f) {
                    clipped.push_back(p);
                }
                if ((dp >= 0.0f) != (dq >= 0.0f)) {
                    clipped.push_back(p + (q - p) * (dp / (dp - dq)));
                }
            }
            polygon.swap(clipped);
            if (polygon.size() < 3) {
                return;
            }
        }
    }
    for (size_t k = 1; k + 1 < polygon.size(); ++k) {
        const glm::vec3 p0 = polygon[0];
        const glm::vec3 e1 = polygon[k] - p0;
        const glm::vec3 e2 = polygon[k + 1] - p0;
        const float area = 0.5f * glm::length(glm::cross(e1, e2));
        if (!(area > 0.0f)) {
            continue;
        }
        const float longest = std::max({glm::length(e1), glm::length(e2), glm::length(e2 - e1)});
        const int m = std::max(1, int(std::ceil(longest / max_edge)));
        const float sub_area = area / float(m * m);
        const float inv_m = 1.0f / float(m);
        for (int i = 0; i < m; ++i) {
            for (int j = 0; i + j < m; ++j) {
                // Upright sub-triangle (i, j), (i+1, j), (i, j+1), then the inverted one
                // beside it.
                const float fi = float(i);
                const float fj = float(j);
                emit(p0 + ((fi + 1.0f / 3.0f) * e1 + (fj + 1.0f / 3.0f) * e2) * inv_m, sub_area);
                if (i + j + 1 < m) {
                    emit(p0 + ((fi + 2.0f / 3.0f) * e1 + (fj + 2.0f / 3.0f) * e2) * inv_m,
                         sub_area);
                }
            }
        }
    }
}

} // namespace probekit
