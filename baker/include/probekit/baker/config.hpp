// probekit::baker — the bake configuration: every setting with its default, and the config file.
//
// A BakeConfig is usually parsed from the JSON config (parseBakeConfig) and overridden by
// command-line flags; each field here is the one home of its setting and its default. The table
// that parses, describes, validates and gives flags to the scalar settings is settings.hpp
// (rows in baker/src/config.cpp).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/environment.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"

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
// ... unless the box is a level seen from the solid space around its rooms (a sealed level: its
// void is "inside" by the backface rule): at least a quarter of the test points outside
// geometry see front faces in at least this share of their directions. Outside a closed object
// a point sees its faces over about a hemisphere at most; in a room, walls all around.
constexpr float kAutoPaddingEnclosedHits = 0.9f;

constexpr float kDefaultDensity = 4.0f; // probes per metre
constexpr float kMinAutoProbes = 8.0f;  // along the longest axis of an automatic grid
// Bricked: level-0 probes per metre when `density` is unset. Rounded to powers of two per axis
// (2^round(log2)), level 0's spacing stays under 1/1.5 x sqrt(2) = 0.94 m wherever a player can
// stand; refinement goes finer near geometry and light. On the arena level (65 x 8.5 x 65 m)
// 1.35 m level-0 spacing measured 0.18 `--verify` error and 0.68 m measured 0.096 (issue 29).
constexpr float kBrickedDensity = 1.5f;

// max_probes when unset: dense 32^3; bricked 2^17 level-0 probes (4854 bricks: the arena level
// at kBrickedDensity takes 32 x 4 x 32 = 4096).
constexpr uint32_t kDefaultMaxProbes = 32768;
constexpr uint32_t kDefaultMaxBrickedProbes = 131072;

struct VolumeConfig {
    std::string name = "volume";
    BoundsConfig bounds;
    std::optional<glm::uvec3> resolution; // explicit powers of two; empty = "auto"
    // auto: probes per metre. Unset = chosen from the volume: kDefaultDensity, raised so the
    // longest axis gets at least kMinAutoProbes probes (small scenes still get a useful grid).
    // Bricked: level-0 probes per metre; unset = kBrickedDensity, raised the same way.
    std::optional<float> density;
    uint32_t maxResolution = 256; // auto: cap per axis (<= 256)
    // auto: the most probes (bricked: level-0 probes, 27 per brick) the grid may have. Past it
    // the axis with the finest spacing is halved until it fits, so a flat level keeps even
    // spacing (65 x 8.5 x 65 m at 4/m: 64 x 8 x 64, 1.02 m) where a cap per axis would give
    // 32 x 32 x 32 (2.03 x 0.27 x 2.03 m) for the same count. Unset: kDefaultMaxProbes dense,
    // kDefaultMaxBrickedProbes bricked (maxProbesOf).
    std::optional<uint32_t> maxProbes;
    grid::PositionMode position = grid::PositionMode::Center;
    Storage storage = Storage::Float16;
    sh::Order shOrder = sh::Order::L2;
    int32_t blendPriority = 0;
    float fadeDistance = 0.0f; // metres
    // Bricked (adaptive) layout (formats/.../brick.hpp). `resolution`, `density` and
    // `maxResolution` then describe level 0: bricks per axis, explicit or
    // round_pow2(size * density / 3) (a brick spans 3 probe spacings).
    // Unset ("auto"): dense, unless the resolution is automatic, probes are centred and a
    // dense grid at the density would need more than kDefaultMaxProbes probes (a level:
    // 512 m^3 at 4 probes/m), where one budget's worth of probes spaces them past 0.25 m and a
    // level's rooms need finer probes near walls than in their air (withLayout, bake.cpp).
    std::optional<VolumeLayout> layout;
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

// Light modes (docs/baking.md#light-modes): what the bake stores of each source of light, so
// that an engine which shades some lights itself does not count their direct light twice.
//  * Baked: direct and bounced light (the default).
//  * Indirect: only what the light reaches after at least one bounce; its direct light at the
//    probe is left out (Unity's Mixed lights, "Baked Indirect"; Unreal's stationary lights).
//  * None: the light is left out of the bake altogether.
enum class LightMode : uint8_t { Baked, Indirect, None };
std::string_view toString(LightMode mode); // "baked", "indirect", "none"

struct LightModesConfig {
    LightMode punctual = LightMode::Baked;    // every KHR_lights_punctual light not in perLight
    LightMode emissive = LightMode::Baked;    // emissive surfaces
    LightMode environment = LightMode::Baked; // the environment (sky)
    // Per light, by glTF light name or by index into the file's KHR_lights_punctual lights (as
    // text: "0"); a name or index no light has is an error at bake time.
    std::vector<std::pair<std::string, LightMode>> perLight;

