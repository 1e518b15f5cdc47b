#include "methods/path_integrator.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <iterator>
#include <limits>
#include <numbers>
#include <optional>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "methods/irradiance_error.hpp"
#include "trace/rng.hpp"
#include "trace/sampling.hpp"

namespace probekit::baker {

namespace {

// The probe's own directions are uniform over the sphere.
constexpr float kProbeDirectionPdf = 1.0f / kFourPi;

// Samples are summed into a block before the block joins the total, so that a probe of many
// thousand samples does not lose the small late terms to float rounding of one long sum.
constexpr uint32_t kSamplesPerBlock = 64;

// The scramble seed of the Sobol set keyed by `key` (a probe's, a batch's or a pixel's). The
// inside-geometry check relies on it to cast exactly the directions the paths will take.
constexpr uint32_t sobolSeed(uint64_t key) {
    return uint32_t(key ^ (key >> 32));
}

} // namespace

PathIntegrator::PathIntegrator(const Scene& scene, const RayTracer& tracer, PathConfig config,
                               sh::Order order, float near_distance)
    : m_scene(scene), m_tracer(tracer), m_config(config), m_nearDistance(near_distance),
      m_order(order), m_lights(scene), m_environmentBlack(scene.environment.isBlack()) {
    assert(config.samples >= 1);
    assert(tracer.triangleCount() == scene.triangles.size());
}

BatchPlan batchPlan(const PathConfig& settings) {
    const uint32_t size = std::clamp(std::bit_floor(std::max(1u, settings.samples / kMinBatches)),
                                     kMinBatchSize, kMaxBatchSize);
    const uint32_t min_batches =
        std::max(kMinBatches, uint32_t((uint64_t(settings.samples) + size - 1) / size));
    const uint32_t max_batches = std::max(min_batches, settings.maxSamples / size);
    return BatchPlan{size, min_batches, max_batches};
}

ProbeSample PathIntegrator::bakeProbe(glm::vec3 position, uint64_t seed, uint32_t volume_index,
                                      uint64_t probe_index, const sh::ShRgb* known) const {
    const ScopedFloatMode float_mode;
    const uint64_t probe_key = hashKeys(seed, volume_index, probe_index);
    ProbeSample inside{};
    if (insideGeometry(position, probe_key, inside)) {
        return inside;
    }

    // Delta lights at the probe itself, projected exactly.
    sh::ShRgb deltas{};
    uint64_t delta_rays = 0;
    for (size_t li = 0; li < m_scene.lights.size(); ++li) {
        const PunctualLight& light = m_scene.lights[li];
        const std::optional<LightDirection> to_light = directionToLight(light, position);
        // A light in mode indirect (Scene::lightDirectStored) reaches the probe only bounced.
        if (!to_light || !m_scene.directStored(li)) {
            continue;
        }
        const glm::vec3 irradiance = normalIrradianceAt(light, position);
        if (isBlack(irradiance)) {
            continue;
        }
        ++delta_rays;
        if (!m_tracer.occluded(position, to_light->direction, to_light->distance)) {
            deltas += sh::projectDelta(to_light->direction, irradiance, m_order);
        }
    }

    ProbeSample result = m_config.noiseTarget > 0.0f
                             ? bakeAdaptive(position, probe_key, deltas, known)
                             : bakeFixed(position, probe_key);
    result.sh += deltas;
    result.rays += delta_rays + inside.rays;
    return result;
}

void PathIntegrator::traceSample(glm::vec3 position, glm::vec3 dir, uint64_t rng_key, uint32_t n,
                                 sh::ShRgb& sh, PathStats& stats) const {
    Rng rng(rng_key);
    const glm::vec3 radiance = incidentRadiance(position, dir, kProbeDirectionPdf, rng, stats);
    probeDirectLight(position, 1.0f / float(n), rng, sh, stats);
    sh::addSample(sh, m_order, dir, radiance, kFourPi / float(n));
}

bool PathIntegrator::insideGeometry(glm::vec3 position, uint64_t probe_key,
                                    ProbeSample& sample) const {
    if (!(m_insideAbove < 1.0f)) {
        return false;
    }
    // The directions the rule counts: fixed sampling's N points of the probe's sequence, or
    // adaptive sampling's minimum batches, each its own sequence (bakeAdaptive, traceBatch).
    const bool adaptive = m_config.noiseTarget > 0.0f;
    const BatchPlan plan = adaptive ? batchPlan(m_config) : BatchPlan{m_config.samples, 1, 1};
    const uint64_t n = uint64_t(plan.size) * plan.minBatches;
    // probeValidity's test on the count over all n; the count only grows, so once it holds (or
    // can no longer hold with every remaining ray a back face) the verdict is final.
    const auto fraction = [n](uint64_t back_faces) {
        return float(double(back_faces) / double(n));
    };
    uint64_t back_faces = 0, cast = 0;
    for (uint32_t group = 0; group < plan.minBatches; ++group) {
        const uint32_t sobol_seed = sobolSeed(adaptive ? hashKeys(probe_key, group) : probe_key);
        for (uint32_t i = 0; i < plan.size; ++i, ++cast) {
            if (!(fraction(back_faces + (n - cast)) > m_insideAbove)) {
                sample.rays = cast;
                return false;
            }
            const glm::vec3 dir = sphereDirection(scrambledSobol2d(i, sobol_seed));
            const std::optional<Hit> hit = m_tracer.intersect(position, dir);
            back_faces += hit && hit->backFace ? 1 : 0;
            if (fraction(back_faces) > m_insideAbove) {
                sample.rays = cast + 1;
                sample.backFaceFraction = float(double(back_faces) / double(cast + 1));
                return true;
            }
        }
    }
    return false;
}

ProbeSample PathIntegrator::bakeFixed(glm::vec3 position, uint64_t probe_key) const {
    const auto sobol_seed = sobolSeed(probe_key);
    const uint32_t n = m_config.samples;

    ProbeSample result{};
    sh::ShRgb block{};
    uint64_t back_faces = 0;
    uint64_t near_hits = 0;
    for (uint32_t i = 0; i < n; ++i) {
        const glm::vec3 dir = sphereDirection(scrambledSobol2d(i, sobol_seed));
        PathStats stats;
        traceSample(position, dir, hashKeys(probe_key, i), n, block, stats);
        result.rays += stats.rays;
        back_faces += stats.primaryBackFace ? 1 : 0;
        near_hits += stats.primaryNear ? 1 : 0;
        if ((i + 1) % kSamplesPerBlock == 0 || i + 1 == n) {
            result.sh += block;
            block = sh::ShRgb{};
        }
    }
    result.backFaceFraction = float(double(back_faces) / double(n));
    result.nearFraction = float(double(near_hits) / double(n));
    result.samples = n;
    return result;
}

sh::ShRgb PathIntegrator::traceBatch(glm::vec3 position, uint64_t batch_key, uint32_t size,
                                     BatchTally& tally) const {
    const auto sobol_seed = sobolSeed(batch_key);
    sh::ShRgb batch{}, block{};
    for (uint32_t i = 0; i < size; ++i) {
        const glm::vec3 dir = sphereDirection(scrambledSobol2d(i, sobol_seed));
        PathStats stats;
        traceSample(position, dir, hashKeys(batch_key, i), size, block, stats);
        tally.rays += stats.rays;
        tally.backFaces += stats.primaryBackFace ? 1 : 0;
        tally.nearHits += stats.primaryNear ? 1 : 0;
        if ((i + 1) % kSamplesPerBlock == 0 || i + 1 == size) {
            batch += block;
            block = sh::ShRgb{};
        }
    }
    return batch;
}

ProbeSample PathIntegrator::bakeAdaptive(glm::vec3 position, uint64_t probe_key,
                                         const sh::ShRgb& fixed_part,
                                         const sh::ShRgb* known) const {
    const BatchPlan plan = batchPlan(m_config);
    constexpr size_t kComponents = std::size(kAxisNormals) * 3;
    const auto axisIrradiance = [this](const sh::ShRgb& sh) {
        std::array<double, kComponents> x{};
        for (size_t a = 0; a < std::size(kAxisNormals); ++a) {
            const glm::vec3 e = sh::irradiance(sh, m_order, kAxisNormals[a]);
            for (int c = 0; c < 3; ++c) {
                x[3 * a + size_t(c)] = double(e[c]);
            }
        }
        return x;
    };
    sh::ShRgb outside = fixed_part;
    if (known != nullptr) {
        outside += *known;
    }
    const std::array<double, kComponents> outside_axis = axisIrradiance(outside);

    ProbeSample result{};
    sh::ShRgb total{}; // sum of the batch estimates
    // Welford's running mean and sum of squared deviations of the batch estimates.
    std::array<double, kComponents> mean{}, m2{};
    BatchTally tally;
    uint32_t batches = 0;
    uint32_t next_check = plan.minBatches;
    double noise = 0.0;
    for (;;) {
        for (; batches < next_check; ++batches) {
            const sh::ShRgb batch =
                traceBatch(position, hashKeys(probe_key, batches), plan.size, tally);
            total += batch;
            const std::array<double, kComponents> x = axisIrradiance(batch);
            for (size_t c = 0; c < kComponents; ++c) {
                const double delta = x[c] - mean[c];
                mean[c] += delta / double(batches + 1);
                m2[c] += delta * (x[c] - mean[c]);
            }
        }
        // Variance of the mean of `batches` independent estimates, and the probe's magnitude.
        double variance = 0.0, magnitude = 0.0;
        for (size_t c = 0; c < kComponents; ++c) {
            variance += m2[c] / double(batches - 1) / double(batches);
            const double e = mean[c] + outside_axis[c];
            magnitude += e * e;
        }
        magnitude = std::max(magnitude, double(kComponents) * double(m_config.noiseFloor) *
                                            double(m_config.noiseFloor));
        noise = magnitude > 0.0  ? std::sqrt(variance / magnitude)
                : variance > 0.0 ? std::numeric_limits<double>::infinity()
                                 : 0.0;
        if (noise <= double(m_config.noiseTarget) || batches >= plan.maxBatches) {
            break;
        }
        // Noise falls as 1 / sqrt(batches): trace to the predicted count, at most doubling.
        const double ratio = noise / double(m_config.noiseTarget);
        const double wanted = std::ceil(double(batches) * std::min(ratio * ratio, 2.0));
        next_check = std::min(plan.maxBatches, std::max(batches + 1, uint32_t(wanted)));
    }
    total *= 1.0f / float(batches);
    result.sh = total;
    const double n = double(batches) * plan.size;
    result.rays = tally.rays;
    result.backFaceFraction = float(double(tally.backFaces) / n);
    result.nearFraction = float(double(tally.nearHits) / n);
    result.samples = batches * plan.size;
    result.noise = float(std::min(noise, double(std::numeric_limits<float>::max())));
    return result;
}

glm::vec3 PathIntegrator::incidentRadiance(glm::vec3 origin, glm::vec3 dir, float dir_pdf, Rng& rng,
                                           PathStats& stats) const {
    std::optional<Hit> hit = m_tracer.intersect(origin, dir);
    ++stats.rays;
    if (!hit) {
        if (m_environmentBlack || !m_scene.environmentDirectStored) {
            return glm::vec3(0.0f);
        }
        // The probe also samples the environment directly (probeDirectLight), as a surface
        // point does (directLight).
        const float mis_weight = m_lights.hasEnvironmentSampling()
                                     ? powerHeuristic(dir_pdf, m_lights.environmentPdf(dir))
                                     : 1.0f;
        return m_scene.environment.radiance(dir) * mis_weight;
    }
    stats.primaryBackFace = hit->backFace;
    const float hit_distance = hit->t; // dir is unit: metres
    stats.primaryNear = hit_distance < m_nearDistance;

    glm::vec3 radiance(0.0f);
    glm::vec3 throughput(1.0f);
    glm::vec3 previous_position = origin;
    // pdf of the direction that reached `hit`.
    float continuation_pdf = dir_pdf;
    for (uint32_t vertex = 0;;) {
        const glm::vec3 position = m_tracer.surfacePoint(hit->triangle, hit->bary);
        const Material& material = m_scene.materials[m_scene.triangleMaterial[hit->triangle]];
        // The first vertex's emission is direct light at the probe: left out in mode indirect.
        if (material.isEmissive() && (vertex > 0 || m_scene.emissiveDirectStored)) {
            const glm::vec3 emitted = m_scene.emissionAt(hit->triangle, hit->bary);
            // The direction that reached this emitter competes with next-event estimation of
            // the same point, from the previous vertex or from the probe itself.
            const float mis_weight = powerHeuristic(
                continuation_pdf, emitterPdfSolidAngle(*hit, position - previous_position));
            radiance += throughput * emitted * mis_weight;
        }
        if (vertex == m_config.maxBounces || !(hit_distance < m_nearDistance)) {
            break;
        }
        ++vertex;

        const glm::vec3 albedo = m_scene.albedoAt(hit->triangle, hit->bary);
        if (isBlack(albedo)) {
            break;
        }
        const glm::vec3 normal = hit->backFace ? -hit->geometricNormal : hit->geometricNormal;
        const glm::vec3 offset_origin =
            RayTracer::offsetOrigin(position, hit->geometricNormal, normal);
        radiance +=
            throughput * albedo * kInvPi * directLight(position, offset_origin, normal, rng, stats);

        // Continuation: cosine sampling makes the Lambertian weight f cos / pdf = albedo.
        const glm::vec3 next_dir = cosineDirection(normal, rng.uniform2());
        continuation_pdf = glm::dot(normal, next_dir) * kInvPi;
        throughput *= albedo;
        if (vertex >= kRouletteStartBounce) {
            const float survival =
                std::min(1.0f, maxComponent(throughput) / m_config.rouletteWeight);
            if (rng.uniform() >= survival) {
                break;
            }
            throughput /= survival;
        }
        hit = m_tracer.intersect(offset_origin, next_dir);
        ++stats.rays;
        if (!hit) {
            if (!m_environmentBlack) {
                const float mis_weight =
                    m_lights.hasEnvironmentSampling()
                        ? powerHeuristic(continuation_pdf, m_lights.environmentPdf(next_dir))
                        : 1.0f;
                radiance += throughput * m_scene.environment.radiance(next_dir) * mis_weight;
            }
            break;
        }
        previous_position = position;
    }
    return radiance;
}

PathIntegrator::SurfaceEstimate
PathIntegrator::surfaceIrradiance(glm::vec3 position, glm::vec3 geometric_normal, glm::vec3 normal,
                                  uint32_t samples, uint64_t key) const {
    const ScopedFloatMode float_mode;
    const auto sobol_seed = sobolSeed(key);
    const glm::vec3 offset_origin = RayTracer::offsetOrigin(position, geometric_normal, normal);
    SurfaceEstimate result;
    // Welford's running mean and sum of squared deviations, in double: a pixel may take many
    // thousand samples of very different size (a direct hit on a small emitter).
    glm::dvec3 mean(0.0), m2(0.0);
    for (uint32_t i = 0; i < samples; ++i) {
        Rng rng(hashKeys(key, i));
        PathStats stats;
        const glm::vec3 dir = cosineDirection(normal, scrambledSobol2d(i, sobol_seed));
        const float cos_theta = glm::dot(normal, dir);
        glm::vec3 e = directLight(position, offset_origin, normal, rng, stats);
        if (cos_theta > 0.0f) {
            // Cosine sampling: L cos / pdf = pi L.
            e += std::numbers::pi_v<float> *
                 incidentRadiance(offset_origin, dir, cos_theta * kInvPi, rng, stats);
        }
        result.rays += stats.rays;
        const glm::dvec3 x(e);
        const glm::dvec3 delta = x - mean;
        mean += delta / double(i + 1);
        m2 += delta * (x - mean);
    }
    result.irradiance = glm::vec3(mean);
    if (samples > 1) {
        result.varianceOfMean = glm::vec3(m2 / (double(samples - 1) * double(samples)));
    }
    return result;
}

std::optional<PathIntegrator::EmitterSampleFrom>
PathIntegrator::sampleEmitterFrom(glm::vec3 position, Rng& rng) const {
    if (!m_lights.hasEmitters()) {
        return std::nullopt;
    }
    const double u_pick = rng.uniformDouble();
    const LightSampler::EmitterSample s = m_lights.sampleEmitter(u_pick, rng.uniform2());
    const glm::vec3 to_emitter = s.position - position;
    const float distance_squared = glm::dot(to_emitter, to_emitter);
    if (!(distance_squared > 0.0f)) {
        return std::nullopt;
    }
    const glm::vec3 wi = to_emitter / std::sqrt(distance_squared);
    const float cos_emitter = std::abs(glm::dot(s.normal, wi)); // two-sided emitters
    const glm::vec3 emitted = m_scene.emissionAt(s.triangle, s.bary);
    if (!(cos_emitter > 0.0f) || isBlack(emitted)) {
        return std::nullopt;
    }
    const float pdf = s.pdfArea * distance_squared / cos_emitter;
    if (!(pdf > 0.0f)) {
        return std::nullopt;
    }
    // Both ends leave their surfaces; with an unnormalised direction, t = 1 is the (offset)
    // emitter point.
    return EmitterSampleFrom{wi, emitted, pdf, RayTracer::offsetOrigin(s.position, s.normal, -wi)};
}

void PathIntegrator::probeDirectLight(glm::vec3 position, float sample_weight, Rng& rng,
                                      sh::ShRgb& sh, PathStats& stats) const {
    // Emitters and environment in mode indirect: sampled all the same, so that every other
    // random number of the bake is the one a baked bake draws; only the shadow ray is skipped.
    const std::optional<EmitterSampleFrom> e = sampleEmitterFrom(position, rng);
    if (e && m_scene.emissiveDirectStored) {
        ++stats.rays;
        if (!m_tracer.occluded(position, e->target - position, 1.0f)) {
            const float w = powerHeuristic(e->pdf, kProbeDirectionPdf);
            sh::addSample(sh, m_order, e->direction, e->emitted * (w / e->pdf), sample_weight);
        }
    }
    if (m_lights.hasEnvironmentSampling()) {
        const double u_row = rng.uniformDouble();
        const double u_column = rng.uniformDouble();
        const LightSampler::DirectionSample s =
            m_lights.sampleEnvironment(u_row, u_column, rng.uniform2());
        if (s.pdf > 0.0f && m_scene.environmentDirectStored) {
            ++stats.rays;
            if (!m_tracer.occluded(position, s.direction, kInfinity)) {
                const float w = powerHeuristic(s.pdf, kProbeDirectionPdf);
                sh::addSample(sh, m_order, s.direction,
                              m_scene.environment.radiance(s.direction) * (w / s.pdf),
                              sample_weight);
            }
        }
    }
}

glm::vec3 PathIntegrator::punctualLight(glm::vec3 position, glm::vec3 offset_origin,
                                        glm::vec3 normal, Rng& rng, PathStats& stats) const {
    glm::vec3 sum(0.0f);
    // Punctual and directional lights are deltas. Each lights the vertex with its unoccluded
    // contribution c (irradiance x cos) times its visibility. With more than
    // PathConfig::shadowRays lights able to light it, light i keeps its shadow ray with
    // probability q_i = min(1, shadowRays c_i / sum c) and a kept one counts 1 / q_i (Russian
    // roulette: unbiased; the bright lights keep q = 1 and add no noise, and the expected
    // count of rays is at most shadowRays).
    struct Lit {
        glm::vec3 direction;
        float distance;
        glm::vec3 contribution;
    };
    // Reused per thread: a vertex of a level with many lights would otherwise allocate.
    thread_local std::vector<Lit> lit;
    lit.clear();
    float total = 0.0f;
    for (const PunctualLight& light : m_scene.lights) {
        const std::optional<LightDirection> to_light = directionToLight(light, position);
        if (!to_light) {
            continue;
        }
        const float cos_theta = glm::dot(normal, to_light->direction);
        if (cos_theta <= 0.0f) {
            continue;
        }
        const glm::vec3 c = normalIrradianceAt(light, position) * cos_theta;
        if (isBlack(c)) {
            continue;
        }
        lit.push_back(Lit{to_light->direction, to_light->distance, c});
        total += c.x + c.y + c.z;
    }
    const bool roulette = m_config.shadowRays > 0 && lit.size() > m_config.shadowRays;
    for (const Lit& l : lit) {
        glm::vec3 c = l.contribution;
        if (roulette) {
            const float q = std::min(1.0f, float(m_config.shadowRays) * (c.x + c.y + c.z) / total);
            if (q < 1.0f) {
                if (!(rng.uniform() < q)) {
                    continue;
                }
                c /= q;
            }
        }
        ++stats.rays;
        if (!m_tracer.occluded(offset_origin, l.direction, l.distance)) {
            sum += c;
        }
    }
    return sum;
}

glm::vec3 PathIntegrator::directLight(glm::vec3 position, glm::vec3 offset_origin, glm::vec3 normal,
                                      Rng& rng, PathStats& stats) const {
    glm::vec3 sum(0.0f);

    // (a) Punctual and directional lights (punctualLight).
    sum += punctualLight(position, offset_origin, normal, rng, stats);

    // (b) One emissive-triangle sample, MIS against the cosine-sampled continuation.
    if (const std::optional<EmitterSampleFrom> e = sampleEmitterFrom(position, rng)) {
        const float cos_theta = glm::dot(normal, e->direction);
        if (cos_theta > 0.0f) {
            ++stats.rays;
            if (!m_tracer.occluded(offset_origin, e->target - offset_origin, 1.0f)) {
                sum +=
                    e->emitted * (cos_theta * powerHeuristic(e->pdf, cos_theta * kInvPi) / e->pdf);
            }
        }
    }

    // (c) One environment sample for lat-long maps, MIS against the continuation.
    if (m_lights.hasEnvironmentSampling()) {
        const double u_row = rng.uniformDouble();
        const double u_column = rng.uniformDouble();
        const LightSampler::DirectionSample s =
            m_lights.sampleEnvironment(u_row, u_column, rng.uniform2());
        const float cos_theta = glm::dot(normal, s.direction);
        if (cos_theta > 0.0f && s.pdf > 0.0f) {
            ++stats.rays;
            if (!m_tracer.occluded(offset_origin, s.direction, kInfinity)) {
                sum += m_scene.environment.radiance(s.direction) *
                       (cos_theta * powerHeuristic(s.pdf, cos_theta * kInvPi) / s.pdf);
            }
        }
    }
    return sum;
}

float PathIntegrator::emitterPdfSolidAngle(const Hit& hit, glm::vec3 from_previous) const {
    const float pdf_area = m_lights.emitterPdfArea(hit.triangle);
    if (pdf_area == 0.0f) {
        return 0.0f;
    }
    const float distance_squared = glm::dot(from_previous, from_previous);
    if (!(distance_squared > 0.0f)) {
        return 0.0f;
    }
    const float cos_emitter =
        std::abs(glm::dot(hit.geometricNormal, from_previous)) / std::sqrt(distance_squared);
    return cos_emitter > 0.0f ? pdf_area * distance_squared / cos_emitter : 0.0f;
}

} // namespace probekit::baker
