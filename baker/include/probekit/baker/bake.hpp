// probekit::baker — volume placement and the bake itself.
//
// A bake takes a Scene (scene.hpp) and a BakeConfig (config.hpp), places the volumes, runs the
// lighting method for every probe on the baker's parallel loop, marks probes inside geometry
// invalid and fills them by dilation, and returns a PvolFile ready to write. Output is
// bit-identical for any thread count. Error-driven settings (--target-error) are target.hpp.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Where the volumes go and what placing them changed from what was asked.
struct VolumePlan {
    std::vector<VolumeDesc> volumes;
    std::vector<float> padding;     // per volume, metres: the padding used (automatic resolved)
    std::vector<std::string> notes; // each cap or automatic choice that changed what was asked
};

// Places every volume (bounds, frame, resolution) without baking, as resolveVolumes, and says
// what it capped: an automatic resolution above max_resolution (with the resolution asked and
// the spacing used) and an automatic padding that grew the box; and, for a scene far from the
// origin for its probe spacing, what float32 precision costs there.
Result<VolumePlan> planVolumes(const Scene& scene, const BakeConfig& config);

// Places every volume (bounds, frame, resolution) without baking. Fails naming the volume and
// field for zero-size or inverted bounds, unknown nodes, an empty scene with automatic bounds,
// bad resolutions, or a total size beyond config.maxMemoryBytes; naming the file and the node,
// light or volume for coordinates beyond the range a bake supports (|x|, |y|, |z| <= 1e7 m,
// docs/baking.md#scenes).
Result<std::vector<VolumeDesc>> resolveVolumes(const Scene& scene, const BakeConfig& config);

// The volumes a config bakes: those it lists, or one with the defaults when it lists none.
std::vector<VolumeConfig> volumeConfigs(const BakeConfig& config);

// Probes per metre of an automatic resolution without `density` over the padded `box`
// (bricked: at level 0): kDefaultDensity dense, kBrickedDensity bricked, raised so the longest
// axis gets at least kMinAutoProbes probes.
float automaticDensity(const grid::Aabb& box, VolumeLayout layout);

// Smallest distance between probes a volume may have per axis, metres: the grid spacing of a
// dense volume, the deepest level's spacing of a bricked one.
glm::vec3 probeSpacing(const VolumeDesc& desc);

// The VPL settings a bake uses: config.vpl with count and clampDistance filled in by the rules
// documented on VplConfig (surface area of the scene's triangles; probe spacing of `volumes`,
// the whole extent along an axis with one probe).
VplConfig resolveVplConfig(const Scene& scene, const std::vector<VolumeDesc>& volumes,
                           const BakeConfig& config);

// Bytes a bake of these volumes holds at its peak (per-probe SH in float plus output texels).
uint64_t estimateBakeMemory(const std::vector<VolumeDesc>& volumes);

// How far a bake is. probesTotal covers the whole bake, not only the volume or brick level
// under way: the probes queued so far plus those expected of the rest. A volume not yet
// started is expected to bake its dense grid's probes, or its bricked level 0 and as many
// again for each level refinement may test; a bricked volume under way expects each level
// still to be tested to bake as many probes as its latest batch (BrickedSettings::
// expectFurther). The total moves as relocation adds probes and refinement replaces its
// guesses with batches.
struct BakeProgress {
    uint64_t probesDone = 0;
    uint64_t probesTotal = 0;
    double elapsedSeconds = 0.0;
};

// What baking a run of probes added to the bake's statistics: sums, and the most directions
// one probe took.
struct ProbeChunkStats {
    uint64_t rays = 0;
    uint64_t cut = 0;     // method vpl: clusters gathered
    uint64_t samples = 0; // directions of the path-traced parts
    uint64_t over = 0;    // adaptive: valid probes that stopped above the noise target
    uint32_t most = 0;
    ProbeChunkStats& operator+=(const ProbeChunkStats& o) {
        rays += o.rays;
        cut += o.cut;
        samples += o.samples;
        over += o.over;
        most = most > o.most ? most : o.most;
        return *this;
    }
};

// A bake spread over several processes (docs/baking.md#distributed-bakes): every process runs the
// same bake with the same inputs; each batch of probes it meets (a dense volume, a bricked
// volume's level, ...) goes through run(), which has compute(begin, end) called for every
// chunk of [0, count) on exactly one of the processes and returns once every process holds
// every probe's SH and validity in `sh` and `valid` (compute writes its range of them) and the
// batch's statistics summed over all chunks. Every probe's result depends only on (seed,
// volume, probe), so the bake and its file are the same bytes as one process's. The
// implementation handles a lost process itself (the probekit tool's ends the job).
class ProbeDistributor {
public:
    using Compute = std::function<ProbeChunkStats(size_t begin, size_t end)>;
    virtual ~ProbeDistributor() = default;
    virtual ProbeChunkStats run(size_t count, std::span<sh::ShRgb> sh, std::span<uint8_t> valid,
                                const Compute& compute) = 0;
};

