// probekit::baker — references and error-driven settings: path-traced points, the error measure
// of --target-error and --verify, and chooseSettings, which picks the settings of a bake for a
// relative RMS irradiance error.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/bake.hpp"
#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"

namespace probekit::baker {

// Path-traced radiance SH (L2) at world points with config.path's bounces and shadow rays,
// `samples` directions (fixed sampling), the scene's lights and config.environment; `stream`
// selects independent sample sequences (two streams give two independent estimates). valid[i] =
// kProbeInvalid for points inside geometry (config.backfaceThreshold).
struct PointBake {
    std::vector<sh::ShRgb> sh;
    std::vector<uint8_t> valid;
    uint64_t rays = 0;
    double seconds = 0.0; // tracing only (not the scene's BVH build)
};
Result<PointBake> bakePoints(const Scene& scene, const BakeConfig& config,
                             const std::vector<glm::vec3>& points, uint32_t samples,
                             uint32_t stream, uint32_t threads = 0);

// `count` points spread uniformly over the volumes' boxes (in proportion to their volume),
// from a fixed low-discrepancy sequence (deterministic).
std::vector<glm::vec3> volumeSamplePoints(const std::vector<VolumeDesc>& volumes, size_t count);

// The error measure of --target-error and --verify: the bounded relative RMS irradiance error,
// sqrt(sum s |E - E_ref|^2 / sum s |E_ref|^2) over points, the six axis normals and the three
// channels (irradiance from radiance SH, sh::irradiance), s each point's bright-point weight
// (methods/irradiance_error.hpp: a point brighter than kBrightPointCap times the median point
// counts as if it were that bright).
struct ErrorEstimate {
    double relRmse = 0.0;        // against the mean of the two reference estimates, with the
                                 // reference's own noise subtracted (0 if noise explains all)
    double relRmseRaw = 0.0;     // without the subtraction
    double referenceNoise = 0.0; // RMS noise of the reference mean, same units
    size_t points = 0;           // valid points compared
    size_t cappedPoints = 0;     // of them, those above the bright-point cap
    // How many points carry the reference's weighted squared irradiance (Kish's effective
    // sample size of the weights w = s |E_ref|^2, s the bright-point weight: (sum w)^2 /
    // sum w^2). The cap keeps it from collapsing to the one or two points next to a light.
    double effectivePoints = 0.0;
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
    double noiseFloor = 0.0;     // the pilot's bounded RMS irradiance (path.noise_floor), W/m^2
    double predictedNoise = 0.0; // noise after interpolation at `samples`
    double interpolationBudget = 0.0; // refine_error given to the bricked volumes
    double pilotSeconds = 0.0;
    // The plan printed before the bake. Level 0's lattice probes, the directions adaptive
    // sampling is expected to give one (the mean over the pilot's points of what each point's
    // noise asks, within minSamples..kTargetMaxSamples), and level 0's seconds at the pilot's
    // tracing seconds per point and direction. Refinement comes on top, where light changes.
    uint64_t levelZeroProbes = 0;
    double expectedDirections = 0.0;
    double levelZeroSeconds = 0.0;
};
// The error budget of chooseSettings, as fractions of the target t.
constexpr double kTargetTolerance = 1.5; // probekit bake fails when predicted or measured is more
// Fewest directions per probe chooseSettings gives: L2 SH has 9 coefficients per channel, and
// below ~14 directions per coefficient a probe is noise wherever the 256 pilot points missed a
// light feature (8 directions, the old floor, baked a grainy millimetre engine).
constexpr uint32_t kTargetMinSamples = 128;
constexpr uint32_t kTargetMaxSamples = 1u << 16;
constexpr double kTargetNoiseShare = 0.6;       // interpolated Monte Carlo noise
constexpr double kTargetBand2Share = 0.4;       // SH band 2 may be dropped (L1) below this
constexpr double kTargetMinInterpolation = 0.2; // interpolation's share never falls below this
// Level 0's probes are at most this far apart (metres): a player (about 1.8 m tall) moving through
// a level sees light no coarser than this wherever it stands, before refinement adds detail.
constexpr double kTargetMaxSpacing = 1.0;

// Chooses settings so that the bake's error against a converged path reference is about
// `target` t: every volume becomes bricked (levels 3) with refine_error from the error budget
// and level-0 bricks from the density rule with the spacing scaled by sqrt(t / 0.05) (the
// smooth light level 0 covers has trilinear error growing with the square of the spacing), but
// never more than kTargetMaxSpacing apart;
// SH order L1 where band 2 carries less than kTargetBand2Share x t; the sample count so that
// the interpolated Monte Carlo noise is kTargetNoiseShare x t (from a pilot of two independent
// estimates at 256 points); interpolation gets the rest in quadrature,
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
