#include "probekit/formats/brick.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <glm/common.hpp>

#include "probekit/formats/check.hpp"
#include "probekit/formats/visibility.hpp"

namespace probekit::brick {

namespace {

std::string brickText(size_t index, const Brick& b) {
    return "brick " + std::to_string(index) + " (level " + std::to_string(b.level) + ", coord " +
           std::to_string(b.coord.x) + "," + std::to_string(b.coord.y) + "," +
           std::to_string(b.coord.z) + ")";
}

} // namespace

Result<std::vector<uint32_t>> buildIndirection(glm::uvec3 top_bricks, const BrickLayout& layout,
                                               const std::string& label) {
    if (layout.maxLevel > kMaxLevel) {
        return makeError(ErrorCode::OutOfRange, label + ": max_level " +
                                                    std::to_string(layout.maxLevel) + " exceeds " +
                                                    std::to_string(kMaxLevel));
    }
    const glm::uvec3 cells = finestCells(top_bricks, layout.maxLevel);
    const uint64_t cell_count = uint64_t(cells.x) * cells.y * cells.z;
    if (cell_count > kMaxFinestCells) {
        return makeError(ErrorCode::OutOfRange, label + ": " + std::to_string(cell_count) +
                                                    " finest cells exceed the limit of " +
                                                    std::to_string(kMaxFinestCells) +
                                                    " (fewer levels or top bricks)");
    }
    if (layout.bricks.size() >= std::numeric_limits<uint32_t>::max()) {
        return makeError(ErrorCode::OutOfRange, label + ": too many bricks");
    }
    constexpr uint32_t kUncovered = std::numeric_limits<uint32_t>::max();
    for (size_t i = 0; i < layout.bricks.size(); ++i) {
        const Brick& b = layout.bricks[i];
        if (b.level > layout.maxLevel) {
            return makeError(ErrorCode::OutOfRange, label + ": " + brickText(i, b) +
                                                        ": level exceeds max_level " +
                                                        std::to_string(layout.maxLevel));
        }
        const glm::uvec3 level_grid = top_bricks * (1u << b.level);
        if (b.coord.x >= level_grid.x || b.coord.y >= level_grid.y || b.coord.z >= level_grid.z) {
            return makeError(ErrorCode::OutOfRange,
                             label + ": " + brickText(i, b) + ": coord outside the level's " +
                                 std::to_string(level_grid.x) + "x" + std::to_string(level_grid.y) +
                                 "x" + std::to_string(level_grid.z) + " grid");
        }
    }
    // Coarse bricks first: a finer brick then overwrites the cells it covers, so every cell
    // ends up naming the deepest brick over it. Same-level regions coincide or are disjoint, so
    // meeting an entry of the same level means the brick is listed twice.
    std::vector<uint32_t> order(layout.bricks.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        return layout.bricks[a].level < layout.bricks[b].level;
    });
    std::vector<uint32_t> indirection(size_t(cell_count), kUncovered);
    for (const uint32_t i : order) {
        const Brick& b = layout.bricks[i];
        const uint32_t span = 1u << (layout.maxLevel - b.level);
        const glm::uvec3 first = b.coord * span;
        for (uint32_t z = first.z; z < first.z + span; ++z) {
            for (uint32_t y = first.y; y < first.y + span; ++y) {
                for (uint32_t x = first.x; x < first.x + span; ++x) {
                    uint32_t& entry = indirection[x + size_t(cells.x) * (y + size_t(cells.y) * z)];
                    if (entry != kUncovered && layout.bricks[entry].level == b.level) {
                        return makeError(ErrorCode::InconsistentSize,
                                         label + ": " + brickText(i, b) + " repeats brick " +
                                             std::to_string(entry));
                    }
                    entry = i;
                }
            }
        }
    }
    for (size_t c = 0; c < indirection.size(); ++c) {
        if (indirection[c] == kUncovered) {
            const size_t x = c % cells.x;
            const size_t y = (c / cells.x) % cells.y;
            const size_t z = c / (size_t(cells.x) * cells.y);
            return makeError(ErrorCode::InconsistentSize,
                             label + ": finest cell " + std::to_string(x) + "," +
                                 std::to_string(y) + "," + std::to_string(z) +
                                 " is covered by no brick");
        }
    }
    return indirection;
}

BrickSample locate(glm::uvec3 top_bricks, const BrickLayout& layout,
                   std::span<const uint32_t> indirection, glm::vec3 cell_coord) {
    const glm::uvec3 cells = finestCells(top_bricks, layout.maxLevel);
    glm::vec3 f;
    glm::uvec3 c;
    for (int a = 0; a < 3; ++a) {
        f[a] = std::isnan(cell_coord[a]) ? 0.0f : std::clamp(cell_coord[a], 0.0f, float(cells[a]));
        c[a] = std::min(uint32_t(f[a]), cells[a] - 1);
    }
    BrickSample sample;
    sample.brick = indirection[c.x + size_t(cells.x) * (c.y + size_t(cells.y) * c.z)];
    const uint32_t span = 1u << (layout.maxLevel - layout.bricks[sample.brick].level);
    const glm::uvec3 origin = (c / span) * span;
    sample.local = glm::clamp((f - glm::vec3(origin)) * (float(kBrickCells) / float(span)), 0.0f,
                              float(kBrickCells));
    return sample;
}

