// probekit::baker::PathIntegrator — the path-traced reference for SH light probes.
//
// This is the accuracy reference every faster method is measured against, so it is unbiased
// first (up to the documented bounce cap) and fast second.
//
// Per probe, `samples` directions cover the whole sphere: point i of a per-probe shuffled,
// Owen-scrambled 2D Sobol sequence (rng.hpp) mapped by z = 1 - 2u, phi = 2 pi v (an equal-area
// map), so each direction is uniform on the sphere and the set is stratified; each incident
// radiance is projected with weight 4 pi / N (sh::addSample).
//
// Incident radiance along a direction is estimated by unidirectional path tracing:
//  * Surfaces are two-sided Lambertian (Scene::albedoAt) and two-sided emitters
//    (Scene::emissionAt); the shading normal is the geometric normal turned to face the
//    arriving ray. Emission seen directly from the probe counts fully (the probe is not a
//    surface and samples no lights).
//  * At every diffuse vertex: next-event estimation to (a) every punctual light (point, spot,
//    directional: normalIrradianceAt x cos x albedo / pi, one shadow ray each; with more lights
//    than PathConfig::shadowRays able to light the vertex, each ray is kept with probability
//    min(1, shadowRays x its share of their unoccluded sum) and weighted by its inverse),
//    (b) one emissive-triangle sample (LightSampler), (c) one environment sample for lat-long
//    maps (LightSampler). (b) and (c) are combined with the cosine-sampled continuation by
//    multiple importance sampling with the power heuristic (Veach 1997, ch. 9). A constant
//    environment is reached by the continuation only (cosine sampling is already ideal there).
//  * Russian roulette on the continuation from the kRouletteStartBounce-th vertex on, as a
//    weight window: survival probability min(1, max channel of the path throughput /
//    PathConfig::rouletteWeight), the survivor divided by it (unbiased). A path is never cut
//    while its throughput is above the window, and a survivor's weight is the window's, so the
//    roulette adds at most that much weight to any one path.
//  * maxBounces caps the number of diffuse vertices; the emission reached after the last one is
//    still counted, so maxBounces = 0 keeps only what the probe sees directly. The cap
//    truncates energy: in a closed room of albedo a the missing fraction is a^(maxBounces+1).
//    The default, PathConfig::maxBounces = 64, puts that below the noise of any sample count
//    (0.73^65 = 1e-9 for the Cornell box's white); Russian roulette ends almost every path long
//    before, so it costs nothing measurable against a cap of 8 (which lost 0.5-1.4% on the bundled
//    rooms).
//
// Adaptive sampling (PathConfig::noiseTarget > 0). The directions come in batches of B, each
// batch the first B points of its own independently scrambled Sobol sequence, so the batch
// estimates are independent and each is unbiased; the probe is their mean. After every batch
// from the minimum on, the probe's relative noise is estimated from the spread of the batch
// estimates, in the project's error measure (irradiance at the six axis normals, three
// channels; irradiance_error.hpp):
//     noise^2 = sum_c s_c^2 / K  /  sum_c (mean_c + known_c)^2
// with s_c^2 the unbiased sample variance of component c over the K batches and known_c the
// exact or separately estimated light the caller adds (delta lights at the probe, a VPL gather,
// LPV cascades); the denominator is at least 18 noiseFloor^2. The probe stops once noise <=
// noiseTarget or K reaches the cap; otherwise it traces up to the number of batches the estimate
// predicts, at most twice the present number, before it checks again. The rule reads only the
// probe's own samples, so the result does not depend on threads or order.
//
// Probes inside geometry (stopInsideGeometry(threshold)): before any path, the primary rays
// alone of the directions the paths would take first (fixed sampling's N; adaptive sampling's
// minimum batches) are cast and their back faces counted, and the count stops as soon as
// probeValidity's verdict on it is known. A probe found inside geometry returns there with no
// value (the bake discards it and dilates). Any other probe is traced as without the check, to
// the same bits: fixed sampling's verdict is the same, and an adaptive probe is invalid after
// its minimum exactly when the check finds it. The check costs at most N primary rays on a valid
// probe, against the N paths (a shadow ray per light at every vertex) an invalid one does not take.
//
// Punctual and directional lights are deltas: no sampled direction can hit them, so their
// direct light at the probe is added analytically, projectDelta(dir to light,
// normalIrradianceAt(p)) when the shadow ray from the probe is unoccluded.
#pragma once

#include <cstdint>
#include <optional>

#include <glm/vec3.hpp>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"
#include "trace/light_sampler.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {

