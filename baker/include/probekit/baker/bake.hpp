// probekit::baker — bake configuration, volume placement and the bake itself.
//
// A bake takes a Scene (scene.hpp) and a BakeConfig (usually parsed from the JSON config and
// overridden by command-line flags), places the volumes, runs the lighting method for every
// probe on the baker's parallel loop, marks probes inside geometry invalid and fills them by
// dilation, and returns a PvolFile ready to write. Output is bit-identical for any thread
// count.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

enum class BoundsMode : uint8_t {
    Custom,    // center + size, or min + max
    AutoWorld, // world AABB of the scene, or of the listed nodes
    AutoLocal, // local AABB of one node, oriented by its world transform
};

struct BoundsConfig {
    BoundsMode mode = BoundsMode::AutoWorld;
    glm::vec3 min{0.0f}; // custom, metres (center/size are converted to min/max when parsed)
    glm::vec3 max{0.0f};
    std::vector<std::string> nodes; // auto-world: node names (or decimal indices); empty = all
    std::string node;               // auto-local: node name (or decimal index)
    // Metres added on every side. Unset = automatic: 0 for custom bounds; for automatic bounds
    // 0 unless the box's centre region lies inside geometry (a single closed object), when the
    // box grows by kAutoPaddingGrowth x its longest side on every side (autoPadding).
    std::optional<float> padding;
};

// The automatic padding rule: of a kAutoPaddingLattice^3 lattice of test points at the cell
// centres of the unpadded box, each casting kAutoPaddingRays directions, more than
// kAutoPaddingInsideShare inside geometry (the bake's validity rule, backface_threshold) means
// the box hugs a closed object; adding half the longest side on every side then leaves the
// object at most 1/8 of the volume, so most probes lie outside it.
constexpr uint32_t kAutoPaddingLattice = 4;
constexpr uint32_t kAutoPaddingRays = 64;
constexpr float kAutoPaddingInsideShare = 0.5f;
constexpr float kAutoPaddingGrowth = 0.5f;

constexpr float kDefaultDensity = 4.0f; // probes per metre
constexpr float kMinAutoProbes = 8.0f;  // along the longest axis of an automatic grid

struct VolumeConfig {
    std::string name = "volume";
    BoundsConfig bounds;
    std::optional<glm::uvec3> resolution; // explicit powers of two; empty = "auto"
    // auto: probes per metre. Unset = chosen from the volume: kDefaultDensity, raised so the
    // longest axis gets at least kMinAutoProbes probes (small scenes still get a useful grid).
    std::optional<float> density;
    uint32_t maxResolution = 32; // auto: cap per axis (<= 256)
    grid::PositionMode position = grid::PositionMode::Center;
    Storage storage = Storage::Float16;
    sh::Order shOrder = sh::Order::L2;
    int32_t blendPriority = 0;
    float fadeDistance = 0.0f; // metres
    // Bricked (adaptive) layout (formats/.../brick.hpp). `resolution`, `density` and
    // `maxResolution` then describe level 0: bricks per axis, explicit or
    // round_pow2(size * density / 3) (a brick spans 3 probe spacings).
    VolumeLayout layout = VolumeLayout::Dense;
    uint32_t maxLevel = 2; // bricked: finer levels allowed over level 0 (0..3), each 2x denser
    // Bricked: an octant of a level-0 brick gets its own finer brick when the brick's
    // interpolation at the octant's finer probes disagrees with their baked irradiance by more
    // than this fraction of the volume's RMS irradiance (RMS over the octant); at level l when
    // it disagrees by more than sqrt(8)^l times this (equal shares of the volume's squared
    // error; bricked.hpp). Octants that do not gain keep the coarser brick.
    float refineError = 0.05f;
};

struct EnvironmentConfig {
    enum class Type : uint8_t { Black, Constant, LatLong };
    Type type = Type::Black;
    glm::vec3 radiance{0.0f};   // constant, W/(sr m^2)
    std::filesystem::path file; // lat-long image (relative paths resolve against the config)
    float intensity = 1.0f;
    float rotationDeg = 0.0f;
};

