// References at points, the error measure, and the settings --target-error chooses.
#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "methods/irradiance_error.hpp"
#include "methods/path_integrator.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/target.hpp"
#include "trace/parallel.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {
namespace {

// Volume index reserved for reference and pilot estimates, so that their sample sequences
// never coincide with a volume's probes.
constexpr uint32_t kReferenceVolumeIndex = 0xfffffff0u;

double radicalInverse(uint64_t i, uint32_t base) {
    double inverse = 1.0 / base, factor = inverse, result = 0.0;
    while (i > 0) {
        result += double(i % base) * factor;
        i /= base;
        factor *= inverse;
    }
    return result;
}

sh::ShRgb mean(const sh::ShRgb& a, const sh::ShRgb& b) {
    sh::ShRgb m = a;
    m += b;
    m *= 0.5f;
    return m;
}

} // namespace

std::vector<glm::vec3> volumeSamplePoints(const std::vector<VolumeDesc>& volumes, size_t count) {
    std::vector<double> cumulative;
    double total = 0.0;
    for (const VolumeDesc& d : volumes) {
        const glm::vec3 s = d.grid.bounds().size();
        total += double(s.x) * s.y * s.z;
        cumulative.push_back(total);
    }
    std::vector<glm::vec3> points;
    if (volumes.empty() || !(total > 0.0)) {
        return points;
    }
    points.reserve(count);
    for (size_t i = 0; i < count; ++i) {
        // Halton bases 2, 3, 5 inside the box, base 7 picks the box; index from 1 (0 is a
        // corner).
        const double pick = radicalInverse(i + 1, 7) * total;
        const size_t v = size_t(std::upper_bound(cumulative.begin(), cumulative.end(), pick) -
                                cumulative.begin());
        const VolumeDesc& d = volumes[std::min(v, volumes.size() - 1)];
        const glm::vec3 t(float(radicalInverse(i + 1, 2)), float(radicalInverse(i + 1, 3)),
                          float(radicalInverse(i + 1, 5)));
        const grid::Aabb& box = d.grid.bounds();
        points.push_back(d.grid.frame().toWorld(box.min + t * box.size()));
    }
    return points;
}

Result<PointBake> bakePoints(const Scene& scene, const BakeConfig& config,
                             const std::vector<glm::vec3>& points, uint32_t samples,
                             uint32_t stream, uint32_t threads) {
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    if (!tracer) {
        return tracer.error();
    }
    // The bake's own path settings (bounces, shadow rays), at a fixed `samples` directions.
    PathConfig settings = config.path;
    settings.samples = samples;
    settings.noiseTarget = 0.0f;
    PathIntegrator integrator(scene, *tracer.value(), settings, sh::Order::L2);
    // Points inside geometry are skipped by every comparison: their paths are not traced.
    integrator.stopInsideGeometry(config.backfaceThreshold);
    PointBake out;
    out.sh.resize(points.size());
    out.valid.resize(points.size());
    std::atomic<uint64_t> rays{0};
    const auto start = std::chrono::steady_clock::now();
    parallelFor(points.size(), threads, 1, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            const ProbeSample s =
                integrator.bakeProbe(points[i], config.seed, kReferenceVolumeIndex - stream, i);
            out.sh[i] = s.sh;
            out.valid[i] = probeValidity(s, config.backfaceThreshold);
            rays.fetch_add(s.rays);
        }
    });
    out.rays = rays.load();
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return out;
}

