#include "methods/vpl_paths.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <optional>

#include <glm/geometric.hpp>

#include "trace/light_sampler.hpp"
#include "trace/rng.hpp"
#include "trace/sampling.hpp"

namespace probekit::baker {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Stream keys: each kind of random number gets its own hash domain, so no two uses share a
// stream.
constexpr uint64_t kPilotStream = 0x70696c6f74ull;      // "pilot"
constexpr uint64_t kStartStream = 0x7374617274ull;      // "start" (random sampling)
constexpr uint64_t kJitterStream = 0x6a6974746572ull;   // "jitter"
constexpr uint64_t kHaltonStream = 0x68616c746f6eull;   // "halton"
constexpr uint64_t kContinueStream = 0x636f6e74696eull; // "contin(uation)"
constexpr uint64_t kPermutationStream = 0x7065726dull;  // "perm"

// The first primes: one Halton base per light-path dimension.
constexpr std::array<uint32_t, kVplPathDimensions> kHaltonBases = {2, 3, 5, 7, 11, 13, 17};

// Largest double below 1: every uniform handed out stays in [0, 1).
constexpr double kOneMinusEpsilon = 0x1.fffffffffffffp-1;

// Radical inverse of `index` in `base` with a nested random digit scramble: output digit k is
// the index's k-th digit cyclically shifted by a hash of (key, the k digits before it). Digits
// continue past the index's own (as zeros, shifted) until they fall below double resolution,
// so the scrambled point is uniform in its elementary interval (Owen 1995's nested scramble,
// restricted to cyclic shifts).
double scrambledRadicalInverse(uint32_t index, uint32_t base, uint64_t key) {
    const double inverse_base = 1.0 / double(base);
    double scale = inverse_base;
    double result = 0.0;
    uint64_t prefix = key;
    while (scale > 0x1p-52) {
        const uint32_t digit = index % base;
        index /= base;
        const auto shift = uint32_t(mix64(prefix) % base);
        result += double((digit + shift) % base) * scale;
        scale *= inverse_base;
        prefix = hashKeys(prefix, digit);
    }
    return std::min(result, kOneMinusEpsilon);
}

// A pseudo-random permutation of [0, length), Kensler, "Correlated Multi-Jittered Sampling"
// (Pixar Technical Memo 13-01, 2013), listing 3: a hash bijection on the next power of two,
// cycle-walked into range.
uint32_t permute(uint32_t i, uint32_t length, uint32_t key) {
    uint32_t w = length - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    do {
        i ^= key;
        i *= 0xe170893du;
        i ^= key >> 16;
        i ^= (i & w) >> 4;
        i ^= key >> 8;
        i *= 0x0929eb3fu;
        i ^= key >> 23;
        i ^= (i & w) >> 1;
        i *= 1u | key >> 27;
        i *= 0x6935fa69u;
        i ^= (i & w) >> 11;
        i *= 0x74dcb303u;
        i ^= (i & w) >> 2;
        i *= 0x9e501cc3u;
        i ^= (i & w) >> 2;
        i *= 0xc860a3dfu;
        i &= w;
        i ^= i >> 5;
    } while (i >= length);
    return (i + key) % length;
}

// Uniform point on a disc of `radius` about `centre`, perpendicular to unit `axis`.
glm::vec3 discPoint(glm::vec3 centre, glm::vec3 axis, float radius, double u1, double u2) {
    glm::vec3 tangent, bitangent;
    orthonormalBasis(axis, tangent, bitangent);
    const float r = radius * float(std::sqrt(u1));
    const float phi = kTwoPi * float(u2);
    return centre + r * std::cos(phi) * tangent + r * std::sin(phi) * bitangent;
}

// Direction at angle acos(cos_theta) from unit `axis`, azimuth 2 pi u.
glm::vec3 coneDirection(glm::vec3 axis, float cos_theta, double u) {
    glm::vec3 tangent, bitangent;
    orthonormalBasis(axis, tangent, bitangent);
    const float sin_theta = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
    const float phi = kTwoPi * float(u);
    return glm::normalize(sin_theta * std::cos(phi) * tangent +
                          sin_theta * std::sin(phi) * bitangent + cos_theta * axis);
}

// The glTF spot falloff t(cos)^2, t = clamp((cos - cos_outer) s, 0, 1), split into the full
// cone [c1, 1] and the ramp [cos_outer, c1] (see the header), with the solid-angle integral of
// each part.
struct SpotProfile {
    float cosOuter;
    float c1;
    double fullMass; // 2 pi (1 - c1)
    double rampMass; // 2 pi (c1 - cos_outer)^3 s^2 / 3