struct BakeOptions {
    uint32_t threads = 0; // 0 = all hardware threads (of this process)
    // Probes baked across processes (ProbeDistributor); null: this process alone.
    ProbeDistributor* distributor = nullptr;
    // Called from the calling thread about every 100 ms and once at the end.
    std::function<void(const BakeProgress&)> progress;
    // A scene that emits no light (checkSceneLit, scene_summary.hpp) bakes to zeros by
    // construction, so bake() fails on it; true bakes it anyway with a warning (for bakes that
    // are black on purpose, e.g. the validity of probes alone).
    bool allowUnlit = false;
};

struct BakeStats {
    double seconds = 0.0;
    uint64_t probes = 0;
    uint64_t rays = 0;
    double mraysPerSecond = 0.0;
    uint64_t invalidProbes = 0;
    // BakeConfig::dering: stored probes whose coefficients a deringing pass changed, and the
    // relative RMS change of their irradiance over the sphere (sh::DeringResult::
    // relativeChange; a bricked probe changed before and after stitching counts once, with its
    // larger change): mean over them and largest. A bricked border probe stitched from deringed
    // probes passes as it is and is not counted.
    uint64_t deringedProbes = 0;
    double deringMeanChange = 0.0;
    double deringMaxChange = 0.0;
    uint64_t peakMemoryBytes = 0; // the process's peak resident set (getrusage)
    // The memory model's prediction of that peak, made before the bake allocated anything big
    // (docs/baking.md#memory-max_memory_mb): the phase that peaks and its terms (what, bytes). For
    // bricked volumes it counts refinement at its bound, predictedRefinementBytes of it.
    uint64_t predictedPeakBytes = 0;
    uint64_t predictedRefinementBytes = 0;
    std::string predictedPeakPhase;
    std::vector<std::pair<std::string, uint64_t>> predictedTerms;
    uint32_t threads = 0;
    uint64_t vpls = 0;          // methods vpl and lpv: VPLs in the set
    uint64_t vplLightPaths = 0; // method vpl: light paths traced to place them
    double vplMeanCut = 0.0;    // method vpl: clusters gathered per probe, mean
    // Directions per probe of the path-traced part (the whole probe for method path, the
    // direct light for vpl and lpv): mean and most. With adaptive sampling (path.noise_target)
    // they vary; probesOverTarget counts valid probes that stopped at path.max_samples with
    // their estimated noise still above the target.
    double meanSamples = 0.0;
    uint32_t maxSamples = 0;
    uint64_t probesOverTarget = 0;
    // Bricked volumes (summed over them):
    uint64_t bricksPerLevel[4] = {0, 0, 0, 0}; // bricks written, by level
    // Bricks written whose every probe is inside geometry (invalid), by level: they hold only
    // values dilated from outside.
    uint64_t solidBricksPerLevel[4] = {0, 0, 0, 0};
    uint64_t nudgedProbes = 0;     // box-face probes baked just inside the box
    uint64_t relocatedProbes = 0;  // probes inside geometry baked at the nearest free point
    uint64_t refineCandidates = 0; // bricks whose finer probes were baked to test them
    uint64_t budgetDropped = 0;    // finer bricks removed by max_memory_mb
    uint64_t memoryUntested = 0;   // candidate bricks not refined: the working memory was full
    // Largest disagreement (fraction of RMS irradiance) of a refinement the budget removed:
    // the error the budget cost where it cost most. 0 when the budget did not bind.
    double budgetError = 0.0;
    // Predicted interpolation error of the bricked volumes (fraction of RMS irradiance, RMS
    // over the volume) from the measured disagreements where each brick shows.
    double predictedInterpolationError = 0.0;
};

struct BakeResult {
    PvolFile file;
    BakeStats stats;
    std::vector<std::string> warnings;
};

// Checks the config first (validateBakeConfig, settings.hpp): a config built in code gets the
// errors a config file would. Then fails on a scene that emits no light (checkSceneLit) unless
// options.allowUnlit, which turns that error into a warning; on the errors of planVolumes; and,
// before building the BVH, on a predicted peak memory above max_memory_mb
// (docs/baking.md#memory-max_memory_mb), naming the largest terms.
Result<BakeResult> bake(const Scene& scene, const BakeConfig& config,
                        const BakeOptions& options = {});

} // namespace probekit::baker