struct PathConfig {
    uint32_t samples = 1024;  // directions per probe; the minimum with a noise target
    uint32_t maxBounces = 64; // path length cap (Russian roulette ends most paths far earlier)
    // Adaptive sampling (path_integrator.hpp): each probe's path-traced part is traced until
    // its estimated relative noise is at most noiseTarget (0 = off: every probe takes the
    // minimum), or it has taken maxSamples directions. The minimum is `samples` for method
    // path, vpl.direct_samples and lpv.direct_samples for the others.
    float noiseTarget = 0.0f;
    uint32_t maxSamples = 1u << 16;
    // W/m^2, RMS over the six axis normals and three channels: a probe darker than this has its
    // noise measured against this instead of its own irradiance, so that dark probes are not
    // chased to a relative noise the bake's overall error does not need (--target-error sets
    // it to the pilot's RMS irradiance). 0 = every probe against its own.
    float noiseFloor = 0.0f;
};

// Method "vpl": instant radiosity (Keller 1997). Light paths leave the lights, a virtual point
// light (VPL) is left at every diffuse hit, and each probe gathers the VPLs: they carry the
// light reflected by surfaces one or more times, while the direct light at the probe comes from
// the lights as in the path method (the path integrator with maxBounces 0 and
// VplConfig::directSamples directions).
enum class VplClamp : uint8_t {
    None,      // inverse square: unbiased, spikes near surfaces
    Distance,  // inverse square with d >= clampDistance
    Spherical, // virtual spherical lights of radius clampDistance (Hasan et al. 2009)
};
enum class VplSampling : uint8_t {
    Random,     // independent uniforms per light path
    Stratified, // scrambled Halton over the light-path dimensions (deterministic, low discrepancy)
    Jittered,   // one jittered stratum per path in every dimension, strata shuffled per dimension
};

// The names the config and the command line use: "none", "distance", "spherical";
// "random", "stratified", "jittered".
std::string_view toString(VplClamp clamp);
std::string_view toString(VplSampling sampling);

constexpr uint32_t kMinDefaultVplCount = 16384; // automatic count: floor and cap
constexpr uint32_t kMaxDefaultVplCount = 65536;

struct VplConfig {
    // VPLs to place (a target: the number of light paths is sized by a pilot run so that the
    // set holds about this many). Unset = automatic: enough that the VPL spacing on the
    // scene's surfaces is at most half the smallest probe spacing,
    // 4 x surface area / spacing^2, rounded up to a power of two, within
    // kMinDefaultVplCount..kMaxDefaultVplCount (resolveVplConfig).
    std::optional<uint32_t> count;
    uint32_t bounces = 64; // reflections per light path (1 = classic single bounce); Russian
                           // roulette ends almost all paths far earlier
    // Directions per probe for the direct light (emitters and sky seen from the probe, with
    // next-event estimation). Direct light alone converges far faster than full paths: 256
    // give ~2% noise on the Cornell reference points where full paths need ~30000.
    uint32_t directSamples = 256;
    VplSampling sampling = VplSampling::Stratified;
    VplClamp clamp = VplClamp::Spherical;
    // Metres: minimum distance (distance clamp) or sphere radius (spherical). Unset = twice the
    // radius of the surface disc each VPL stands for, 2 sqrt(area / (pi count)), so the
    // clamping bias vanishes as the count grows.
    std::optional<float> clampDistance;
    // Metres: surfaces nearer to a probe than this are path-traced from the probe (its direct
    // light directions continue as full paths) instead of gathered from VPLs, which cannot
    // resolve a surface a few VPL spacings away (a probe in a corner). 0 = off. Unset = twice
    // the clamp distance. Needs shadows on to partition the sphere exactly.
    std::optional<float> nearField;
    bool shadows = true; // a visibility ray per probe-cluster pair (off: light leaks)
    // Lightcut: each gathered cluster's error is bounded by this fraction of the probe's
    // scalar irradiance (0 = gather every VPL individually). Stricter than Lightcuts' 2% for
    // one pixel: a probe sums its clusters' errors over the whole sphere.
    float cutError = 0.005f;
};

