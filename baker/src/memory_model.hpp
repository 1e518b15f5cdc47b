// The memory model of a bake: its peak resident bytes, predicted before anything big is
// allocated, so that bake() refuses a bake above max_memory_mb with the terms that make it
// big instead of running out of memory halfway (docs/baking.md#memory-max_memory_mb).
//
// The bake runs in phases, and what one phase allocates is freed before the next, except what
// it hands on; the peak is the largest phase:
//  * build: the BVH being built (Embree's build peak, kBvhBuildBytesPerTriangle);
//  * prepare (methods vpl and lpv): the VPL set and the light tree, or the LPV's injected lights;
//  * per volume, lpv: the propagation of each cascade (two fields ping-ponging, the flux
//    crossing every face, the transfers and the geometry volume), keeping the cascades before;
//  * per volume, probes: a dense volume's positions, ids, SH, validity, visibility and the texels
//    makeVolume stages and keeps; a bricked volume's lattice (kBakedProbeBytes per baked probe);
//  * write: the baked volumes and their encoded file (probekit bake writes after bake()).
// Each phase also holds the process's own bytes (libraries and whatever the caller holds
// besides the scene: measured at the start of the bake), the scene's arrays, the tracer's
// copies of them and its BVH, per-thread scratch and the volumes already baked.
//
// Byte counts are the sizes of the arrays the code allocates (sizeof of their elements); the
// constants that are not are measured and say where from.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Embree 3.13 (Debian 12) with the tracer's settings (one triangle geometry, build quality
// high: spatial splits), bytes per triangle its memory monitor reports (RayTracer::embreeBytes
// and embreePeakBytes): after the build 56.6 to 66.1, at the build's peak 99.7 to 133.2, over
// height fields and overlapping triangle soups of 10^4 to 4 x 10^6 triangles
// (tests/bake/test_memory_model.cpp holds the model to them).
constexpr uint64_t kBvhBytesPerTriangle = 68;
constexpr uint64_t kBvhBuildBytesPerTriangle = 136;
// Stacks, malloc arenas and scratch (path vertices, a VPL cut of up to kMaxCutSize clusters)
// each bake thread touches: 8 threads instead of 1 add 2 MiB to path and VPL bakes of the
// Cornell box.
constexpr uint64_t kThreadBytes = 512ull << 10;

struct MemoryTerm {
    std::string what;   // "vpl.count 16777216 VPLs", "volumes[0] ('hall'): 4194304 probes"
    std::string advice; // "lower --vpl-count"; empty when the term is not a setting's
    uint64_t bytes = 0;
    // Bricked refinement, counted at its bound: it shrinks to the room left, so it never makes
    // a bake fail.
    bool adapts = false;
    // Held before the bake began (the process's libraries, whatever an application holds):
    // part of the predicted peak the report compares with the measured one, but not of what
    // max_memory_mb limits, which is the bake's own memory. Counting it would refuse every bake
    // in an application that already holds more than max_memory_mb, and every bake of a
    // sanitizer build (whose shadow memory alone is about 270 MiB resident).
    bool external = false;
};

struct MemoryPhase {
    std::string name; // "build", "prepare", "volumes[0] probes", "write"
    std::vector<MemoryTerm> terms;
    uint64_t bytes() const;
    // The bytes max_memory_mb limits: bytes() less the external terms and, with adapting too,
    // less the terms that shrink to fit.
    uint64_t ownBytes(bool with_adapting = true) const;
};

struct MemoryPrediction {
    std::vector<MemoryPhase> phases;
    size_t peakPhase = 0;
    uint64_t peakBytes = 0;
    // Bricked volumes: the part of peakBytes that is refinement, counted at its bound (the
    // working room, or every brick refined where less); the bake uses what the light needs.
    uint64_t refinementBoundBytes = 0;
    // Per volume: the working bytes its bricked refinement may use (brickedWorkingBytes; 0
    // for dense volumes).
    std::vector<uint64_t> brickedWorkingBytes;
};

struct MemoryInputs {
    const Scene& scene;
    const BakeConfig& config;
    const std::vector<VolumeDesc>& volumes; // planVolumes
    uint32_t vplCount = 0;                  // method vpl: resolveVplConfig's count
    uint32_t threads = 1;
    uint64_t processBytes = 0; // resident bytes besides the scene (processBytes())
};

// The process's resident bytes now (Linux /proc/self/statm; 0 where unavailable).
uint64_t residentBytes();

// The process's resident bytes besides the scene's arrays and the heap malloc holds free for
// reuse: MemoryInputs::processBytes.
uint64_t processBytes(const Scene& scene);

// What a bricked volume's refinement may use: max_memory_mb less everything else the bake holds
// at its peak, but at least kMinWorkingBytes (bricked.hpp).
uint64_t brickedWorkingBytes(const BakeConfig& config, uint64_t other_bytes);

MemoryPrediction predictBakeMemory(const MemoryInputs& in);

// Fails when the bake's own peak (the process's earlier bytes and bricked refinement, which
// shrinks to fit, not counted) exceeds max(max_memory_mb, kMinWorkingBytes), naming the largest
// terms: "the bake's predicted peak memory 5.7 GiB (tracing the VPLs) exceeds max_memory_mb =
// 4096: vpl.count 16777216 VPLs and their light tree need 5.7 GiB (lower --vpl-count, or raise
// --max-memory)". Below kMinWorkingBytes max_memory_mb bounds the grids alone (planVolumes) and
// bricked volumes' GPU bytes.
Result<void> checkBakeMemory(const MemoryPrediction& prediction, const BakeConfig& config);

// "1.4 GiB", "312 MiB".
std::string formatBytes(uint64_t bytes);

} // namespace probekit::baker
