// probekit::baker — method "lpv" inside a bake: what is computed once per bake (the lights the
// grids carry), once per volume (its propagated cascades) and per probe. The transport itself
// is lpv.hpp's.
//
// Lights. Always the VPLs of the vpl method (traceVpls: LpvConfig::vplCount of them, light
// paths of every bounce under Russian roulette): a VPL of radiant intensity J along its normal
// reflects the flux pi J into its hemisphere. With direct light propagated, the lights as well:
// emissive triangles as vplCount area samples per side (two-sided emitters: flux
// pi L_e / (pdf_area N) per sample and side), point and spot lights as their intensity
// distribution in the cell holding them, and sun and sky entering through the coarsest grid's
// border (a sun of irradiance E along l brings E (l.n) per m^2 of a border side with inward
// normal n; the sky integral of L (w.n) over the inward hemisphere). Range windows of point and
// spot lights are ignored there.
//
// Probes. With direct light traced (the default), a probe's SH is the path integrator's with
// no bounce (directSamples directions: emitters and sky seen from the probe with next-event
// estimation, punctual lights exactly) plus intensity x the LPV radiance; with it propagated,
// intensity x the LPV radiance alone, and the path integrator traces only kLpvValiditySamples
// directions for the probe's validity. The LPV part is L1: band 2 holds the direct light only.
#pragma once

#include <cstdint>
#include <vector>

#include "methods/lpv.hpp"
#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {

// Directions per probe that decide validity when the direct light is propagated.
constexpr uint32_t kLpvValiditySamples = 64;

// The transport settings of a config, iterations resolved (unset = grid).
LpvSettings resolveLpvSettings(const LpvConfig& config);

struct LpvLights {
    LpvInjection injection;
    uint64_t vpls = 0; // VPLs among the injection's surface lights
    uint64_t rays = 0; // light paths and escape rays
};

// The lights of every volume's cascades (file comment), with escape rays long enough for the
// coarsest cascade of any of `volumes`. Deterministic in (scene, config, seed).
LpvLights prepareLpvLights(const Scene& scene, const RayTracer& tracer, const LpvConfig& config,
                           const std::vector<VolumeDesc>& volumes, uint64_t seed, uint32_t threads);

// The propagated cascades of one output volume.
LpvCascades propagateLpv(const Scene& scene, const LpvLights& lights, const LpvConfig& config,
                         const VolumeDesc& volume, uint32_t threads);

// A probe's SH at world point p from the path integrator's `traced` SH (file comment).
sh::ShRgb lpvProbe(const LpvCascades& cascades, const LpvConfig& config, glm::vec3 p,
                   const sh::ShRgb& traced);

} // namespace probekit::baker
