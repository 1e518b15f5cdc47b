// probekit::brick — the bricked (adaptive) volume layout: a coarse level of bricks plus finer
// bricks where the scene needs them.
//
// The volume box (VolumeDesc::grid bounds and frame) is cut into
//   topBricks = VolumeDesc::grid.resolution()      (powers of two, 1..256 per axis)
// level-0 regions. A region at level l splits into 2 x 2 x 2 regions at level l + 1, down to
// level maxLevel (<= kMaxLevel = 3). A brick holds 4 x 4 x 4 probes at the corners of a
// 3 x 3 x 3 cell lattice over one region, so probes sit on the region's faces and
// neighbouring bricks hold copies of the same border probes. Each level is 2x denser than the
// one above it (probe spacing region size / 3, halved per level), and a level's probe lattice
// contains every coarser level's lattice.
//
// Bricks nest: a layout lists bricks at any levels, and at every point the deepest brick whose
// region contains it is the one that shows. A refined region therefore needs only the finer
// bricks of the octants that gain from them; the coarser brick still shows in the rest of its
// region. (A layout whose bricks tile the box without nesting is the special case where each
// brick shows everywhere in its region.) Every point of the box must lie in some brick, and no
// brick may be listed twice.
//
// Continuity (no seams): where two bricks that show meet, the finer one's border probes are
// "stitched" to the coarser brick's interpolation at those points (same-level neighbours share
// their border probes). Trilinear interpolation of samples of a piecewise-trilinear function
// on a nested lattice reproduces it, so the field is continuous across brick and level borders.
//
// Finest cells: the box split into N = topBricks * 2^maxLevel cells per axis (a brick at level
// l covers 2^(maxLevel - l) finest cells per axis). The indirection maps every finest cell
// (x fastest) to the index of the deepest brick covering it; this is what the runtime uploads
// as its indirection texture, and buildIndirection is also the layout check.
//
// Probe data of a bricked Volume: probeCount() = bricks.size() * 64; probe k belongs to brick
// k / 64, at brick-local (x, y, z) with k % 64 = x + 4 * (y + 4 * z). Texel planes and validity
// are stored exactly as for a dense volume over those probes (volume.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"