// Method "lpv": light propagation volumes (Kaplanyan and Dachsbacher, "Cascaded Light
// Propagation Volumes for Real-Time Indirect Illumination", I3D 2010). The VPLs of the vpl
// method are injected into nested grids of L1 SH cells, light flows from cell to cell with
// occlusion from the scene's geometry, and every probe takes the interpolated result:
// the fastest, coarsest method. baker/src/lpv.hpp documents the transport and its units.
enum class LpvDirect : uint8_t {
    Traced,     // direct light at the probes from the lights, as the other methods compute it
    Propagated, // the lights are injected too, and the grid carries direct light as well
};
std::string_view toString(LpvDirect direct); // "traced", "propagated"

struct LpvConfig {
    uint32_t grid = 32;        // cells along the longest axis of every cascade (4..256)
    uint32_t cascades = 1;     // nested grids around each volume (1..4)
    float cascadeRatio = 2.0f; // cell size of a cascade / that of the next finer one (1.25..4)
    // Propagation steps (light moves one cell per step). Unset = grid: light crosses the
    // longest axis of a cascade once; longer adds little, since light that has travelled that
    // far has left the grid or met a surface.
    std::optional<uint32_t> iterations;
    float propagationWeight = 1.0f; // fraction of the flux a step passes on, (0, 1]; 1 = lossless
    float fadeCells = 2.0f;         // cells over which a finer cascade blends into the next (>= 0)
    bool occlusion = true;          // geometry volume: surfaces block light between cells
    LpvDirect direct = LpvDirect::Traced;
    // Directions per probe for the traced direct light (path integrator, no bounce): on the
    // Cornell reference points 128 add ~1% to the rel RMSE over 4096.
    uint32_t directSamples = 128;
    // VPLs injected (light paths of the vpl method, all bounces). Sparse injection rings more
    // in L1: on the Cornell box 65536 lower the rel RMSE from ~0.11 to ~0.09 at 4x the
    // light-path time; 16384 keep a 16^3 bake near 2% of the path method's time at 4096.
    uint32_t vplCount = 16384;
    float intensity = 1.0f; // scale of the propagated light for artists; 1 = physical (>= 0)
};

// The lighting method: the path-traced reference, instant radiosity (VplConfig) or light
// propagation volumes (LpvConfig).
enum class Method : uint8_t { Path, Vpl, Lpv };
std::string_view toString(Method method); // "path", "vpl", "lpv"

struct BakeConfig {
    Method method = Method::Path;
    uint64_t seed = 1;
    // Metres per scene unit (0.01 for a file in centimetres), applied when the scene is loaded
    // (LoadOptions::scale); bake() checks that the scene was loaded with it. Custom bounds and
    // every length setting are in metres after the scale.
    float scale = 1.0f;
    PathConfig path;
    VplConfig vpl;
    LpvConfig lpv;
    EnvironmentConfig environment;
    float backfaceThreshold = 0.25f; // probe invalid when more of its rays hit back faces
    bool dilate = true;              // fill invalid probes from valid neighbours
    // Bricked volumes: an invalid probe on a box face (one lying on a wall or floor the box
    // is placed against) is baked again just inside the box, within 1/8 of the finest probe
    // spacing, instead of being dilated.
    bool nudge = true;
    // Dense volumes: a probe inside geometry is baked at the nearest free point within one cell
    // instead (virtual offset; baker/src/visibility.hpp), and lights the surfaces of the solid
    // it sits in (README, "Surface accuracy").
    bool relocate = true;
    // Store per-probe occluder distances (formats/.../visibility.hpp) so that interpolation
    // between probes does not carry light through walls; 54 rays per probe.
    bool visibility = true;
    // Window every stored probe's SH bands 1 and 2 so that its irradiance is non-negative for
    // every normal (sh::deringIrradiance, formats/.../sh.hpp; README, "Deringing"): SH
    // truncation otherwise gives negative irradiance facing away from a small bright light.
    bool dering = true;
    // The bake's predicted peak memory (the memory model, README) may not exceed this, nor
    // 256 MiB when less (error); dense volumes' grids may not exceed it either. Bricked volumes:
    // their refinement uses what is left of it, and it is the budget for their GPU bytes
    // (texels + indirection); when that binds, the refinements whose removal costs the least
    // error are dropped (BakeStats::budgetDropped / budgetError).
    uint64_t maxMemoryBytes = 4ull << 30;
    std::vector<VolumeConfig> volumes; // empty = one auto-world volume with defaults
    // "target_error": let chooseSettings pick density, refinement, SH order and sample count
    // for this relative RMS irradiance error (probekit bake --target-error).
    std::optional<double> targetError;
};