    explicit SpotProfile(const PunctualLight& light) {
        // The same slope as normalIrradianceAt (formats/light.hpp).
        const double s = 1.0 / std::max(0.001, double(light.innerConeCos - light.outerConeCos));
        cosOuter = light.outerConeCos;
        const double c1_exact = std::min(1.0, double(light.outerConeCos) + 1.0 / s);
        c1 = float(c1_exact);
        const double ramp = c1_exact - double(light.outerConeCos);
        fullMass = 2.0 * std::numbers::pi * (1.0 - c1_exact);
        rampMass = 2.0 * std::numbers::pi * ramp * ramp * ramp * s * s / 3.0;
    }
    double solidAngle() const { return fullMass + rampMass; }
    // cos(theta) distributed proportionally to the falloff: uniform on the full cone, density
    // (cos - cos_outer)^2 on the ramp (inverted CDF: a cube root).
    float sampleCos(double u) const {
        const double x = u * solidAngle();
        if (x < fullMass) {
            return c1 + (1.0f - c1) * float(x / fullMass);
        }
        const double v = std::min(1.0, (x - fullMass) / rampMass);
        return cosOuter + (c1 - cosOuter) * float(std::cbrt(v));
    }
};

// One light path's start: where it leaves, where to, with what flux (W, before division by the
// number of paths).
struct PathStart {
    glm::vec3 origin;
    glm::vec3 direction; // unit
    glm::vec3 flux;
    float range; // metres, first segment's range window (0 = none)
};

// The scene's lights as sources of light paths, chosen proportionally to power.
class LightPathTracer {
public:
    LightPathTracer(const Scene& scene, const RayTracer& tracer, uint32_t bounces)
        : m_scene(scene), m_tracer(tracer), m_sampler(scene), m_bounces(bounces) {
        const glm::vec3 extent = scene.bounds.size();
        m_centre = scene.bounds.center();
        // A little beyond the bounding sphere, so that discs cover every surface.
        m_radius = 0.5f * glm::length(extent) * 1.001f + 1e-4f;
        const double disc_area = double(kPi) * double(m_radius) * double(m_radius);

        for (uint32_t i = 0; i < uint32_t(scene.lights.size()); ++i) {
            const PunctualLight& light = scene.lights[i];
            const double solid_angle = light.type == LightType::Directional
                                           ? disc_area // W/m^2 x m^2
                                           : punctualSolidAngle(light);
            addSource(Source::Kind::Punctual, i, luminance(light.intensity) * solid_angle);
        }
        if (m_sampler.hasEmitters()) {
            double power = 0.0;
            for (uint32_t tri = 0; tri < uint32_t(scene.triangles.size()); ++tri) {
                const Material& material = scene.materials[scene.triangleMaterial[tri]];
                if (material.isEmissive()) {
                    const glm::uvec3 t = scene.triangles[tri];
                    const glm::vec3 p0 = scene.positions[t.x];
                    const double area =
                        0.5 * double(glm::length(glm::cross(scene.positions[t.y] - p0,
                                                            scene.positions[t.z] - p0)));
                    // Two-sided Lambertian emission: pi L per side.
                    power += area * 2.0 * std::numbers::pi * luminance(material.emission);
                }
            }
            addSource(Source::Kind::Emitters, 0, power);
        }
        if (!scene.environment.isBlack()) {
            addSource(Source::Kind::Environment, 0, environmentPower() * disc_area);
        }
        double total = 0.0;
        for (const Source& s : m_sources) {
            total += s.power;
        }
        m_totalPower = total;
        double running = 0.0;
        for (Source& s : m_sources) {
            s.cdfLow = running / total;
            running += s.power;
            s.cdfHigh = running / total;
        }
        if (!m_sources.empty()) {
            m_sources.back().cdfHigh = 1.0;
        }
    }