sh::ShRgb interpolate(std::span<const sh::ShRgb> brick_probes, glm::vec3 local,
                      std::span<const uint8_t> brick_visibility) {
    uint32_t first[3];
    float t[3];
    glm::vec3 g;
    for (int a = 0; a < 3; ++a) {
        g[a] = std::clamp(local[a], 0.0f, float(kBrickCells));
        first[a] = std::min(uint32_t(g[a]), kBrickCells - 1);
        t[a] = g[a] - float(first[a]);
    }
    const bool visible_weights = !brick_visibility.empty();
    sh::ShRgb out;
    float weight_sum = 0.0f;
    for (uint32_t k = 0; k < 8; ++k) {
        const uint32_t dx = k & 1, dy = (k >> 1) & 1, dz = k >> 2;
        float w = (dx ? t[0] : 1.0f - t[0]) * (dy ? t[1] : 1.0f - t[1]) * (dz ? t[2] : 1.0f - t[2]);
        if (w == 0.0f) {
            continue;
        }
        const glm::uvec3 tap(first[0] + dx, first[1] + dy, first[2] + dz);
        const uint32_t index = tap.x + kBrickSize * (tap.y + kBrickSize * tap.z);
        if (visible_weights) {
            w *= visibility::probeVisibility(&brick_visibility[visibility::kBytesPerProbe * index],
                                             g - glm::vec3(tap)) +
                 visibility::kFloor;
            weight_sum += w;
        }
        sh::ShRgb term = brick_probes[index];
        term *= w;
        out += term;
    }
    if (visible_weights) {
        out *= 1.0f / weight_sum;
    }
    return out;
}

namespace {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// The order bricks are stitched in: ascending level, then index.
struct StitchOrder {
    const BrickLayout& layout;
    bool operator()(uint32_t a, uint32_t b) const {
        const uint8_t level_a = layout.bricks[a].level, level_b = layout.bricks[b].level;
        return level_a < level_b || (level_a == level_b && a < b);
    }
};

// Per level l and level-l region: the first brick (by `precedes`) that shows anywhere in it.
std::vector<std::vector<uint32_t>> firstShownPerLevel(glm::uvec3 top_bricks,
                                                      const BrickLayout& layout,
                                                      std::span<const uint32_t> indirection,
                                                      StitchOrder precedes) {
    const glm::uvec3 cells = finestCells(top_bricks, layout.maxLevel);
    std::vector<std::vector<uint32_t>> first_shown(layout.maxLevel + 1);
    for (uint32_t l = 0; l <= layout.maxLevel; ++l) {
        const glm::uvec3 regions = top_bricks * (1u << l);
        const uint32_t shift = layout.maxLevel - l;
        std::vector<uint32_t>& first = first_shown[l];
        first.assign(size_t(regions.x) * regions.y * regions.z, kNone);
        for (uint32_t z = 0; z < cells.z; ++z) {
            for (uint32_t y = 0; y < cells.y; ++y) {
                for (uint32_t x = 0; x < cells.x; ++x) {
                    const uint32_t shown =
                        indirection[x + size_t(cells.x) * (y + size_t(cells.y) * z)];
                    uint32_t& entry =
                        first[(x >> shift) + size_t(regions.x) *
                                                 ((y >> shift) + size_t(regions.y) * (z >> shift))];
                    if (entry == kNone || precedes(shown, entry)) {
                        entry = shown;
                    }
                }
            }
        }
    }
    return first_shown;
}

// The brick a point at `lattice` of brick `self` takes its value from: the first (by
// `precedes`) shown in the regions of self's level around it (`first`: firstShownPerLevel's
// table for that level), self when none precedes it.
uint32_t stitchSource(const std::vector<uint32_t>& first, glm::uvec3 regions,
                      uint32_t region_points, glm::uvec3 lattice, uint32_t self,
                      StitchOrder precedes) {
    // The regions of the brick's level around the point (on a region border along an axis,
    // those on both sides).
    glm::uvec3 lo, hi;
    for (int a = 0; a < 3; ++a) {
        const uint32_t region = lattice[a] / region_points;
        const bool on_border = lattice[a] % region_points == 0;
        lo[a] = on_border && region > 0 ? region - 1 : region;
        hi[a] = std::min(region, regions[a] - 1);
    }
    uint32_t source = self;
    for (uint32_t z = lo.z; z <= hi.z; ++z) {
        for (uint32_t y = lo.y; y <= hi.y; ++y) {
            for (uint32_t x = lo.x; x <= hi.x; ++x) {
                const uint32_t other = first[x + size_t(regions.x) * (y + size_t(regions.y) * z)];
                if (precedes(other, source)) {
                    source = other;
                }
            }
        }
    }
    return source;
}

// Brick `source`'s value at the point `lattice` (weighted by its visibility, when given).
sh::ShRgb sampleBrickAt(const BrickLayout& layout, uint32_t source, glm::uvec3 lattice,
                        std::span<const sh::ShRgb> probes, std::span<const uint8_t> visibility) {
    const Brick& from = layout.bricks[source];
    // Powers of two: the division is exact in float.
    const uint32_t step = 1u << (layout.maxLevel - from.level);
    const glm::vec3 from_local =
        (glm::vec3(lattice) - glm::vec3(from.coord * (kBrickCells * step))) / float(step);
    constexpr size_t kBrickVisibility = kBrickProbeCount * visibility::kBytesPerProbe;
    return interpolate(
        probes.subspan(size_t(source) * kBrickProbeCount, kBrickProbeCount), from_local,
        visibility.empty() ? visibility
                           : visibility.subspan(source * kBrickVisibility, kBrickVisibility));
}

// Replaces the face probes of brick `self` by the values of the bricks that precede it there.
void stitchBrick(glm::uvec3 top_bricks, const BrickLayout& layout,
                 const std::vector<std::vector<uint32_t>>& first_shown, uint32_t self,
                 std::span<sh::ShRgb> probes, std::span<const uint8_t> visibility) {
    const StitchOrder precedes{layout};
    const auto on_face = [](uint32_t i) { return i == 0 || i == kBrickCells; };
    const Brick& own = layout.bricks[self];
    const glm::uvec3 regions = top_bricks * (1u << own.level);
    const uint32_t region_points = kBrickCells << (layout.maxLevel - own.level);
    const std::vector<uint32_t>& first = first_shown[own.level];
    for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
        const glm::uvec3 local(k % kBrickSize, (k / kBrickSize) % kBrickSize,
                               k / (kBrickSize * kBrickSize));
        if (!on_face(local.x) && !on_face(local.y) && !on_face(local.z)) {
            continue;
        }
        const glm::uvec3 lattice = latticeCoord(own, local, layout.maxLevel);
        const uint32_t source =
            stitchSource(first, regions, region_points, lattice, self, precedes);
        if (source != self) {
            probes[size_t(self) * kBrickProbeCount + k] =
                sampleBrickAt(layout, source, lattice, probes, visibility);
        }
    }
}

} // namespace