ErrorEstimate
estimateError(const std::function<glm::vec3(glm::vec3 point, glm::vec3 normal)>& irradiance,
              const std::vector<glm::vec3>& points, const PointBake& ref_a,
              const PointBake& ref_b) {
    struct Point {
        double error2 = 0.0, reference2 = 0.0, noise2 = 0.0;
    };
    std::vector<Point> compared;
    for (size_t i = 0; i < points.size(); ++i) {
        if (ref_a.valid[i] != kProbeValid || ref_b.valid[i] != kProbeValid) {
            continue;
        }
        const sh::ShRgb reference = mean(ref_a.sh[i], ref_b.sh[i]);
        Point p;
        for (const glm::vec3& n : kAxisNormals) {
            const glm::vec3 r = sh::irradiance(reference, sh::Order::L2, n);
            const glm::vec3 d = irradiance(points[i], n) - r;
            p.error2 += double(glm::dot(d, d));
            p.reference2 += double(glm::dot(r, r));
        }
        // Var(mean of two) = E|a - b|^2 / 4.
        p.noise2 = 0.25 * squaredAxisIrradianceDifference(ref_a.sh[i], ref_b.sh[i], sh::Order::L2);
        compared.push_back(p);
    }
    std::vector<double> squares;
    for (const Point& p : compared) {
        squares.push_back(p.reference2);
    }
    const double cap = brightPointCap(squares);
    ErrorEstimate e;
    e.points = compared.size();
    double error2 = 0.0, reference2 = 0.0, noise2 = 0.0, weight2 = 0.0;
    for (const Point& p : compared) {
        const double s = brightPointWeight(p.reference2, cap);
        e.cappedPoints += s < 1.0;
        error2 += s * p.error2;
        reference2 += s * p.reference2;
        noise2 += s * p.noise2;
        weight2 += s * p.reference2 * s * p.reference2;
    }
    if (reference2 > 0.0) {
        e.relRmseRaw = std::sqrt(error2 / reference2);
        e.referenceNoise = std::sqrt(noise2 / reference2);
        e.relRmse = std::sqrt(std::max(0.0, error2 - noise2) / reference2);
        e.effectivePoints = reference2 * reference2 / weight2;
    }
    return e;
}

