// The dynamic GI's geometry volume (runtime/src/gi_geometry.hpp), CPU twin.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "gi_geometry.hpp"

namespace probekit::runtime {
namespace {

// An axis-aligned quad as two triangles, albedo `albedo`.
void addQuad(std::vector<RenderVertex>& v, std::vector<uint32_t>& idx, glm::vec3 a, glm::vec3 b,
             glm::vec3 c, glm::vec3 d, glm::vec3 albedo) {
    const auto base = uint32_t(v.size());
    for (const glm::vec3& p : {a, b, c, d}) {
        RenderVertex r;
        r.position = p;
        r.albedo = albedo;
        v.push_back(r);
    }
    idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

GiCascadeLayout unitLayout() {
    GiCascadeLayout l;
    l.origin = glm::vec3(0.0f);
    l.cellSize = 0.25f;
    l.cells = 8; // 2 m cube
    return l;
}

// A wall at x = 1.0 (a plane of geometry-cell centres: LPV cell faces at multiples of 0.25)
// spanning the cube: its total area and albedo land in the volume to fixed-point rounding.
TEST(GiGeometry, AreaAndAlbedoAreConserved) {
    std::vector<RenderVertex> v;
    std::vector<uint32_t> idx;
    addQuad(v, idx, {1.0f, 0.0f, 0.0f}, {1.0f, 2.0f, 0.0f}, {1.0f, 2.0f, 2.0f}, {1.0f, 0.0f, 2.0f},
            glm::vec3(0.5f, 0.25f, 0.75f));
    const GiCascadeLayout layout = unitLayout();
    const auto cells = buildGiGeometry(layout, v, idx);
    // Sums are in units of the cell's face area.
    const double face = double(layout.cellSize) * double(layout.cellSize);
    double area = 0.0;
    glm::dvec3 albedo(0.0);
    size_t samples_bound = 0;
    for (const GiGeometryCell& c : cells) {
        area += face * double(c.area) / kGiFixedScale;
        for (int ch = 0; ch < 3; ++ch) {
            albedo[ch] += face * double(c.albedoArea[size_t(ch)]) / kGiFixedScale;
        }
        samples_bound += c.area != 0 ? 1 : 0;
    }
    // Each sample rounds by at most half a unit; a 4 m^2 quad cut into sub-triangles of edge
    // <= 0.125 m has at most 2 x (2 / 0.125 + 1)^2 = 578 samples per triangle.
    const double rounding = face * 2.0 * 578.0 * 0.5 / kGiFixedScale;
    EXPECT_NEAR(area, 4.0, rounding);
    EXPECT_NEAR(albedo.x, 2.0, rounding);
    EXPECT_NEAR(albedo.y, 1.0, rounding);
    EXPECT_NEAR(albedo.z, 3.0, rounding);
    EXPECT_GT(samples_bound, 0u);
}

// The wall blocks light crossing it (along x) and not light running along it (along y or z),
// as the offline LPV's geometry volume: A (n.w)^2 / s^2 over a geometry cell's s x s share of
// the wall. Bands 0 and 2 hold (n.w)^2 exactly, so the potential at 45 degrees is exactly half
// the one across; the one across is 1 up to how the area samples fall on the cell borders
// (whole sub-triangles of edge <= s / 2 go to the cell holding their centroid: measured 1.089
// here, and the offline volume does the same).
TEST(GiGeometry, WallBlocksAcrossAndNotAlong) {
    std::vector<RenderVertex> v;
    std::vector<uint32_t> idx;
    addQuad(v, idx, {1.0f, 0.0f, 0.0f}, {1.0f, 2.0f, 0.0f}, {1.0f, 2.0f, 2.0f}, {1.0f, 0.0f, 2.0f},
            glm::vec3(0.5f));
    const GiCascadeLayout layout = unitLayout();
    const auto cells = buildGiGeometry(layout, v, idx);
    // The face between LPV cells (3, 4, 4) and (4, 4, 4) lies on the wall.
    const glm::ivec3 cell(3, 4, 4);
    const float across = giFacePotential(layout, cells, cell, 0, glm::vec3(1, 0, 0));
    const float diagonal =
        giFacePotential(layout, cells, cell, 0, glm::normalize(glm::vec3(1, 1, 0)));
    EXPECT_NEAR(across, 1.0f, 0.15f);
    EXPECT_NEAR(diagonal / across, 0.5f, 1e-3f);
    EXPECT_EQ(giFaceBlocking(layout, cells, cell, 0, glm::vec3(1, 0, 0)), std::min(across, 1.0f));
    // Along the wall (faces across y in the cells beside it) light passes.
    EXPECT_NEAR(giFacePotential(layout, cells, cell, 2, glm::vec3(0, 1, 0)), 0.0f, 1e-3f);
    // Away from the wall nothing blocks.
    EXPECT_EQ(giFaceBlocking(layout, cells, glm::ivec3(1, 4, 4), 0, glm::vec3(1, 0, 0)), 0.0f);
}

// The sums are integers: any triangle order gives identical cells (what lets the compute
// shader's atomics match this twin exactly).
TEST(GiGeometry, TriangleOrderDoesNotChangeTheBytes) {
    std::vector<RenderVertex> v;
    std::vector<uint32_t> idx;
    std::mt19937 random(7);
    std::uniform_real_distribution<float> u(-0.2f, 2.2f);
    for (int i = 0; i < 50; ++i) {
        const glm::vec3 a(u(random), u(random), u(random));
        addQuad(v, idx, a, a + glm::vec3(0.3f, 0.1f, 0.0f), a + glm::vec3(0.3f, 0.4f, 0.2f),
                a + glm::vec3(0.0f, 0.3f, 0.2f), glm::vec3(u(random) / 2.2f));
    }
    const GiCascadeLayout layout = unitLayout();
    const auto forward = buildGiGeometry(layout, v, idx);
    std::vector<uint32_t> reversed;
    for (size_t t = idx.size(); t >= 3; t -= 3) {
        reversed.insert(reversed.end(), {idx[t - 3], idx[t - 2], idx[t - 1]});
    }
    EXPECT_EQ(buildGiGeometry(layout, v, reversed), forward);
}

} // namespace
} // namespace probekit::runtime