    bool canEmit() const { return m_totalPower > 0.0 && std::isfinite(m_totalPower); }

    // Traces light path `index` from uniforms `u`, appending its VPLs (flux x flux_scale) to
    // `out` when given. Returns the number of VPLs the path left.
    uint32_t trace(const std::array<double, kVplPathDimensions>& u, Rng& rng, float flux_scale,
                   std::vector<Vpl>* out, uint64_t& rays) const {
        std::optional<PathStart> start = emit(u);
        if (!start) {
            return 0;
        }
        glm::vec3 flux = start->flux * flux_scale;
        glm::vec3 origin = start->origin;
        glm::vec3 direction = start->direction;
        uint32_t left = 0;
        for (uint32_t bounce = 1;; ++bounce) {
            const std::optional<Hit> hit = m_tracer.intersect(origin, direction);
            ++rays;
            if (!hit) {
                break;
            }
            if (bounce == 1 && start->range > 0.0f) {
                // KHR_lights_punctual's window, as normalIrradianceAt applies it.
                flux *= rangeWindow(start->range, hit->t * hit->t);
            }
            const glm::vec3 albedo = m_scene.albedoAt(hit->triangle, hit->bary);
            if (isBlack(albedo) || isBlack(flux)) {
                break;
            }
            const glm::vec3 position = m_tracer.surfacePoint(hit->triangle, hit->bary);
            // The side the light arrived from: the one the ray came from.
            const glm::vec3 normal = hit->backFace ? -hit->geometricNormal : hit->geometricNormal;
            if (out) {
                out->push_back(
                    Vpl{position, normal, albedo * flux * kInvPi,
                        RayTracer::offsetOrigin(position, hit->geometricNormal, normal)});
            }
            ++left;
            if (bounce >= m_bounces) {
                break;
            }
            const float survival = std::min(1.0f, maxComponent(albedo));
            if (rng.uniform() >= survival) {
                break;
            }
            // Cosine sampling makes the Lambertian weight f cos / pdf = albedo.
            flux *= albedo / survival;
            direction = cosineDirection(normal, rng.uniform2());
            origin = RayTracer::offsetOrigin(position, hit->geometricNormal, direction);
        }
        return left;
    }

private:
    struct Source {
        enum class Kind : uint8_t { Punctual, Emitters, Environment };
        Kind kind;
        uint32_t light; // index into Scene::lights (punctual)
        double power;   // luminance of the RGB power, W
        double cdfLow = 0.0;
        double cdfHigh = 0.0;
    };

    void addSource(Source::Kind kind, uint32_t light, double power) {
        if (power > 0.0 && std::isfinite(power)) {
            m_sources.push_back(Source{kind, light, power});
        }
    }

    // Integral of the environment's radiance luminance over the sphere (a selection weight
    // only: an approximation would still be unbiased).
    double environmentPower() const {
        const Environment& env = m_scene.environment;
        if (env.type == Environment::Type::Constant) {
            return 4.0 * std::numbers::pi * luminance(env.constant) * double(env.intensity);
        }
        const Image& image = env.image;
        double sum = 0.0;
        for (uint32_t y = 0; y < image.height; ++y) {
            const double solid_angle = 2.0 * std::numbers::pi / double(image.width) *
                                       (std::cos(std::numbers::pi * y / image.height) -
                                        std::cos(std::numbers::pi * (y + 1) / image.height));
            for (uint32_t x = 0; x < image.width; ++x) {
                const glm::vec4 t = image.texels[size_t(y) * image.width + x];
                sum += std::max(0.0, luminance(glm::vec3(t))) * solid_angle;
            }
        }
        return sum * double(env.intensity);
    }

