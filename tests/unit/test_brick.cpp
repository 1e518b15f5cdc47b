// The bricked layout (brick.hpp): the indirection and its layout checks (nested bricks too), the
// sampling rule (locate + interpolate) and border stitching, which is what makes the field
// seamless.
#include "probekit/formats/brick.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <vector>

#include "../gpu/bricked_test_volume.hpp"

namespace probekit::brick {
namespace {

// The jumps are measured this far (finest-cell units) either side of a border.
constexpr float kBorderOffset = 1e-4f;
// Rounding in interpolate (8 weighted terms of values of magnitude <= 1, weights <= 1) and in
// the sample coordinates near a border at up to 8 cells: a few float ulps of 1, with room.
constexpr float kFloatSlack = 1e-5f;
// A globally trilinear field of magnitude <= 8 re-interpolated once by stitching: 8 rounded
// products and a rounded sum, each off by at most 2^-24 relative, plus the rounding of the
// probe positions; 1e-5 is about 20 ulps of 8 and still far below any real mismatch.
constexpr float kTrilinearTolerance = 1e-5f;

// splitmix64: deterministic pseudo-random numbers from an index (fixed seeds, no clock).
uint64_t mix(uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

// Uniform in [0, 1).
float unitFloat(uint64_t index) {
    return float(mix(index) >> 40) / float(uint64_t(1) << 24);
}

size_t cellIndex(glm::uvec3 cells, glm::uvec3 c) {
    return c.x + size_t(cells.x) * (c.y + size_t(cells.y) * c.z);
}

// Top bricks 2 x 1 x 2, max level 2 (finest cells 8 x 4 x 8):
//   top (1,0,0) and (0,0,1) stay at level 0;
//   top (0,0,0) splits into 8 level-1 bricks, of which (1,0,0) splits again into 8 level-2
//     bricks; the level-2 bricks at x = 3 touch the level-0 brick top (1,0,0);
//   top (1,0,1) splits into 8 level-1 bricks, touching both level-0 bricks on faces and the
//     level-1 bricks of top (0,0,0) along an edge.
// Bricks are listed in a scrambled order: the layout allows any.
constexpr glm::uvec3 kMixedTop{2, 1, 2};
constexpr uint32_t kMixedMaxLevel = 2;

BrickLayout mixedLayout() {
    std::vector<Brick> bricks;
    bricks.push_back({glm::uvec3(1, 0, 0), 0});
    for (uint32_t z = 0; z < 2; ++z) {
        for (uint32_t y = 0; y < 2; ++y) {
            for (uint32_t x = 0; x < 2; ++x) {
                bricks.push_back({glm::uvec3(2 + x, y, z), 2});
                bricks.push_back({glm::uvec3(2 + x, y, 2 + z), 1});
                if (glm::uvec3(x, y, z) != glm::uvec3(1, 0, 0)) {
                    bricks.push_back({glm::uvec3(x, y, z), 1});
                }
            }
        }
    }
    bricks.push_back({glm::uvec3(0, 0, 1), 0});
    return BrickLayout{kMixedMaxLevel, bricks};
}

// The same top bricks, nested (bricktest::nestedLayout, also used by the sampler and GPU
// tests): all four level-0 bricks; in top (0,0,0) the level-1 bricks of octants 0, 3 and 5
// only; under level-1 (0,0,0) the level-2 bricks (1,0,0), (0,1,0) and (1,1,1); and in top
// (1,0,0) a lone level-2 brick (5,2,1) with no level-1 brick above it.
BrickLayout nestedLayout() {
    return bricktest::nestedLayout(kMixedTop);
}

uint32_t findBrick(const BrickLayout& layout, glm::uvec3 coord, uint8_t level) {
    const auto it = std::find(layout.bricks.begin(), layout.bricks.end(), Brick{coord, level});
    EXPECT_NE(it, layout.bricks.end()) << "no brick at level " << int(level);
    return uint32_t(it - layout.bricks.begin());
}

std::vector<uint32_t> mustBuild(glm::uvec3 top, const BrickLayout& layout) {
    auto built = buildIndirection(top, layout, "test");
    EXPECT_TRUE(built.ok()) << (built.ok() ? "" : built.error().message);
    return built.ok() ? built.value() : std::vector<uint32_t>{};
}

// Samples the bricked field at a point in finest-cell units, as the runtime does.
sh::ShRgb sampleField(glm::uvec3 top, const BrickLayout& layout,
                      std::span<const uint32_t> indirection, std::span<const sh::ShRgb> probes,
                      glm::vec3 cell_coord) {
    const BrickSample s = locate(top, layout, indirection, cell_coord);
    return interpolate(probes.subspan(size_t(s.brick) * kBrickProbeCount, kBrickProbeCount),
                       s.local);
}

float maxAbsDifference(const sh::ShRgb& a, const sh::ShRgb& b) {
    float most = 0.0f;
    for (size_t i = 0; i < a.rgb.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            most = std::max(most, std::abs(a.rgb[i][c] - b.rgb[i][c]));
        }
    }
    return most;
}

// Independent values in [-1, 1] for every coefficient of every probe: bricks disagree on their
// shared border probes until stitched.
std::vector<sh::ShRgb> randomProbes(size_t brick_count, uint64_t seed) {
    std::vector<sh::ShRgb> probes(brick_count * kBrickProbeCount);
    for (size_t p = 0; p < probes.size(); ++p) {
        for (size_t i = 0; i < sh::kMaxCoefficients; ++i) {
            for (int c = 0; c < 3; ++c) {
                probes[p].rgb[i][c] = 2.0f * unitFloat(seed ^ (p * 64 + i * 3 + c)) - 1.0f;
            }
        }
    }
    return probes;
}

// Probe values as a function of the position (lattice coordinate), one function per
// coefficient and channel.
template <class Field>
std::vector<sh::ShRgb> probesFromField(const BrickLayout& layout, Field field) {
    std::vector<sh::ShRgb> probes(layout.bricks.size() * kBrickProbeCount);
    for (size_t b = 0; b < layout.bricks.size(); ++b) {
        for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
            const glm::uvec3 local(k % 4, (k / 4) % 4, k / 16);
            const glm::uvec3 lattice = latticeCoord(layout.bricks[b], local, layout.maxLevel);
            for (size_t i = 0; i < sh::kMaxCoefficients; ++i) {
                for (int c = 0; c < 3; ++c) {
                    probes[b * kBrickProbeCount + k].rgb[i][c] = field(lattice, i * 3 + c);
                }
            }
        }
    }
    return probes;
}

// --- buildIndirection -------------------------------------------------------------------------

TEST(BrickIndirection, UniformLayoutMapsEachCellToItsBrick) {
    const glm::uvec3 top(2, 1, 1);
    const BrickLayout fine = uniformLayout(top, 1);
    EXPECT_EQ(fine.bricks.size(), 16u);
    std::vector<uint32_t> identity(16);
    std::iota(identity.begin(), identity.end(), 0u);
    EXPECT_EQ(mustBuild(top, fine), identity) << "one finest cell per brick, both x fastest";

    // Level-0 bricks under max level 1: each covers 2 x 2 x 2 finest cells of a 4 x 2 x 2 grid.
    const BrickLayout coarse{1, uniformLayout(top, 0).bricks};
    const std::vector<uint32_t> indirection = mustBuild(top, coarse);
    ASSERT_EQ(indirection.size(), 16u);
    for (uint32_t z = 0; z < 2; ++z) {
        for (uint32_t y = 0; y < 2; ++y) {
            for (uint32_t x = 0; x < 4; ++x) {
                EXPECT_EQ(indirection[cellIndex({4, 2, 2}, {x, y, z})], x / 2)
                    << x << "," << y << "," << z;
            }
        }
    }
}

TEST(BrickIndirection, MixedLayoutEntriesNameTheCoveringBrick) {
    const BrickLayout layout = mixedLayout();
    ASSERT_EQ(layout.bricks.size(), 25u);
    const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
    const glm::uvec3 cells = finestCells(kMixedTop, kMixedMaxLevel);
    ASSERT_EQ(cells, glm::uvec3(8, 4, 8));
    ASSERT_EQ(indirection.size(), 256u);

    // Hand-picked cells.
    EXPECT_EQ(indirection[cellIndex(cells, {0, 0, 0})], findBrick(layout, {0, 0, 0}, 1));
    EXPECT_EQ(indirection[cellIndex(cells, {1, 3, 1})], findBrick(layout, {0, 1, 0}, 1));
    EXPECT_EQ(indirection[cellIndex(cells, {2, 0, 0})], findBrick(layout, {2, 0, 0}, 2));
    EXPECT_EQ(indirection[cellIndex(cells, {3, 1, 1})], findBrick(layout, {3, 1, 1}, 2));
    EXPECT_EQ(indirection[cellIndex(cells, {3, 3, 1})], findBrick(layout, {1, 1, 0}, 1));
    EXPECT_EQ(indirection[cellIndex(cells, {4, 0, 0})], 0u); // top (1,0,0), listed first
    EXPECT_EQ(indirection[cellIndex(cells, {7, 3, 3})], 0u);
    EXPECT_EQ(indirection[cellIndex(cells, {0, 0, 4})], 24u); // top (0,0,1), listed last
    EXPECT_EQ(indirection[cellIndex(cells, {7, 3, 7})], findBrick(layout, {3, 1, 3}, 1));

    // Every cell, against a brute-force search: the one brick whose region contains it.
    for (uint32_t z = 0; z < cells.z; ++z) {
        for (uint32_t y = 0; y < cells.y; ++y) {
            for (uint32_t x = 0; x < cells.x; ++x) {
                std::vector<uint32_t> covering;
                for (uint32_t b = 0; b < layout.bricks.size(); ++b) {
                    const uint32_t span = 1u << (kMixedMaxLevel - layout.bricks[b].level);
                    if (glm::uvec3(x, y, z) / span == layout.bricks[b].coord) {
                        covering.push_back(b);
                    }
                }
                ASSERT_EQ(covering.size(), 1u) << x << "," << y << "," << z;
                EXPECT_EQ(indirection[cellIndex(cells, {x, y, z})], covering[0]);
            }
        }
    }
}

TEST(BrickIndirection, NestedLayoutEntriesNameTheDeepestCoveringBrick) {
    const BrickLayout layout = nestedLayout();
    const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
    const glm::uvec3 cells = finestCells(kMixedTop, kMixedMaxLevel);
    ASSERT_EQ(indirection.size(), 256u);
    EXPECT_EQ(indirection[cellIndex(cells, {0, 0, 0})], findBrick(layout, {0, 0, 0}, 1));
    EXPECT_EQ(indirection[cellIndex(cells, {1, 0, 0})], findBrick(layout, {1, 0, 0}, 2));
    EXPECT_EQ(indirection[cellIndex(cells, {0, 2, 0})], findBrick(layout, {0, 0, 0}, 0))
        << "an octant without a finer brick shows the level-0 brick";
    EXPECT_EQ(indirection[cellIndex(cells, {2, 2, 0})], findBrick(layout, {1, 1, 0}, 1));
    EXPECT_EQ(indirection[cellIndex(cells, {5, 2, 1})], findBrick(layout, {5, 2, 1}, 2))
        << "a level-2 brick shows without a level-1 brick above it";
    EXPECT_EQ(indirection[cellIndex(cells, {4, 0, 0})], findBrick(layout, {1, 0, 0}, 0));
    std::vector<uint32_t> shown_cells(layout.bricks.size(), 0);
    for (uint32_t z = 0; z < cells.z; ++z) {
        for (uint32_t y = 0; y < cells.y; ++y) {
            for (uint32_t x = 0; x < cells.x; ++x) {
                int deepest = -1;
                for (uint32_t b = 0; b < layout.bricks.size(); ++b) {
                    const uint32_t span = 1u << (kMixedMaxLevel - layout.bricks[b].level);
                    if (glm::uvec3(x, y, z) / span == layout.bricks[b].coord &&
                        (deepest < 0 || layout.bricks[b].level > layout.bricks[deepest].level)) {
                        deepest = int(b);
                    }
                }
                ASSERT_GE(deepest, 0);
                EXPECT_EQ(indirection[cellIndex(cells, {x, y, z})], uint32_t(deepest))
                    << x << "," << y << "," << z;
                ++shown_cells[indirection[cellIndex(cells, {x, y, z})]];
            }
        }
    }
    // Level-0 (0,0,0) covers 64 cells; its three level-1 octants take 3 x 8 of them, and the
    // level-2 bricks 3 of level-1 (0,0,0)'s 8.
    EXPECT_EQ(shown_cells[findBrick(layout, {0, 0, 0}, 0)], 64u - 24u);
    EXPECT_EQ(shown_cells[findBrick(layout, {0, 0, 0}, 1)], 8u - 3u);
    EXPECT_EQ(shown_cells[findBrick(layout, {1, 0, 0}, 0)], 64u - 1u);
    EXPECT_EQ(shown_cells[findBrick(layout, {1, 0, 1}, 0)], 64u);
}

void expectRejected(glm::uvec3 top, const BrickLayout& layout, ErrorCode code,
                    const std::string& fragment) {
    const auto built = buildIndirection(top, layout, "volume 'hall'");
    ASSERT_FALSE(built.ok()) << "accepted; expected: " << fragment;
    EXPECT_EQ(built.error().code, code) << built.error().message;
    EXPECT_TRUE(built.error().message.starts_with("volume 'hall': ")) << built.error().message;
    EXPECT_NE(built.error().message.find(fragment), std::string::npos)
        << "message: " << built.error().message << "\nexpected fragment: " << fragment;
}

TEST(BrickIndirection, RejectsMaxLevelAboveThree) {
    expectRejected({1, 1, 1}, BrickLayout{4, uniformLayout({1, 1, 1}, 0).bricks},
                   ErrorCode::OutOfRange, "max_level 4 exceeds 3");
}

TEST(BrickIndirection, RejectsTooManyFinestCells) {
    // 256^3 top bricks at max level 1: 2^27 finest cells, 8x the limit. Fails before the
    // indirection (or anything per brick) is allocated.
    expectRejected({256, 256, 256}, BrickLayout{1, {}}, ErrorCode::OutOfRange,
                   "134217728 finest cells exceed the limit of 16777216");
}

TEST(BrickIndirection, RejectsLevelAboveMaxLevel) {
    BrickLayout layout = uniformLayout({2, 1, 1}, 1);
    layout.bricks[3].level = 2;
    expectRejected({2, 1, 1}, layout, ErrorCode::OutOfRange,
                   "brick 3 (level 2, coord 3,0,0): level exceeds max_level 1");
}

TEST(BrickIndirection, RejectsCoordOutsideItsLevel) {
    BrickLayout layout = uniformLayout({2, 1, 1}, 1);
    layout.bricks[5].coord = glm::uvec3(1, 2, 0);
    expectRejected({2, 1, 1}, layout, ErrorCode::OutOfRange,
                   "brick 5 (level 1, coord 1,2,0): coord outside the level's 4x2x2 grid");
}

TEST(BrickIndirection, RejectsARepeatedBrick) {
    BrickLayout layout = uniformLayout({2, 1, 1}, 1);
    layout.bricks.push_back({glm::uvec3(1, 1, 0), 1}); // brick 5 again
    expectRejected({2, 1, 1}, layout, ErrorCode::InconsistentSize,
                   "brick 16 (level 1, coord 1,1,0) repeats brick 5");
}

TEST(BrickIndirection, RejectsGap) {
    BrickLayout layout = uniformLayout({2, 1, 1}, 1);
    layout.bricks.erase(layout.bricks.begin() + 6); // coord (2,1,0)
    expectRejected({2, 1, 1}, layout, ErrorCode::InconsistentSize,
                   "finest cell 2,1,0 is covered by no brick");
}

// --- locate -------------------------------------------------------------------------------------

TEST(BrickLocate, KnownPoints) {
    const BrickLayout layout = mixedLayout();
    const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    struct Case {
        glm::vec3 point; // finest-cell units
        uint32_t brick;
        glm::vec3 local;
    };
    const Case cases[] = {
        // Inside a level-1 brick (span 2 finest cells, so 3/2 local units per cell).
        {{1.5f, 0.5f, 0.5f}, findBrick(layout, {0, 0, 0}, 1), {2.25f, 0.75f, 0.75f}},
        // Exactly on the border between a level-1 brick (cells 0..1) and a level-2 brick
        // (cell 2): the cell rule picks the brick on the + side.
        {{2.0f, 0.5f, 0.5f}, findBrick(layout, {2, 0, 0}, 2), {0.0f, 1.5f, 1.5f}},
        // Level-2 brick next to the level-0 brick, just before the border and on it.
        {{3.5f, 1.0f, 1.0f}, findBrick(layout, {3, 1, 1}, 2), {1.5f, 0.0f, 0.0f}},
        {{4.0f, 1.0f, 1.0f}, 0, {0.0f, 0.75f, 0.75f}},
        // Box max faces: the last cell, local 3.
        {{8.0f, 4.0f, 8.0f}, findBrick(layout, {3, 1, 3}, 1), {3.0f, 3.0f, 3.0f}},
        {{8.0f, 0.0f, 0.0f}, 0, {3.0f, 0.0f, 0.0f}},
        // Outside the box: clamped to the faces; NaN counts as 0.
        {{-5.0f, 100.0f, nan}, findBrick(layout, {0, 1, 0}, 1), {0.0f, 3.0f, 0.0f}},
        {{nan, nan, nan}, findBrick(layout, {0, 0, 0}, 1), {0.0f, 0.0f, 0.0f}},
        {{1e30f, -1e30f, 6.0f}, findBrick(layout, {3, 0, 3}, 1), {3.0f, 0.0f, 0.0f}},
        // A level-0 brick (span 4): 3/4 local units per cell.
        {{1.0f, 3.0f, 7.0f}, 24, {0.75f, 2.25f, 2.25f}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(testing::Message()
                     << "point " << c.point.x << "," << c.point.y << "," << c.point.z);
        const BrickSample s = locate(kMixedTop, layout, indirection, c.point);
        EXPECT_EQ(s.brick, c.brick);
        EXPECT_EQ(s.local, c.local); // dyadic values: exact
    }
}

// --- interpolate --------------------------------------------------------------------------------

// A trilinear function with dyadic coefficients: at dyadic points (multiples of 1/8) every
// product and sum in interpolate is exact in float, so the comparison can be exact too.
double trilinear(glm::dvec3 p, size_t variant) {
    const double v = double(variant);
    return 1.0 + v + 2.0 * p.x - 3.0 * p.y + 0.5 * p.z + 0.25 * p.x * p.y - p.x * p.z +
           0.5 * p.y * p.z + 0.125 * (1.0 + v) * p.x * p.y * p.z;
}

TEST(BrickInterpolate, ReproducesATrilinearFunctionExactly) {
    std::vector<sh::ShRgb> probes(kBrickProbeCount);
    for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
        const glm::dvec3 at(k % 4, (k / 4) % 4, k / 16);
        for (size_t i = 0; i < sh::kMaxCoefficients; ++i) {
            for (int c = 0; c < 3; ++c) {
                probes[k].rgb[i][c] = float(trilinear(at, i * 3 + c));
            }
        }
    }
    size_t checked = 0;
    for (uint32_t z = 0; z <= 24; z += 3) {
        for (uint32_t y = 0; y <= 24; y += 1) {
            for (uint32_t x = 0; x <= 24; x += 5) {
                const glm::vec3 local = glm::vec3(x, y, z) / 8.0f; // 0 .. 3 inclusive
                const sh::ShRgb got = interpolate(probes, local);
                for (size_t i = 0; i < sh::kMaxCoefficients; ++i) {
                    for (int c = 0; c < 3; ++c) {
                        ASSERT_EQ(got.rgb[i][c], float(trilinear(glm::dvec3(local), i * 3 + c)))
                            << "local " << local.x << "," << local.y << "," << local.z;
                    }
                }
                ++checked;
            }
        }
    }
    EXPECT_EQ(checked, 9u * 25u * 5u);
}

// --- stitchBorders ------------------------------------------------------------------------------

// Largest jump of the field across every finest-cell border plane, sampled at points on lines
// crossing the plane: kBorderOffset before and after it. The other two coordinates are random,
// and a quarter of the time snapped to a cell border (edges and corners of bricks).
float largestBorderJump(const BrickLayout& layout, std::span<const uint32_t> indirection,
                        std::span<const sh::ShRgb> probes, uint64_t seed, size_t* samples) {
    const glm::uvec3 cells = finestCells(kMixedTop, layout.maxLevel);
    float largest = 0.0f;
    uint64_t n = 0;
    for (int axis = 0; axis < 3; ++axis) {
        for (uint32_t plane = 1; plane < cells[axis]; ++plane) {
            for (int line = 0; line < 200; ++line, ++n) {
                glm::vec3 p;
                for (int a = 0; a < 3; ++a) {
                    const float u = unitFloat(seed ^ (n * 8 + a)) * float(cells[a]);
                    const bool snap = (mix(seed ^ (n * 8 + 3 + a)) & 3) == 0;
                    p[a] = snap ? std::round(u) : u;
                }
                glm::vec3 before = p, after = p;
                before[axis] = float(plane) - kBorderOffset;
                after[axis] = float(plane) + kBorderOffset;
                const float jump =
                    maxAbsDifference(sampleField(kMixedTop, layout, indirection, probes, before),
                                     sampleField(kMixedTop, layout, indirection, probes, after));
                largest = std::max(largest, jump);
            }
        }
    }
    *samples = n;
    return largest;
}

TEST(BrickStitch, MixedLevelsBecomeContinuous) {
    const BrickLayout layout = mixedLayout();
    const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
    const std::vector<sh::ShRgb> raw = randomProbes(layout.bricks.size(), 0x5EED);
    std::vector<sh::ShRgb> stitched = raw;
    stitchBorders(kMixedTop, layout, indirection, stitched);

    // Inside one brick the field is trilinear in brick-local units, so its slope along an axis
    // is at most the largest difference of two probes (2, values in [-1, 1]) per local unit;
    // level-2 bricks have 3 local units per finest cell. Crossing 2 * kBorderOffset cells:
    const float max_probe_difference = 2.0f;
    const float bound = max_probe_difference * 3.0f * 2.0f * kBorderOffset + kFloatSlack;

    size_t samples = 0;
    const float jump_stitched = largestBorderJump(layout, indirection, stitched, 7, &samples);
    size_t samples_raw = 0;
    const float jump_raw = largestBorderJump(layout, indirection, raw, 7, &samples_raw);
    EXPECT_EQ(samples, (7u + 3u + 7u) * 200u);
    EXPECT_LE(jump_stitched, bound) << "largest jump across a border after stitching";
    // Without stitching the same measurement sees the seams: the test can fail.
    EXPECT_GT(jump_raw, 100.0f * bound) << "unstitched data should show seams";
    RecordProperty("jump_stitched", testing::PrintToString(jump_stitched));
    RecordProperty("jump_unstitched", testing::PrintToString(jump_raw));
    std::printf("[          ] largest border jump: stitched %.3g (bound %.3g), unstitched %.3g "
                "over %zu lines\n",
                double(jump_stitched), double(bound), double(jump_raw), samples);

    // Stitching only rewrites border probes of bricks that have a coarser or earlier neighbour:
    // interior probes, and every probe of the first-visited level-0 brick, are untouched.
    for (size_t b = 0; b < layout.bricks.size(); ++b) {
        for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
            const glm::uvec3 local(k % 4, (k / 4) % 4, k / 16);
            const auto inside = [](uint32_t i) { return i > 0 && i < 3; };
            const bool interior = inside(local.x) && inside(local.y) && inside(local.z);
            if (interior || b == 0) {
                ASSERT_EQ(stitched[b * kBrickProbeCount + k], raw[b * kBrickProbeCount + k])
                    << "brick " << b << " probe " << k;
            }
        }
    }
}

