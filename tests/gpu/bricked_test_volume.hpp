// Bricked test volumes (formats/.../brick.hpp) for the CPU sampler tests (tests/unit) and the GPU
// tests: a mixed-level layout, a nested one and volumes filled from a field at every brick probe's
// position. Header-only and formats-only, so both test executables can use it.
#pragma once

#include <functional>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "probekit/formats/brick.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::bricktest {

// Levels 0..2 over `top` level-0 regions: region 0 splits into eight level-1 regions, the first
// of which splits into eight level-2 regions; every other region stays one level-0 brick. So
// there are level 0/1, 0/2 and 1/2 borders.
inline brick::BrickLayout mixedLayout(glm::uvec3 top) {
    brick::BrickLayout layout;
    layout.maxLevel = 2;
    for (uint32_t z = 0; z < top.z; ++z) {
        for (uint32_t y = 0; y < top.y; ++y) {
            for (uint32_t x = 0; x < top.x; ++x) {
                if (x + y + z > 0) {
                    layout.bricks.push_back({glm::uvec3(x, y, z), 0});
                }
            }
        }
    }
    for (uint32_t child = 1; child < 8; ++child) {
        layout.bricks.push_back({glm::uvec3(child & 1, (child >> 1) & 1, child >> 2), 1});
    }
    for (uint32_t child = 0; child < 8; ++child) {
        layout.bricks.push_back({glm::uvec3(child & 1, (child >> 1) & 1, child >> 2), 2});
    }
    return layout;
}

// Nested levels 0..2 over `top` level-0 regions (brick.hpp: the deepest brick over a point
// shows): every level-0 brick; in region 0 the level-1 bricks of octants 0, 3 and 5 only (the
// level-0 brick shows in the other five); under level-1 octant 0, level-2 bricks in 3 of its
// 8 octants; and in region 1 (if any) a lone level-2 brick with no level-1 brick above it.
inline brick::BrickLayout nestedLayout(glm::uvec3 top) {
    brick::BrickLayout layout = brick::uniformLayout(top, 0);
    layout.maxLevel = 2;
    for (uint32_t child : {0u, 3u, 5u}) {
        layout.bricks.push_back({glm::uvec3(child & 1, (child >> 1) & 1, child >> 2), 1});
    }
    for (uint32_t child : {1u, 2u, 7u}) {
        layout.bricks.push_back({glm::uvec3(child & 1, (child >> 1) & 1, child >> 2), 2});
    }
    if (top.x > 1) {
        layout.bricks.push_back({glm::uvec3(5, 2, 1), 2});
    }
    return layout;
}

// Local position (m) of probe k (0..63, x fastest) of brick b: on the finest level's probe
// lattice, box.min + latticeCoord * box.size / (3 * finestCells). Probes that bricks share get
// bit-identical positions.
inline glm::vec3 probeLocal(const VolumeDesc& desc, const brick::Brick& b, uint32_t k) {
    const glm::uvec3 local(k % 4, (k / 4) % 4, k / 16);
    const glm::uvec3 lattice = brick::latticeCoord(b, local, desc.bricks.maxLevel);
    const glm::uvec3 cells = brick::finestCells(desc.grid.resolution(), desc.bricks.maxLevel);
    const grid::Aabb& box = desc.grid.bounds();
    return box.min + glm::vec3(lattice) * box.size() / (3.0f * glm::vec3(cells));
}

// A bricked volume (desc.layout and desc.bricks set by the caller) whose probe at world position
// x holds field(x), truncated to L1 for L1 volumes; with `stitch`, brick::stitchBorders makes it
// continuous across level borders first.
inline Volume makeBrickedVolume(VolumeDesc desc,
                                const std::function<sh::ShRgb(glm::vec3 world)>& field,
                                bool stitch) {
    Result<std::vector<uint32_t>> indirection =
        brick::buildIndirection(desc.grid.resolution(), desc.bricks, desc.name);
    EXPECT_TRUE(indirection.ok()) << indirection.error().message;
    std::vector<sh::ShRgb> probes;
    for (const brick::Brick& b : desc.bricks.bricks) {
        for (uint32_t k = 0; k < brick::kBrickProbeCount; ++k) {
            probes.push_back(field(desc.grid.frame().toWorld(probeLocal(desc, b, k))));
        }
    }
    if (stitch) {
        brick::stitchBorders(desc.grid.resolution(), desc.bricks, indirection.value(), probes);
    }
    if (desc.shOrder == sh::Order::L1) {
        for (sh::ShRgb& p : probes) {
            p = sh::truncateToL1(p);
        }
    }
    Result<Volume> volume = makeVolume(std::move(desc), probes);
    EXPECT_TRUE(volume.ok()) << volume.error().message;
    return std::move(volume).value();
}

} // namespace probekit::bricktest
