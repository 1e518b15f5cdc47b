// probekit::baker — placing virtual point lights by tracing light paths (instant radiosity,
// Keller, "Instant Radiosity", SIGGRAPH 1997).
//
// A light path starts at a light chosen with probability proportional to its power
// (luminance of the RGB power):
//  * point light of intensity I (W/sr): power 4 pi I, direction uniform on the sphere;
//  * spot light: power I x the integral of the glTF cone falloff over the sphere,
//    2 pi [(1 - c1) + (c1 - cos_outer)^3 s^2 / 3] with s = 1 / max(0.001, cos_inner -
//    cos_outer) and c1 = min(1, cos_outer + 1 / s) (normalIrradianceAt's ramp, squared);
//    the direction is sampled exactly proportional to the falloff, so every path of a spot
//    carries the same flux;
//  * directional light of irradiance E (W/m^2): power E pi R^2 through a disc of radius R
//    (the bounding sphere of the scene) perpendicular to the light, the start uniform on it;
//  * emissive triangles, as one source: power sum of area x pi x radiance x 2 (two-sided);
//    a point by LightSampler::sampleEmitter (area x radiance), a side with probability 1/2,
//    a cosine-distributed direction about it;
//  * the environment: power pi R^2 x the integral of its radiance over the sphere, through the
//    same disc, which turns to face the sampled direction; lat-long maps are importance sampled
//    by LightSampler, constant ones uniformly over the sphere.
// The range window of point and spot lights (KHR_lights_punctual) scales the flux at the first
// hit, where the distance is known.
//
// At every diffuse hit the path leaves a VPL: the point, the normal of the side the light came
// from, and the radiant intensity it reflects along that normal, albedo x arriving flux / pi
// (Lambertian: intensity albedo x flux x cos / pi into that hemisphere only). Then the path
// continues in a cosine-distributed direction with throughput x albedo, under Russian roulette
// with survival probability min(1, max albedo channel) (the survivor divided by it, unbiased),
// for at most `bounces` hits. Every VPL's flux is divided by the number of light paths, so the
// VPL set's radiance estimate is unbiased whatever the sampling mode.
//
// The VPLs carry light reflected one or more times; what the lights deliver straight to a probe
// is the path integrator's (maxBounces 0) business.
//
// Deterministic: the set is a function of (scene, settings, seed) only, built on one thread.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {

struct Vpl {
    glm::vec3 position;     // on the surface, world, metres
    glm::vec3 normal;       // unit: the side the light arrived from (it reflects only into it)
    glm::vec3 intensity;    // radiant intensity along `normal`, W/sr: albedo x flux / pi
    glm::vec3 shadowTarget; // `position` moved off the surface to the lit side (offsetOrigin)
};

struct VplSet {
    std::vector<Vpl> vpls;
    uint64_t lightPaths = 0; // paths whose VPLs are in the set (the pilot's are not)
    uint64_t rays = 0;       // every ray traced, pilot included
};

// Traces the light paths and returns their VPLs. The number of paths is
// ceil(count x pilot paths / pilot VPLs) from a pilot of kVplPilotPaths random paths (at most
// kVplMaxPathsPerVpl x count), so the set holds `count` VPLs up to the pilot's noise. An
// empty set when the scene has no light or no geometry.
constexpr uint32_t kVplPilotPaths = 1024;
constexpr uint32_t kVplMaxPathsPerVpl = 64;
// `count` VPLs wanted (>= 1); `config` gives the hits per light path (bounces, >= 1) and the
// light-path sampling.
VplSet traceVpls(const Scene& scene, const RayTracer& tracer, uint32_t count,
                 const VplConfig& config, uint64_t seed);

// The solid angle a point or spot light shines into, weighted by its falloff, sr: 4 pi for a
// point light, the integral of the glTF cone falloff above for a spot; 0 for a directional
// light. Its power is its intensity (W/sr) times this.
double punctualSolidAngle(const PunctualLight& light);

// The uniforms that start light path `index` of `path_count` (light choice, point on the
// light, direction, environment pixel): kVplPathDimensions numbers in [0, 1).
//  * Random: independent (rng.hpp, keyed by seed and index).
//  * Stratified: the Halton sequence (bases 2, 3, 5, ...) with a nested random digit
//    scramble keyed by the seed (at each digit the b subintervals are cyclically shifted by an
//    amount hashed from the digits above it, an Owen-style scramble: each point is uniform,
//    the set keeps Halton's stratification). Deterministic and low-discrepancy.
//  * Jittered: dimension d of path i lies in stratum perm_d(i) of path_count equal strata,
//    uniformly inside it (perm_d a hashed permutation, Kensler 2013): every one-dimensional
//    projection is a jittered sample (a Latin hypercube).
// The continuation of each path after its first hit always uses independent random numbers.
constexpr int kVplPathDimensions = 7;
class VplPathSampler {
public:
    VplPathSampler(VplSampling mode, uint64_t seed, uint32_t path_count);
    std::array<double, kVplPathDimensions> operator()(uint32_t index) const;

private:
    VplSampling m_mode;
    uint64_t m_seed;
    uint32_t m_pathCount;
};

} // namespace probekit::baker