TEST(BrickStitch, NestedLayoutsBecomeContinuous) {
    // The hand-made nested layout, then random ones: every level-0 brick, then each level-1
    // and level-2 region's brick with probability 3/8, independently (a level-2 brick need not
    // have a level-1 parent).
    const float bound = 2.0f * 3.0f * 2.0f * kBorderOffset + kFloatSlack; // as above
    float worst = 0.0f;
    for (uint64_t trial = 0; trial <= 24; ++trial) {
        BrickLayout layout = nestedLayout();
        if (trial > 0) {
            layout = BrickLayout{kMixedMaxLevel, uniformLayout(kMixedTop, 0).bricks};
            for (uint32_t level = 1; level <= kMixedMaxLevel; ++level) {
                for (const Brick& b : uniformLayout(kMixedTop, level).bricks) {
                    if ((mix(trial * 1000 + layout.bricks.size() * 7 + level) & 7) < 3) {
                        layout.bricks.push_back(b);
                    }
                }
            }
        }
        const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
        const std::vector<sh::ShRgb> raw = randomProbes(layout.bricks.size(), trial);
        std::vector<sh::ShRgb> probes = raw;
        stitchBorders(kMixedTop, layout, indirection, probes);
        size_t samples = 0;
        const float jump = largestBorderJump(layout, indirection, probes, trial, &samples);
        EXPECT_LE(jump, bound) << "trial " << trial << ", " << layout.bricks.size() << " bricks";
        worst = std::max(worst, jump);
        if (trial == 0) {
            EXPECT_GT(largestBorderJump(layout, indirection, raw, trial, &samples), 100.0f * bound)
                << "unstitched data should show seams";
        }
    }
    std::printf("[          ] 25 nested layouts: largest border jump %.3g (bound %.3g)\n",
                double(worst), double(bound));
}