    bool allBaked() const {
        if (punctual != LightMode::Baked || emissive != LightMode::Baked ||
            environment != LightMode::Baked) {
            return false;
        }
        for (const auto& [key, mode] : perLight) {
            if (mode != LightMode::Baked) {
                return false;
            }
        }
        return true;
    }
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
    // it to the pilot's RMS irradiance in the bounded measure, irradiance_error.hpp). 0 = every
    // probe against its own.
    float noiseFloor = 0.0f;
    // Punctual and directional lights at a path vertex (path_integrator.hpp): when more than
    // this many could light it, light i's shadow ray is traced with probability
    // q_i = min(1, shadowRays x c_i / sum c) (c: its unoccluded contribution) and weighted 1 / q_i,
    // so a vertex traces at most this many shadow rays on average; the estimate stays unbiased.
    // 0 = a shadow ray to every light. At 4 the generated arenas (32 lights) trace 6 times
    // fewer rays for the same seed-to-seed noise.
    uint32_t shadowRays = 4;
    // Russian roulette's weight window (path_integrator.hpp): from the third vertex on, a path
    // whose throughput (max channel) is below this survives with probability throughput /
    // this and continues at this weight. 1 cuts paths as soon as any light is absorbed; at
    // 0.25 a room lit only through a doorway (thin-wall's unlit room) has half the noise for
    // 1.3x the time, and the generated arenas and the Cornell box are within 5% of the same
    // noise per second.
    float rouletteWeight = 0.25f;
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
// the fastest, coarsest method. baker/src/methods/lpv.hpp documents the transport and its units.
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
    LightModesConfig lights;
    float backfaceThreshold = 0.25f; // probe invalid when more of its rays hit back faces
    bool dilate = true;              // fill invalid probes from valid neighbours
    // Bricked volumes: an invalid probe on a box face (one lying on a wall or floor the box
    // is placed against) is baked again just inside the box, within 1/8 of the finest probe
    // spacing, instead of being dilated.
    bool nudge = true;
    // Dense volumes: a probe inside geometry is baked at the nearest free point within one cell
    // instead (virtual offset; baker/src/volume/visibility.hpp), and lights the surfaces of the
    // solid it sits in (docs/accuracy.md#surface-accuracy).
    bool relocate = true;
    // Store per-probe occluder distances (formats/.../visibility.hpp) so that interpolation
    // between probes does not carry light through walls; 54 rays per probe.
    bool visibility = true;
    // Window every stored probe's SH bands 1 and 2 so that its irradiance is non-negative for
    // every normal (sh::deringIrradiance, formats/.../sh.hpp; docs/baking.md#deringing): SH
    // truncation otherwise gives negative irradiance facing away from a small bright light.
    bool dering = true;
    // The bake's predicted peak memory (the memory model, docs/baking.md#memory-max_memory_mb) may
    // not exceed this, nor 256 MiB when less (error); dense volumes' grids may not exceed it
    // either. Bricked volumes: their refinement uses what is left of it, and it is the budget for
    // their GPU bytes (texels + indirection); when that binds, the refinements whose removal costs
    // the least error are dropped (BakeStats::budgetDropped / budgetError).
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

// Builds the scene's environment from the config (loads lat-long images, refusing one whose
// decode needs more than `max_bytes`: pass the bake's maxMemoryBytes).
Result<Environment> makeEnvironment(const EnvironmentConfig& config,
                                    uint64_t max_bytes = UINT64_MAX);

} // namespace probekit::baker