// Parses the JSON config. Unknown keys are errors (they are usually typos); every message
// names `source` and the JSON path of the field, e.g. "bake.json: volumes[1].resolution[2]".
// The settings, their ranges and their flags are one table (settings.hpp).
Result<BakeConfig> parseBakeConfig(std::string_view json_text, std::string_view source,
                                   const std::filesystem::path& base_dir = {});
// Reads a config file and parses it: a regular file (a directory, FIFO or device is refused,
// file_io.hpp) of at most kMaxConfigBytes.
Result<BakeConfig> loadBakeConfig(const std::filesystem::path& path);
// 16 MiB: a config with thousands of volumes is a few hundred KB.
constexpr uint64_t kMaxConfigBytes = uint64_t(16) << 20;

// The config with every default filled in, as JSON (recorded in the file's metadata).
std::string describeConfig(const BakeConfig& config);

// Builds the scene's environment from the config (loads lat-long images).
Result<Environment> makeEnvironment(const EnvironmentConfig& config);

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
// README "Scenes").
Result<std::vector<VolumeDesc>> resolveVolumes(const Scene& scene, const BakeConfig& config);

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

// A bake spread over several processes (README, "Distributed bakes"): every process runs the
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
    // (README, max_memory_mb): the phase that peaks and its terms (what, bytes). For bricked
    // volumes it counts refinement at its bound, predictedRefinementBytes of it.
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
    uint64_t nudgedProbes = 0;                 // box-face probes baked just inside the box
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
// before building the BVH, on a predicted peak memory above max_memory_mb (README, Memory),
// naming the largest terms.
Result<BakeResult> bake(const Scene& scene, const BakeConfig& config,
                        const BakeOptions& options = {});

// ---- References and error-driven settings ----

// Path-traced radiance SH (L2) at world points with config.path's bounces and `samples`
// directions, the scene's lights and config.environment; `stream` selects independent sample
// sequences (two streams give two independent estimates). valid[i] = kProbeInvalid for
// points inside geometry (config.backfaceThreshold).
struct PointBake {
    std::vector<sh::ShRgb> sh;
    std::vector<uint8_t> valid;
    uint64_t rays = 0;
};
Result<PointBake> bakePoints(const Scene& scene, const BakeConfig& config,
                             const std::vector<glm::vec3>& points, uint32_t samples,
                             uint32_t stream, uint32_t threads = 0);

// `count` points spread uniformly over the volumes' boxes (in proportion to their volume),
// from a fixed low-discrepancy sequence (deterministic).
std::vector<glm::vec3> volumeSamplePoints(const std::vector<VolumeDesc>& volumes, size_t count);

// The error measure of --target-error and --verify: relative RMS irradiance error,
// sqrt(sum |E - E_ref|^2 / sum |E_ref|^2) over points, the six axis normals and the three
// channels (irradiance from radiance SH, sh::irradiance).
struct ErrorEstimate {
    double relRmse = 0.0;        // against the mean of the two reference estimates, with the
                                 // reference's own noise subtracted (0 if noise explains all)
    double relRmseRaw = 0.0;     // without the subtraction
    double referenceNoise = 0.0; // RMS noise of the reference mean, same units
    size_t points = 0;           // valid points compared
};
// `irradiance(point, normal)` is what the baked volumes give (e.g. runtime::VolumeSet
// irradiance, W/m^2 per channel); ref_a / ref_b are two independent reference estimates
// (bakePoints with two streams). Points invalid in either reference are skipped.
ErrorEstimate
estimateError(const std::function<glm::vec3(glm::vec3 point, glm::vec3 normal)>& irradiance,
              const std::vector<glm::vec3>& points, const PointBake& ref_a, const PointBake& ref_b);