namespace {

// Every volume becomes bricked, centre-placed, refinable to the deepest level, its level-0
// resolution left to the density rule (resolved by the caller) and its budget that of a
// dense grid (the planner's calibration, kDensityTarget, was measured with both).
void makeVolumesRefinable(BakeConfig& config) {
    config.volumes = volumeConfigs(config);
    for (VolumeConfig& v : config.volumes) {
        v.layout = VolumeLayout::Bricked;
        v.position = grid::PositionMode::Center;
        v.maxLevel = brick::kMaxLevel;
        v.resolution.reset(); // level 0 from the density rule
        v.maxProbes = v.maxProbes.value_or(kDefaultMaxProbes);
    }
}

// The planner scales level 0 from a dense grid's density rule (kDefaultDensity), not from the
// coarser default of a bricked volume (kBrickedDensity): each volume without a density gets
// the dense rule's over the box its first placement found, and is placed again with the
// padding that placement chose, so automatic padding traces its test rays once.
Result<std::vector<VolumeDesc>> placeAtDenseDensity(const Scene& scene, BakeConfig& config) {
    Result<VolumePlan> first = planVolumes(scene, config);
    if (!first) {
        return first.error();
    }
    bool changed = false;
    BakeConfig again = config;
    for (size_t i = 0; i < config.volumes.size(); ++i) {
        if (!config.volumes[i].density) {
            config.volumes[i].density =
                automaticDensity(first.value().volumes[i].grid.bounds(), VolumeLayout::Dense);
            again.volumes[i].density = config.volumes[i].density;
            again.volumes[i].bounds.padding = first.value().padding[i];
            changed = true;
        }
    }
    if (!changed) {
        return std::move(first).value().volumes;
    }
    return resolveVolumes(scene, again);
}

// Level 0 covers the smooth light, where trilinear error grows with the square of the spacing:
// its spacing scales with sqrt(target / kDensityTarget) from the density rule's (which suits
// kDensityTarget); refinement adds the detail. It is never coarser than kTargetMaxSpacing, so
// a level gets probes at most that far apart wherever a player can be, lit or not.
void chooseLevel0Resolution(const std::vector<VolumeDesc>& descs, double target,
                            BakeConfig& config) {
    constexpr double kDensityTarget = 0.05;
    const double spacing_scale = std::sqrt(target / kDensityTarget);
    for (size_t i = 0; i < descs.size(); ++i) {
        const glm::uvec3 top = descs[i].grid.resolution();
        const glm::vec3 extent = descs[i].grid.bounds().size();
        glm::uvec3 chosen;
        for (int a = 0; a < 3; ++a) {
            const double bricks = double(top[a]) / spacing_scale;
            const uint32_t by_error = 1u << uint32_t(std::max(0L, std::lround(std::log2(bricks))));
            // Level 0 holds kBrickCells cells per brick.
            const double fewest = double(extent[a]) / (kTargetMaxSpacing * brick::kBrickCells);
            const uint32_t by_spacing = std::bit_ceil(uint32_t(std::ceil(std::max(1.0, fewest))));
            chosen[a] = std::clamp(std::max(by_error, by_spacing), 1u, grid::kMaxResolution);
        }
        config.volumes[i].resolution = chosen;
    }
}

constexpr uint32_t kPilotSamples = 256;

// What the pilot measured that the budget and the plan use after it.
struct PilotFigures {
    // Mean over the valid points of the squared reference irradiance (summed over the six axis
    // normals and three channels) in the bounded measure, each point weighed by
    // brightPointWeight: the noise floor's square. The plain mean is set by whichever point
    // lands nearest a light: on the closed arena it read 0.95 W/m^2 RMS at 64 points and 2.94
    // at 256, and a floor that high let every darker probe stay three times noisier.
    double floor2 = 0.0;
    // Per valid point: one 256-direction estimate's noise variance relative to its irradiance
    // (or to the noise floor where darker), what adaptive sampling compares.
    std::vector<double> relativeNoise2;
    double secondsPerPoint = 0.0; // tracing, per point and estimate
};

// Pilot: two independent estimates at kPilotPoints points give the noise of one estimate and
// band 2's share of the irradiance (choice.pilotNoise, band2, pilotPoints). Each point's noise
// comes from one pair of estimates and a few noisy points dominate the mean: at 64 points the
// closed arena's noise ranged 0.051-0.079 over eight seeds, so each seed chose another
// refine_error (0.080-0.092) and refined other bricks; at 256 points, 0.059-0.069, for about
// 0.2 s.
Result<PilotFigures> runPilot(const Scene& scene, const BakeConfig& base,
                              const std::vector<VolumeDesc>& descs, uint32_t threads,
                              TargetChoice& choice) {
    constexpr size_t kPilotPoints = 256;
    const std::vector<glm::vec3> points = volumeSamplePoints(descs, kPilotPoints);
    Result<PointBake> a = bakePoints(scene, base, points, kPilotSamples, 11, threads);
    if (!a) {
        return a.error();
    }
    Result<PointBake> b = bakePoints(scene, base, points, kPilotSamples, 12, threads);
    if (!b) {
        return b.error();
    }
    struct Point {
        double noise2, reference2, band2;
    };
    std::vector<Point> pilot;
    std::vector<double> squares;
    for (size_t i = 0; i < points.size(); ++i) {
        if (a.value().valid[i] != kProbeValid || b.value().valid[i] != kProbeValid) {
            continue;
        }
        const sh::ShRgb m = mean(a.value().sh[i], b.value().sh[i]);
        // One estimate's variance: E|a - b|^2 / 2.
        pilot.push_back(
            {0.5 * squaredAxisIrradianceDifference(a.value().sh[i], b.value().sh[i], sh::Order::L2),
             squaredAxisIrradiance(m, sh::Order::L2),
             squaredAxisIrradianceDifference(m, sh::truncateToL1(m), sh::Order::L2)});
        squares.push_back(pilot.back().reference2);
    }
    // Noise, band 2 and the noise floor in the bounded measure --verify uses.
    const double cap = brightPointCap(squares);
    double noise2 = 0.0, band2 = 0.0, bounded2 = 0.0;
    for (const Point& p : pilot) {
        const double w = brightPointWeight(p.reference2, cap);
        noise2 += w * p.noise2;
        band2 += w * p.band2;
        bounded2 += w * p.reference2;
    }
    choice.pilotPoints = uint32_t(pilot.size());
    if (choice.pilotPoints == 0 || !(bounded2 > 0.0)) {
        return makeError(ErrorCode::InvalidArgument,
                         "target_error: no pilot point outside geometry receives light; the "
                         "error of a black scene is not defined");
    }
    choice.pilotSamples = kPilotSamples;
    PilotFigures figures;
    figures.floor2 = bounded2 / double(pilot.size());
    figures.secondsPerPoint =
        (a.value().seconds + b.value().seconds) / (2.0 * double(points.size()));
    for (const Point& p : pilot) {
        figures.relativeNoise2.push_back(p.noise2 / std::max(p.reference2, figures.floor2));
    }
    choice.pilotNoise = std::sqrt(noise2 / bounded2);
    // Band 2's own share, less the noise it carries (band 2 is 5 of the 9 coefficients).
    choice.band2 = std::sqrt(
        std::max(0.0, band2 / bounded2 - 5.0 / 9.0 * 0.5 * choice.pilotNoise * choice.pilotNoise));
    return figures;
}

// Splits the target between noise, SH order and interpolation from the pilot's figures, and
// writes the resulting settings into choice.config.
void allocateErrorBudget(Method method, double target, double floor2, TargetChoice& choice) {
    const double noise_budget = kTargetNoiseShare * target;
    choice.shOrder = choice.band2 < kTargetBand2Share * target ? sh::Order::L1 : sh::Order::L2;
    const double sh_error = choice.shOrder == sh::Order::L1 ? choice.band2 : 0.0;
    // Trilinear interpolation averages 8 probes: over uniform positions the noise variance
    // falls to (2/3)^3 of one probe's.
    constexpr double kInterpolatedVariance = 8.0 / 27.0;
    const double wanted = double(kPilotSamples) * choice.pilotNoise * choice.pilotNoise *
                          kInterpolatedVariance / (noise_budget * noise_budget);
    choice.samplesWanted = std::ceil(wanted);
    choice.samples = uint32_t(
        std::clamp(choice.samplesWanted, double(kTargetMinSamples), double(kTargetMaxSamples)));
    choice.predictedNoise = choice.pilotNoise * std::sqrt(double(kPilotSamples) / choice.samples *
                                                          kInterpolatedVariance);
    choice.interpolationBudget = std::sqrt(std::max(
        target * target - choice.predictedNoise * choice.predictedNoise - sh_error * sh_error,
        kTargetMinInterpolation * kTargetMinInterpolation * target * target));

    // Adaptive sampling spends the directions where the noise is: a probe whose noise
    // relative to its own irradiance meets probeNoiseTarget meets the share over the volume.
    choice.minSamples =
        std::clamp(std::bit_floor(std::max(1u, choice.samples / 8)), kTargetMinSamples, 4096u);
    choice.probeNoiseTarget = noise_budget / std::sqrt(kInterpolatedVariance);
    choice.config.path.noiseTarget = float(choice.probeNoiseTarget);
    // The error is relative to the volume's RMS irradiance, not each probe's: a dark probe's
    // noise is held to the pilot's RMS irradiance, not chased to a fraction of its own.
    choice.noiseFloor = std::sqrt(floor2 / 18.0); // RMS over 6 normals x 3 channels
    choice.config.path.noiseFloor = float(choice.noiseFloor);
    choice.config.path.maxSamples = kTargetMaxSamples;
    if (method == Method::Path) {
        choice.config.path.samples = choice.minSamples;
    } else if (method == Method::Vpl) {
        choice.config.vpl.directSamples = choice.minSamples;
    } else {
        choice.config.lpv.directSamples = choice.minSamples;
    }
    for (VolumeConfig& v : choice.config.volumes) {
        v.shOrder = choice.shOrder;
        v.refineError = float(choice.interpolationBudget);
    }
}

// Level 0's probes and seconds (TargetChoice's plan). Adaptive sampling traces a probe until
// its relative noise meets probeNoiseTarget: at N directions a point's noise variance is its
// 256-direction one times 256 / N.
void planLevelZero(const PilotFigures& pilot, TargetChoice& choice) {
    for (const VolumeConfig& v : choice.config.volumes) {
        const glm::uvec3 points = *v.resolution * brick::kBrickCells + 1u;
        choice.levelZeroProbes += uint64_t(points.x) * points.y * points.z;
    }
    double directions = 0.0;
    const double target2 = choice.probeNoiseTarget * choice.probeNoiseTarget;
    for (double rel2 : pilot.relativeNoise2) {
        directions += std::clamp(double(kPilotSamples) * rel2 / target2, double(choice.minSamples),
                                 double(kTargetMaxSamples));
    }
    choice.expectedDirections = directions / double(pilot.relativeNoise2.size());
    choice.levelZeroSeconds = double(choice.levelZeroProbes) * pilot.secondsPerPoint *
                              choice.expectedDirections / double(kPilotSamples);
}

} // namespace