    std::optional<PathStart> emit(const std::array<double, kVplPathDimensions>& u) const {
        // The light, then the remainder of u[0] inside its CDF interval as a fresh uniform (it
        // keeps the stratification of u[0] for the emitter choice).
        const auto it =
            std::upper_bound(m_sources.begin(), m_sources.end(), u[0],
                             [](double value, const Source& s) { return value < s.cdfHigh; });
        const Source& source = it == m_sources.end() ? m_sources.back() : *it;
        const double pick_probability = source.cdfHigh - source.cdfLow;
        const double u_rest =
            std::clamp((u[0] - source.cdfLow) / pick_probability, 0.0, kOneMinusEpsilon);
        const float inverse_pick = float(1.0 / pick_probability);

        switch (source.kind) {
        case Source::Kind::Punctual: {
            const PunctualLight& light = m_scene.lights[source.light];
            switch (light.type) {
            case LightType::Point:
                return PathStart{light.position,
                                 sphereDirection(glm::vec2(float(u[3]), float(u[4]))),
                                 light.intensity * (4.0f * kPi * inverse_pick), light.range};
            case LightType::Spot: {
                const SpotProfile profile(light);
                const glm::vec3 axis = glm::normalize(light.direction);
                return PathStart{light.position, coneDirection(axis, profile.sampleCos(u[3]), u[4]),
                                 light.intensity * float(profile.solidAngle()) * inverse_pick,
                                 light.range};
            }
            case LightType::Directional: {
                const glm::vec3 direction = glm::normalize(light.direction);
                const glm::vec3 centre = m_centre - 2.0f * m_radius * direction;
                return PathStart{discPoint(centre, direction, m_radius, u[1], u[2]), direction,
                                 light.intensity * (kPi * m_radius * m_radius * inverse_pick),
                                 0.0f};
            }
            }
            return std::nullopt;
        }
        case Source::Kind::Emitters: {
            const LightSampler::EmitterSample s =
                m_sampler.sampleEmitter(u_rest, glm::vec2(float(u[1]), float(u[2])));
            const glm::vec3 emitted = m_scene.emissionAt(s.triangle, s.bary);
            // Two-sided: either side with probability 1/2, then cosine about it.
            const bool front = u[3] < 0.5;
            const double u_side = front ? 2.0 * u[3] : 2.0 * u[3] - 1.0;
            const glm::vec3 side = front ? s.normal : -s.normal;
            const glm::vec3 direction = cosineDirection(
                side, glm::vec2(float(std::min(u_side, kOneMinusEpsilon)), float(u[4])));
            // L cos / (pdf_area x 1/2 x cos / pi).
            return PathStart{RayTracer::offsetOrigin(s.position, s.normal, direction), direction,
                             emitted * (2.0f * kPi / s.pdfArea * inverse_pick), 0.0f};
        }
        case Source::Kind::Environment: {
            glm::vec3 towards_sky;
            float pdf;
            if (m_sampler.hasEnvironmentSampling()) {
                const LightSampler::DirectionSample s =
                    m_sampler.sampleEnvironment(u[3], u[4], glm::vec2(float(u[5]), float(u[6])));
                towards_sky = s.direction;
                pdf = s.pdf;
            } else {
                towards_sky = sphereDirection(glm::vec2(float(u[3]), float(u[4])));
                pdf = 1.0f / kFourPi;
            }
            if (!(pdf > 0.0f)) {
                return std::nullopt;
            }
            const glm::vec3 centre = m_centre + 2.0f * m_radius * towards_sky;
            return PathStart{discPoint(centre, towards_sky, m_radius, u[1], u[2]), -towards_sky,
                             m_scene.environment.radiance(towards_sky) *
                                 (kPi * m_radius * m_radius / pdf * inverse_pick),
                             0.0f};
        }
        }
        return std::nullopt;
    }