// What --target-error chose and why (all errors are fractions of RMS irradiance).
struct TargetChoice {
    BakeConfig config; // the settings to bake with
    double target = 0.0;
    uint32_t pilotPoints = 0;  // valid pilot points
    uint32_t pilotSamples = 0; // directions per pilot estimate
    double pilotNoise = 0.0;   // one probe's noise at pilotSamples
    double band2 = 0.0;        // RMS irradiance of SH band 2 (what L1 would lose)
    sh::Order shOrder = sh::Order::L2;
    uint32_t samples = 0;       // directions per probe uniform sampling would need
    double samplesWanted = 0.0; // what the noise budget asked, before the floor and cap
    // Adaptive sampling carries the noise share: each probe is traced to probeNoiseTarget
    // (the share over the interpolation's variance reduction), from minSamples directions
    // (samples / 8 rounded down to a power of two, within kTargetMinSamples..4096) up to
    // kTargetMaxSamples.
    uint32_t minSamples = 0;
    double probeNoiseTarget = 0.0;
    double noiseFloor = 0.0;          // the pilot's RMS irradiance (path.noise_floor), W/m^2
    double predictedNoise = 0.0;      // noise after interpolation at `samples`
    double interpolationBudget = 0.0; // refine_error given to the bricked volumes
    double pilotSeconds = 0.0;
};
// The error budget of chooseSettings, as fractions of the target t.
constexpr double kTargetTolerance = 1.5; // probekit bake fails when predicted or measured is more
// Fewest directions per probe chooseSettings gives: L2 SH has 9 coefficients per channel, and
// below ~14 directions per coefficient a probe is noise wherever the 64 pilot points missed a
// light feature (8 directions, the old floor, baked a grainy millimetre engine).
constexpr uint32_t kTargetMinSamples = 128;
constexpr uint32_t kTargetMaxSamples = 1u << 16;
constexpr double kTargetNoiseShare = 0.6;       // interpolated Monte Carlo noise
constexpr double kTargetBand2Share = 0.4;       // SH band 2 may be dropped (L1) below this
constexpr double kTargetMinInterpolation = 0.2; // interpolation's share never falls below this

// Chooses settings so that the bake's error against a converged path reference is about
// `target` t: every volume becomes bricked (levels 3) with refine_error from the error budget
// and level-0 bricks from the density rule with the spacing scaled by sqrt(t / 0.05) (the
// smooth light level 0 covers has trilinear error growing with the square of the spacing);
// SH order L1 where band 2 carries less than kTargetBand2Share x t; the sample count so that
// the interpolated Monte Carlo noise is kTargetNoiseShare x t (from a pilot of two independent
// estimates at 64 points); interpolation gets the rest in quadrature,
// sqrt(t^2 - noise^2 - band2^2), but at least kTargetMinInterpolation x t. For methods vpl and
// lpv the count chosen is their direct-light samples; their own bias (VPL clamping, LPV
// propagation) is not modelled.
Result<TargetChoice> chooseSettings(const Scene& scene, const BakeConfig& base, double target,
                                    uint32_t threads = 0);

// Predicted error of a bake made with `choice`: interpolation (BakeStats), noise and band 2
// combined in quadrature.
double predictError(const TargetChoice& choice, const BakeStats& stats);

// Which term of predictError is largest and what limit held it there (the sample cap, the
// deepest level, max_memory_mb's GPU budget or working memory, SH order L1), in a sentence.
std::string explainError(const TargetChoice& choice, const BakeStats& stats);

} // namespace probekit::baker