// Largest change stitching makes to a field trilinear over the whole box, which is what every
// brick interpolates exactly, so the coarse neighbours' interpolation at a border probe is the
// probe's own value.
float stitchChangeOfGlobalTrilinearField(const BrickLayout& layout) {
    const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
    const glm::vec3 lattice_points = glm::vec3(finestCells(kMixedTop, kMixedMaxLevel) * 3u);
    const std::vector<sh::ShRgb> probes =
        probesFromField(layout, [&](glm::uvec3 lattice, size_t variant) {
            const glm::dvec3 p = glm::dvec3(glm::vec3(lattice) / lattice_points); // 0..1
            return float(trilinear(p, variant % 4) - 1.0);
        });
    std::vector<sh::ShRgb> stitched = probes;
    stitchBorders(kMixedTop, layout, indirection, stitched);
    float largest = 0.0f;
    for (size_t p = 0; p < probes.size(); ++p) {
        largest = std::max(largest, maxAbsDifference(stitched[p], probes[p]));
    }
    return largest;
}

TEST(BrickStitch, GloballyTrilinearFieldIsUnchanged) {
    EXPECT_LE(stitchChangeOfGlobalTrilinearField(mixedLayout()), kTrilinearTolerance);
    EXPECT_LE(stitchChangeOfGlobalTrilinearField(nestedLayout()), kTrilinearTolerance);
}