class Rng;

// The first path vertex whose continuation Russian roulette may terminate.
constexpr uint32_t kRouletteStartBounce = 3;

// Adaptive sampling: at least kMinBatches batches; a batch holds samples / kMinBatches
// directions rounded down to a power of two, within kMinBatchSize..kMaxBatchSize.
constexpr uint32_t kMinBatches = 8;
constexpr uint32_t kMinBatchSize = 16;
constexpr uint32_t kMaxBatchSize = 1024;

// The batch size and the minimum and maximum batch counts adaptive sampling uses for `settings`.
struct BatchPlan {
    uint32_t size;
    uint32_t minBatches;
    uint32_t maxBatches;
};
BatchPlan batchPlan(const PathConfig& config);

struct ProbeSample {
    sh::ShRgb sh;           // radiance SH, world frame, `order` coefficients (rest zero)
    float backFaceFraction; // primary rays that hit a back face / all primary rays
    uint64_t rays;          // every ray traced: primary, continuation and shadow
    float nearFraction;     // primary rays that hit nearer than nearDistance / all
    uint32_t samples = 0;   // directions traced
    // Adaptive sampling: the estimated relative noise at the stop (see above); 0 for fixed
    // sampling, and for a probe whose batches all agree.
    float noise = 0.0f;
};

// The validity rule of every bake: a probe whose primary rays hit back faces more often than
// `backface_threshold` (BakeConfig::backfaceThreshold) is inside geometry.
inline uint8_t probeValidity(const ProbeSample& s, float backface_threshold) {
    return s.backFaceFraction > backface_threshold ? kProbeInvalid : kProbeValid;
}

class PathIntegrator {
public:
    // `scene` and `tracer` (built from the same scene) must outlive the integrator. Builds the
    // light-sampling distributions once. `config` is the bake's PathConfig as the method uses
    // it (vpl and lpv set their own direct-light samples and bounces in a copy). Paths whose
    // first hit is `near_distance` metres from the probe or farther stop there (as with
    // maxBounces = 0): the VPL method gathers the light those surfaces reflect from its VPLs
    // and path-traces only the near field (vpl_gather.hpp); infinite for the other methods.
    PathIntegrator(const Scene& scene, const RayTracer& tracer, PathConfig config, sh::Order order,
                   float near_distance = kInfinity);

    // Thread-safe and deterministic: every random number comes from (seed, volume_index,
    // probe_index, sample index) through rng.hpp, so the result is bit-identical whatever the
    // thread or call order. Sets flush-to-zero / denormals-are-zero for its duration (Embree's
    // recommended mode) and restores the caller's mode, so results do not depend on the
    // calling thread's floating-point state either.
    //
    // `known` (adaptive sampling only): light the caller adds to this probe from elsewhere,
    // counted in the relative noise's denominator (it carries no noise of this integrator's).
    ProbeSample bakeProbe(glm::vec3 position, uint64_t seed, uint32_t volume_index,
                          uint64_t probe_index, const sh::ShRgb* known = nullptr) const;

    // Irradiance at a surface point, the per-pixel reference (surface_reference.hpp): E at
    // `position` for the unit shading normal `normal` (on the side of `geometric_normal` the
    // receiver faces), estimated with `samples` cosine-distributed directions (a scrambled
    // Sobol set keyed by `key`) and next-event estimation at the point itself, exactly as at a
    // path vertex with albedo 1: E_i = directLight + pi x L(cosine direction). Returns the mean
    // and the variance of the mean per channel (the sample variance / samples: an upper bound
    // for the stratified set).
    struct SurfaceEstimate {
        glm::vec3 irradiance{0.0f};     // W/m^2
        glm::vec3 varianceOfMean{0.0f}; // (W/m^2)^2
        uint64_t rays = 0;
    };
    SurfaceEstimate surfaceIrradiance(glm::vec3 position, glm::vec3 geometric_normal,
                                      glm::vec3 normal, uint32_t samples, uint64_t key) const;

    const PathConfig& config() const { return m_config; }

    // Probes that probeValidity(sample, backface_threshold) calls invalid on their first
    // directions are found from primary rays before any path is traced, and return with a zero
    // value, samples = 0 and their back-face fraction over the rays cast (see above). Off by
    // default (every probe fully traced), and without effect at a threshold of 1 or more.
    void stopInsideGeometry(float backface_threshold) { m_insideAbove = backface_threshold; }

private:
    struct PathStats {
        uint64_t rays = 0;
        bool primaryBackFace = false;
        bool primaryNear = false;
    };