void stitchBorders(glm::uvec3 top_bricks, const BrickLayout& layout,
                   std::span<const uint32_t> indirection, std::span<sh::ShRgb> probes,
                   std::span<const uint8_t> visibility) {
    // Always on (ARCHITECTURE.md, "Preconditions"): every loop below indexes the indirection,
    // the per-level tables and the probe and visibility spans with these sizes, levels and
    // brick indices, unchecked. Linear in the cells, far below the stitching itself.
    PK_CHECK(layout.maxLevel <= kMaxLevel);
    const glm::uvec3 cells = finestCells(top_bricks, layout.maxLevel);
    PK_CHECK(indirection.size() == size_t(cells.x) * cells.y * cells.z);
    PK_CHECK(probes.size() == layout.bricks.size() * kBrickProbeCount);
    PK_CHECK(visibility.empty() || visibility.size() == probes.size() * visibility::kBytesPerProbe);
    const bool levels_within_max_level =
        std::all_of(layout.bricks.begin(), layout.bricks.end(),
                    [&layout](const Brick& b) { return b.level <= layout.maxLevel; });
    PK_CHECK(levels_within_max_level);
    const bool indirection_names_listed_bricks =
        std::all_of(indirection.begin(), indirection.end(),
                    [&layout](uint32_t b) { return b < layout.bricks.size(); });
    PK_CHECK(indirection_names_listed_bricks);
    const StitchOrder precedes{layout};
    const std::vector<std::vector<uint32_t>> first_shown =
        firstShownPerLevel(top_bricks, layout, indirection, precedes);
    // Ascending level, then index: every brick a probe may be replaced from is final by then.
    std::vector<uint32_t> order(layout.bricks.size());
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), precedes);
    for (const uint32_t self : order) {
        stitchBrick(top_bricks, layout, first_shown, self, probes, visibility);
    }
}

BrickLayout uniformLayout(glm::uvec3 top_bricks, uint32_t level) {
    BrickLayout layout;
    layout.maxLevel = level;
    const glm::uvec3 n = top_bricks * (1u << level);
    layout.bricks.reserve(size_t(n.x) * n.y * n.z);
    for (uint32_t z = 0; z < n.z; ++z) {
        for (uint32_t y = 0; y < n.y; ++y) {
            for (uint32_t x = 0; x < n.x; ++x) {
                layout.bricks.push_back(Brick{glm::uvec3(x, y, z), uint8_t(level)});
            }
        }
    }
    return layout;
}

} // namespace probekit::brick
