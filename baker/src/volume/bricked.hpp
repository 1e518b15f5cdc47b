// Bricked (adaptive) volumes: refinement by measured disagreement, the memory budget,
// dilation on the shared probe lattice and stitching (formats/.../brick.hpp has the layout).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::baker {

class RayTracer;

// Bakes probes at world positions: fills sh[i] and valid[i] (kProbeValid / kProbeInvalid) for
// positions[i], seeding each from ids[i] so that a probe's value depends only on its id.
using ProbeBatchFn =
    std::function<void(std::span<const glm::vec3> positions, std::span<const uint64_t> ids,
                       std::span<sh::ShRgb> sh, std::span<uint8_t> valid)>;

// Peak resident bytes per baked lattice probe of a bricked bake (SH, validity, visibility, the
// lattice's index and the batch buffers), rounded up from the courtyard at 16 samples: 0.24 M
// probes peaked at 369 MiB, 4.99 M at 2,845 MiB and 6.73 M at 4,357 MiB (520 to 910 B per probe
// above a ~250 MiB base that holds the scene and its BVH).
constexpr uint64_t kBakedProbeBytes = 1024;
// That base cannot be bargained away: below this working limit max_memory_mb bounds only the
// bricked volumes' GPU bytes (refinement is then limited by kMinWorkingBytes).
constexpr uint64_t kMinWorkingBytes = 256ull << 20;

// A bricked bake reads its settings where they live: the bake's config (dilate, nudge,
// backfaceThreshold, visibility, dering; maxMemoryBytes is the budget for the GPU bytes, texels
// + indirection) and the volume's (maxLevel, refineError, a fraction of the volume's RMS
// irradiance). The rest is what the run gives it.
struct BrickedSettings {
    const BakeConfig& config;
    const VolumeConfig& volume;
    // The bake's working memory for this volume (what BakeConfig::maxMemoryBytes leaves beside
    // the rest of the bake, memory_model.hpp): refinement tests no more candidate bricks than
    // the lattice can hold at kBakedProbeBytes per probe, the candidates with the largest
    // predicted disagreement first.
    uint64_t workingBytes = ~uint64_t(0);
    // Traces the direct-light pre-pass (shadow rays to punctual lights), the search for nudged
    // positions (config.nudge, bricked.cpp's Lattice::nudge) and the visibility (config.
    // visibility, visibility.hpp); null = none of them.
    const RayTracer* tracer = nullptr;
    uint32_t threads = 1; // for the visibility tracing and deringing
    // Told, before each batch, how many probes the levels still to be tested are expected to
    // add after it: as many per level as that batch (level 0's for level 1's test). On the
    // closed arena the tests of levels 0, 1 and 2 bake 251,419, 279,570 and about 300,000
    // probes after level 0's 122,317, so the guess is low while level 0 bakes and close after.
    // Null: not told. Ends with 0.
    std::function<void(uint64_t)> expectFurther;
    // Also store finer bricks whose probes are all inside geometry, as bakes did before
    // free-space bricks (bricked.cpp's insideGeometry): only for comparing the two layouts; the
    // bake never sets it.
    bool storeSolidBricks = false;
};

struct BrickedOutcome {
    VolumeDesc desc; // with desc.bricks filled in
    std::vector<sh::ShRgb> probes;
    std::vector<uint8_t> validity;
    std::vector<uint8_t> visibility; // empty unless BakeConfig::visibility
    // Per probe, what deringing before stitching did (dering.hpp: kNotDeringed, or the relative
    // change); empty unless BakeConfig::dering.
    std::vector<float> deringChanges;
    uint64_t bricksPerLevel[4] = {0, 0, 0, 0};
    uint64_t refineCandidates = 0;
    uint64_t budgetDropped = 0;
    double budgetError = 0.0;
    uint64_t memoryUntested = 0; // candidate bricks not tested: their probes would not fit
    double predictedError = 0.0; // RMS interpolation error, fraction of RMS irradiance
    uint64_t invalidProbes = 0;  // lattice points inside geometry among those written
    uint64_t nudgedProbes = 0;   // box-face lattice points baked just inside the box
    // Stored bricks whose every probe is inside geometry (invalid before dilation), by level:
    // they hold only dilated values.
    uint64_t solidBricksPerLevel[4] = {0, 0, 0, 0};
    std::vector<std::string> warnings;
};

// Error measure: irradiance at the six axis normals, every channel, relative to the volume's
// RMS irradiance (over its valid level-0 probes, the brightest 0.1% counted at the 99.9th
// percentile's value: irradianceScale), RMS over points. Monte Carlo noise is
// measured by baking up to 64 level-0 probes a second time with independent samples, and the
// noise's expected share is subtracted from every squared disagreement.
// Refinement rule (one level at a time, starting from every level-0 brick; t_l =
// refineError x sqrt(8)^l: every brick costs the same bytes and removes about its volume, 1/8
// per level, times the squared disagreement of its octant, so a finer brick under a level-l
// brick is worth keeping where that disagreement exceeds t_l):
//  * prediction: the larger of (a) a cheap pre-pass, the direct light of the punctual lights
//    (one shadow ray per light and point, exact, no noise) at the next level's lattice points
//    against the brick's interpolation of its own, largest over the octants, which finds
//    shadow edges also in open air, and (b) the full bake's disagreement in the brick's octant
//    one level up, divided by 4 (trilinear error falls with the square of the spacing) or by 2
//    where geometry lies within the brick's reach (a triangle's bounding box overlaps the
//    region grown by one probe spacing: contact shading falls about linearly); on level 0,
//    (b) is how far the brick's own probes stray from the interpolation of its 8 corners,
//    divided by 9 (3 near geometry);
//  * a brick whose prediction exceeds t_l, and that has a probe outside geometry (bricks inside
//    solids are never spent on), bakes its finer probes for real; the finer brick of each
//    octant where the larger of the measured disagreement and (a) exceeds t_l is kept (bricks
//    nest: brick.hpp), unless every one of its probes is inside geometry (a free-space brick:
//    the coarser brick shows there; (a) sees the direct light drop to 0 inside a solid next to
//    lit probes and would otherwise keep it). The other octants' finer probes stay unused
//    (their bake time is part of the bake).
// The budget then drops the finer bricks whose removal costs least (volume x squared
// disagreement of their octant), a brick only after its own finer bricks, until the GPU bytes
// fit.
Result<BrickedOutcome> bakeBricked(const Scene& scene, const VolumeDesc& desc, sh::Order order,
                                   const BrickedSettings& settings, const ProbeBatchFn& bake_batch);

// GPU bytes of a bricked layout: texels of `bricks` bricks plus the u32 indirection, plus with
// visibility its 8 bytes per probe (Volume::visibilityGpuBytes).
uint64_t brickedGpuBytes(glm::uvec3 top_bricks, uint32_t max_level, uint64_t bricks,
                         sh::Order order, Storage storage, bool visibility = false);

} // namespace probekit::baker