    // The pre-pass of stopInsideGeometry: true when the probe's primary rays decide it is
    // inside geometry, `sample` then holding the back-face fraction; sample.rays counts the
    // rays cast either way.
    bool insideGeometry(glm::vec3 position, uint64_t probe_key, ProbeSample& sample) const;
    // Fixed sampling: `samples` points of one Sobol sequence.
    ProbeSample bakeFixed(glm::vec3 position, uint64_t probe_key) const;
    // Adaptive sampling (see above); `fixed_part` is the delta lights' exact SH at the probe.
    ProbeSample bakeAdaptive(glm::vec3 position, uint64_t probe_key, const sh::ShRgb& fixed_part,
                             const sh::ShRgb* known) const;
    // The rays and primary-hit counts of the directions traced so far for one probe.
    struct BatchTally {
        uint64_t rays = 0;
        uint64_t backFaces = 0;
        uint64_t nearHits = 0;
    };
    // One batch of `size` Sobol directions (scrambled by `batch_key`): its estimate, summed in
    // blocks of kSamplesPerBlock; the rays and hits go into `tally`.
    sh::ShRgb traceBatch(glm::vec3 position, uint64_t batch_key, uint32_t size,
                         BatchTally& tally) const;
    // One direction's path and the probe's own next-event estimation, added into `sh` with
    // sample weight 1 / n.
    void traceSample(glm::vec3 position, glm::vec3 dir, uint64_t rng_key, uint32_t n, sh::ShRgb& sh,
                     PathStats& stats) const;

    // Radiance arriving at `origin` from direction `dir` (unit), estimated with one path.
    // `dir_pdf` is the solid-angle pdf `dir` was drawn with (the probe's uniform sphere, or a
    // surface's cosine lobe): the MIS weight of an emitter or environment it reaches directly.
    glm::vec3 incidentRadiance(glm::vec3 origin, glm::vec3 dir, float dir_pdf, Rng& rng,
                               PathStats& stats) const;

    // One emissive-triangle sample seen from `position`: direction, emitted radiance, solid-angle
    // pdf and the shadow-ray target (the emitter point moved off its surface). Nothing when the
    // sample cannot contribute (no emitters, seen edge-on, black).
    struct EmitterSampleFrom {
        glm::vec3 direction;
        glm::vec3 emitted;
        float pdf;
        glm::vec3 target;
    };
    std::optional<EmitterSampleFrom> sampleEmitterFrom(glm::vec3 position, Rng& rng) const;

    // Next-event estimation at the probe itself: one emissive-triangle sample and (for lat-long
    // maps) one environment sample, MIS-weighted against the probe's uniform sphere directions
    // (pdf 1 / 4 pi). Adds `radiance / pdf x weight` at the sampled direction into `sh` with
    // sample weight `sample_weight` (1 / N). A small bright emitter seen directly is otherwise
    // the dominant noise of the probe.
    void probeDirectLight(glm::vec3 position, float sample_weight, Rng& rng, sh::ShRgb& sh,
                          PathStats& stats) const;

    // directLight's punctual and directional lights: the sum of their irradiance x cos, one
    // shadow ray each, or by Russian roulette past PathConfig::shadowRays (see above).
    glm::vec3 punctualLight(glm::vec3 position, glm::vec3 offset_origin, glm::vec3 normal, Rng& rng,
                            PathStats& stats) const;

    // Next-event estimation at a diffuse vertex: the sum over lights of (incident radiance x
    // cos / pdf, MIS-weighted), to be multiplied by albedo / pi. `offset_origin` is the vertex
    // moved off the surface to the side of `normal` (the shading normal).
    glm::vec3 directLight(glm::vec3 position, glm::vec3 offset_origin, glm::vec3 normal, Rng& rng,
                          PathStats& stats) const;

    // Solid-angle pdf with which next-event estimation at the previous vertex would have picked
    // `hit`, reached along `from_previous` (hit point - previous vertex; 0 if the
    // triangle is not an emitter), for the MIS weight of the continuation that reached it.
    float emitterPdfSolidAngle(const Hit& hit, glm::vec3 from_previous) const;

    const Scene& m_scene;
    const RayTracer& m_tracer;
    PathConfig m_config;
    float m_nearDistance;
    sh::Order m_order;
    LightSampler m_lights;
    bool m_environmentBlack;
    float m_insideAbove = 1.0f; // stopInsideGeometry's threshold; 1: off
};

} // namespace probekit::baker