namespace probekit::brick {

constexpr uint32_t kBrickSize = 4;        // probes per brick edge
constexpr uint32_t kBrickCells = 3;       // cells per brick edge (kBrickSize - 1)
constexpr uint32_t kBrickProbeCount = 64; // kBrickSize^3
constexpr uint32_t kMaxLevel = 3;         // finest level (levels 0..3: 1x, 2x, 4x, 8x density)
// Indirection entries a file may ask for (64 MiB of u32): bounds the allocation of a forged file.
constexpr uint64_t kMaxFinestCells = uint64_t(1) << 24;

struct Brick {
    glm::uvec3 coord{0u}; // region index at its level: coord < topBricks * 2^level per axis
    uint8_t level = 0;    // 0..maxLevel
    friend bool operator==(const Brick&, const Brick&) = default;
};

struct BrickLayout {
    uint32_t maxLevel = 0;     // deepest level the layout may use (sets the indirection size)
    std::vector<Brick> bricks; // in any order; each one's probes are 64 in a row
    friend bool operator==(const BrickLayout&, const BrickLayout&) = default;
};

// Finest cells per axis: topBricks * 2^maxLevel.
inline glm::uvec3 finestCells(glm::uvec3 top_bricks, uint32_t max_level) {
    return top_bricks * (1u << max_level);
}

// Probe-lattice coordinate of a brick's probe (x, y, z in 0..3) on the finest level's lattice:
// brick origin (coord * 3 * 2^(maxLevel - level)) + local * 2^(maxLevel - level). Lattice points
// are what bricks share: equal coordinates mean the same position. The lattice has
// 3 * finestCells + 1 points per axis.
inline glm::uvec3 latticeCoord(const Brick& b, glm::uvec3 local, uint32_t max_level) {
    const uint32_t step = 1u << (max_level - b.level);
    return (b.coord * kBrickCells + local) * step;
}

// Checks the layout against the volume's level-0 brick grid and builds the indirection:
// one entry per finest cell (x fastest) holding the index of the deepest brick covering it.
// Fails, naming `label` and the brick, when maxLevel > kMaxLevel, the finest cell count
// exceeds kMaxFinestCells, a brick's level exceeds maxLevel, its coord lies outside its
// level's grid, a brick repeats another (same level and coord), or a finest cell is covered
// by no brick.
Result<std::vector<uint32_t>> buildIndirection(glm::uvec3 top_bricks, const BrickLayout& layout,
                                               const std::string& label);

// Where one point samples a bricked volume (mirrored by shaders/probe_volume.glsl):
//   f = clamp(cell_coord, 0, N) per axis (N = finestCells; NaN -> 0), the point in finest-cell
//       units (box min at 0, box max at N);
//   c = min(floor(f), N - 1)  the finest cell, b = indirection[c] the brick covering it;
//   s = 2^(maxLevel - level of b), origin = (c / s) * s (integer division): the brick's first
//       finest cell;
//   local = clamp((f - origin) * 3 / s, 0, 3): brick-local probe coordinates (probe i at i).
// On a border between bricks the cell rule picks one of them; stitched data (stitchBorders)
// makes both give the same value there.
struct BrickSample {
    uint32_t brick = 0;    // index into layout.bricks
    glm::vec3 local{0.0f}; // in [0, 3]
};
BrickSample locate(glm::uvec3 top_bricks, const BrickLayout& layout,
                   std::span<const uint32_t> indirection, glm::vec3 cell_coord);

// Trilinear interpolation of one brick's 64 probes (x fastest) at brick-local coordinates in
// [0, 3] (an axis at exactly 3 uses the last probe alone). With the brick's visibility bytes
// (64 x visibility::kBytesPerProbe), the visibility-weighted interpolation of visibility.hpp,
// as runtime::sampleVolumeSh does it.
sh::ShRgb interpolate(std::span<const sh::ShRgb> brick_probes, glm::vec3 local,
                      std::span<const uint8_t> brick_visibility = {});

// Makes the bricked field continuous (see the top of this file). Visits bricks by ascending
// level, then index; for every probe on its brick's boundary, finds the bricks that show (by
// the indirection) in the finest cells touching that point and takes the one of lowest level
// (ties: lowest index), or the brick itself if it precedes them; when that is another brick,
// the probe is replaced by the other brick's interpolation at the point. Coarser bricks and
// earlier same-level bricks are final before any brick reads them, so the result does not
// depend on anything but the layout. `probes` holds 64 per brick (brick order, as stored).
// With visibility (Volume::visibility, brick order), the other brick's interpolation is the
// visibility-weighted one, so a stitched probe takes exactly what the coarser side shows at its
// point; between stitched probes the two sides then agree up to the field's variation within a
// finer cell, no longer exactly (visibility-weighted interpolation is not piecewise trilinear).
// Preconditions (checked in every build type; a failure prints the condition and aborts,
// ARCHITECTURE.md "Preconditions"): maxLevel <= kMaxLevel and every brick's level <= maxLevel;
// `indirection` has one entry per finest cell, each the index of a listed brick (what
// buildIndirection returns); `probes` holds 64 per brick; `visibility` is empty or
// visibility::kBytesPerProbe per probe.
void stitchBorders(glm::uvec3 top_bricks, const BrickLayout& layout,
                   std::span<const uint32_t> indirection, std::span<sh::ShRgb> probes,
                   std::span<const uint8_t> visibility = {});

// Every brick covering the whole box at `level` (maxLevel = level), x fastest: a uniform layout.
BrickLayout uniformLayout(glm::uvec3 top_bricks, uint32_t level);

} // namespace probekit::brick