    const Scene& m_scene;
    const RayTracer& m_tracer;
    LightSampler m_sampler;
    uint32_t m_bounces;
    glm::vec3 m_centre{0.0f};
    float m_radius = 0.0f;
    std::vector<Source> m_sources;
    double m_totalPower = 0.0;
};

} // namespace

double punctualSolidAngle(const PunctualLight& light) {
    switch (light.type) {
    case LightType::Point:
        return 4.0 * std::numbers::pi;
    case LightType::Spot:
        return SpotProfile(light).solidAngle();
    case LightType::Directional:
        break;
    }
    return 0.0;
}

VplPathSampler::VplPathSampler(VplSampling mode, uint64_t seed, uint32_t path_count)
    : m_mode(mode), m_seed(seed), m_pathCount(path_count) {
    assert(path_count >= 1);
}

std::array<double, kVplPathDimensions> VplPathSampler::operator()(uint32_t index) const {
    std::array<double, kVplPathDimensions> u{};
    switch (m_mode) {
    case VplSampling::Random: {
        Rng rng(hashKeys(m_seed, kStartStream, index));
        for (double& x : u) {
            x = rng.uniformDouble();
        }
        break;
    }
    case VplSampling::Stratified:
        for (int d = 0; d < kVplPathDimensions; ++d) {
            u[d] = scrambledRadicalInverse(index, kHaltonBases[d],
                                           hashKeys(m_seed, kHaltonStream, uint64_t(d)));
        }
        break;
    case VplSampling::Jittered: {
        Rng rng(hashKeys(m_seed, kJitterStream, index));
        for (int d = 0; d < kVplPathDimensions; ++d) {
            const auto key = uint32_t(hashKeys(m_seed, kPermutationStream, uint64_t(d)));
            const uint32_t stratum = permute(index, m_pathCount, key);
            u[d] = std::min((double(stratum) + rng.uniformDouble()) / double(m_pathCount),
                            kOneMinusEpsilon);
        }
        break;
    }
    }
    return u;
}

VplSet traceVpls(const Scene& scene, const RayTracer& tracer, uint32_t count,
                 const VplConfig& config, uint64_t seed) {
    assert(count >= 1 && config.bounces >= 1);
    VplSet set;
    const LightPathTracer paths(scene, tracer, config.bounces);
    if (!scene.hasGeometry() || !paths.canEmit()) {
        return set;
    }

    // Pilot: how many VPLs a path leaves on average, from independent random paths.
    uint64_t pilot_vpls = 0;
    const uint64_t pilot_seed = hashKeys(seed, kPilotStream);
    const VplPathSampler pilot_sampler(VplSampling::Random, pilot_seed, kVplPilotPaths);
    for (uint32_t i = 0; i < kVplPilotPaths; ++i) {
        Rng rng(hashKeys(pilot_seed, kContinueStream, i));
        pilot_vpls += paths.trace(pilot_sampler(i), rng, 1.0f, nullptr, set.rays);
    }
    const uint64_t most_paths = uint64_t(kVplMaxPathsPerVpl) * count;
    const uint64_t path_count =
        pilot_vpls == 0 ? most_paths
                        : std::min(most_paths, (uint64_t(count) * kVplPilotPaths + pilot_vpls - 1) /
                                                   pilot_vpls);
    const auto n = uint32_t(std::min<uint64_t>(path_count, UINT32_MAX));

    const VplPathSampler sampler(config.sampling, seed, n);
    set.vpls.reserve(size_t(count) + count / 8);
    const float flux_scale = 1.0f / float(n);
    for (uint32_t i = 0; i < n; ++i) {
        Rng rng(hashKeys(seed, kContinueStream, i));
        paths.trace(sampler(i), rng, flux_scale, &set.vpls, set.rays);
    }
    set.lightPaths = n;
    return set;
}

} // namespace probekit::baker