Result<TargetChoice> chooseSettings(const Scene& scene, const BakeConfig& base, double target,
                                    uint32_t threads) {
    if (!(target > 0.0) || !(target < 1.0)) {
        return makeError(ErrorCode::InvalidArgument,
                         "target_error: " + std::to_string(target) + " is not in (0, 1)");
    }
    const auto start = std::chrono::steady_clock::now();
    TargetChoice choice;
    choice.target = target;
    choice.config = base;
    makeVolumesRefinable(choice.config);
    Result<std::vector<VolumeDesc>> descs = placeAtDenseDensity(scene, choice.config);
    if (!descs) {
        return descs.error();
    }
    chooseLevel0Resolution(descs.value(), target, choice.config);
    Result<PilotFigures> pilot = runPilot(scene, base, descs.value(), threads, choice);
    if (!pilot) {
        return pilot.error();
    }
    allocateErrorBudget(base.method, target, pilot.value().floor2, choice);
    planLevelZero(pilot.value(), choice);
    choice.pilotSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return choice;
}

double predictError(const TargetChoice& choice, const BakeStats& stats) {
    const double sh_error = choice.shOrder == sh::Order::L1 ? choice.band2 : 0.0;
    return std::sqrt(stats.predictedInterpolationError * stats.predictedInterpolationError +
                     choice.predictedNoise * choice.predictedNoise + sh_error * sh_error);
}

std::string explainError(const TargetChoice& choice, const BakeStats& stats) {
    const double sh_error = choice.shOrder == sh::Order::L1 ? choice.band2 : 0.0;
    const double interpolation = stats.predictedInterpolationError;
    const double noise = choice.predictedNoise;
    char text[400];
    if (interpolation >= noise && interpolation >= sh_error) {
        const char* limit = stats.memoryUntested > 0
                                ? "max_memory_mb's working memory left candidate bricks unrefined"
                            : stats.budgetDropped > 0
                                ? "max_memory_mb's GPU budget dropped finer bricks"
                                : "refinement stopped at the deepest level (3)";
        std::snprintf(text, sizeof text, "interpolation %.3g is the largest term (budget %.3g): %s",
                      interpolation, choice.interpolationBudget, limit);
    } else if (noise >= sh_error) {
        std::snprintf(text, sizeof text,
                      "noise %.3g is the largest term at %u directions per probe%s", noise,
                      choice.samples, choice.samples >= kTargetMaxSamples ? " (the cap)" : "");
    } else {
        std::snprintf(text, sizeof text, "SH band 2 %.3g, dropped by L1, is the largest term",
                      sh_error);
    }
    return text;
}

} // namespace probekit::baker
