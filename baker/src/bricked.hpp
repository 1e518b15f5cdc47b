// Bricked (adaptive) volumes: refinement by measured disagreement, the memory budget,
// dilation on the shared probe lattice and stitching (formats/.../brick.hpp has the layout).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

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

struct BrickedSettings {
    uint32_t maxLevel = 2;
    float refineError = 0.05f; // fraction of the volume's RMS irradiance
    uint64_t budgetBytes = ~uint64_t(0);
    bool dilate = true;
    // Traces the direct-light pre-pass (shadow rays to punctual lights); null = no pre-pass.
    const RayTracer* tracer = nullptr;
};

struct BrickedOutcome {
    VolumeDesc desc; // with desc.bricks filled in
    std::vector<sh::ShRgb> probes;
    std::vector<uint8_t> validity;
    uint64_t bricksPerLevel[4] = {0, 0, 0, 0};
    uint64_t refineCandidates = 0;
    uint64_t budgetDropped = 0;
    double budgetError = 0.0;
    double predictedError = 0.0; // RMS interpolation error, fraction of RMS irradiance
    float noise = 0.0f;          // one probe's RMS Monte Carlo noise, same units
    uint64_t invalidProbes = 0;  // lattice points inside geometry among those written
    std::vector<std::string> warnings;
};

// Error measure: irradiance at the six axis normals, every channel, relative to the volume's
// RMS irradiance (over its valid level-0 probes), RMS over points. Monte Carlo noise is
// measured by baking up to 64 level-0 probes a second time with independent samples, and the
// noise's expected share is subtracted from every squared disagreement.
// Refinement rule (one level at a time, starting from every level-0 brick):
//  * a brick is a candidate when geometry lies within its reach (a triangle's bounding box
//    overlaps the brick's region grown by one of its probe spacings) or when its predicted
//    interpolation error exceeds refineError, and it has at least one probe outside geometry;
//  * a candidate's finer probes (the next level's lattice over its region) are baked for real
//    and compared with the candidate's trilinear interpolation at them: the candidate is split
//    when the RMS disagreement exceeds refineError (no cheap pre-pass: the test is the real
//    bake of one level more, and its cost is part of the bake);
//  * the predicted error of a brick is a quarter of what was measured on its region one level
//    up (trilinear error falls with the square of the spacing); on level 0 it is a ninth of
//    how far the brick's own probes stray from the interpolation of its 8 corners.
// The budget then merges the splits whose disagreement is smallest until the GPU bytes fit.
Result<BrickedOutcome> bakeBricked(const Scene& scene, const VolumeDesc& desc, sh::Order order,
                                   const BrickedSettings& settings, const ProbeBatchFn& bake_batch);

// GPU bytes of a bricked layout: texels of `bricks` leaves plus the u32 indirection.
uint64_t brickedGpuBytes(glm::uvec3 top_bricks, uint32_t max_level, uint64_t bricks,
                         sh::Order order, Storage storage);

} // namespace probekit::baker