// stitchBorders checks its sizes, levels and indirection entries in every build type
// (brick.hpp, ARCHITECTURE.md "Preconditions"): each of these would index past a span.
TEST(BrickStitchDeathTest, ChecksItsPreconditions) {
    const BrickLayout layout = mixedLayout();
    const std::vector<uint32_t> indirection = mustBuild(kMixedTop, layout);
    const std::vector<sh::ShRgb> probes = randomProbes(layout.bricks.size(), 0x5EED);
    std::vector<sh::ShRgb> copy = probes;
    const std::span<const uint32_t> short_indirection(indirection.data(), indirection.size() - 1);
    EXPECT_DEATH(stitchBorders(kMixedTop, layout, short_indirection, copy),
                 "precondition failed in stitchBorders: indirection.size\\(\\) ==");
    std::span<sh::ShRgb> short_probes(copy.data(), copy.size() - 1);
    EXPECT_DEATH(stitchBorders(kMixedTop, layout, indirection, short_probes),
                 "precondition failed in stitchBorders: probes.size\\(\\) ==");
    const std::vector<uint8_t> short_visibility(probes.size() * visibility::kBytesPerProbe - 1);
    EXPECT_DEATH(stitchBorders(kMixedTop, layout, indirection, copy, short_visibility),
                 "precondition failed in stitchBorders: visibility.empty\\(\\) \\|\\|");
    std::vector<uint32_t> stray = indirection;
    stray[0] = uint32_t(layout.bricks.size());
    EXPECT_DEATH(stitchBorders(kMixedTop, layout, stray, copy),
                 "precondition failed in stitchBorders: indirection_names_listed_bricks");
    BrickLayout too_deep = layout;
    too_deep.bricks[0].level = uint8_t(layout.maxLevel + 1);
    EXPECT_DEATH(stitchBorders(kMixedTop, too_deep, indirection, copy),
                 "precondition failed in stitchBorders: levels_within_max_level");
    BrickLayout past_max = layout;
    past_max.maxLevel = kMaxLevel + 1;
    EXPECT_DEATH(stitchBorders(kMixedTop, past_max, indirection, copy),
                 "precondition failed in stitchBorders: layout.maxLevel <= kMaxLevel");
    // The valid call still runs.
    stitchBorders(kMixedTop, layout, indirection, copy);
}

} // namespace
} // namespace probekit::brick
