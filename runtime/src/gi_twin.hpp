// probekit::runtime — the dynamic GI's CPU twin: the specification and test oracle of every
// compute shader DynamicGi records (shaders/gi_*.comp), stage by stage, on the same buffers in
// the same layouts. docs/runtime.md#dynamic-gi says how the stages fit together; the transport is
// the offline LPV's (baker/src/methods/lpv.hpp: injection as a cosine lobe half a cell along the
// normal, the five-face transfer with geometry blocking, the flux-conserving negative clamp,
// radiance from accumulated face crossings), rebuilt here on plain arrays because the runtime may
// not depend on the baker.
//
// Per cascade (a cube of n^3 LPV cells of side s; its geometry volume (n + 1)^3, gi_geometry.hpp):
//
//  1. Geometry (gi_geometry.comp): buildGiGeometry.
//  2. Surfaces (gi_surface.comp, one thread per geometry cell): the cell's surface is one
//     two-sided element (giSurfaceOf: area per side, mean albedo, area-weighted canonical
//     normal, area-weighted position). For each side m = +-n it computes the flux the side
//     reflects, Phi = albedo x area x E(m), and the LPV cell it is injected into (the cell holding
//     the position moved half a cell along m; -1 when that is outside the cascade).
//       First bounce:  E(m) = sum over lights of E_facing max(0, m.l) x transmittance, the
//                      transmittance marched through the geometry volume (giTransmittance).
//       Later bounces: E(m) = the previous bounce's radiance field as irradiance at the
//                      injection point facing m (L1, clamped at 0).
//  3. Inject (gi_inject.comp, one thread per LPV cell): gathers the sides whose target is this
//     cell from the 27 geometry cells c + {-1, 0, 1}^3 (z, y, x ascending, side + before -) as
//     the cosine lobe Phi (Y00, 2/3 Y1m(m)); the first bounce adds the sky entering through the
//     border (giBorderSky, per border side of the cell, d ascending).
//  4. Propagate (gi_propagate.comp, one thread per LPV cell, `iterations` times, ping-pong):
//     giPropagateStep. The flux-conserving clamp needs the field's total flux, so each step
//     also writes per-workgroup partial sums and gi_reduce.comp turns them into the per-channel
//     scale the next step applies when it reads. Each transfer's keep factor depends on the
//     geometry alone, so gi_keep.comp computes it once per geometry volume (the twin's
//     giUpdateCascade likewise; giPropagateStep computes it itself).
//  5. Resolve (gi_resolve.comp, one thread per LPV cell): face crossings -> L1 radiance SH,
//     added to the cascade's radiance (bounces accumulate).
//
// Shading (gi_shade.comp, after shade.comp): giSampleRadiance per pixel (pk_gi_irradiance), and
// the functions below.
//
// Units: flux W, intensity W/sr, radiance W/(sr m^2), as offline. Light "comes from" -w for an
// intensity travelling along w; radiance SH is indexed by the direction light comes from.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "gi_geometry.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/sh.hpp"

namespace probekit::runtime {

// LPV cells of a cascade, x fastest.
inline size_t giCellCount(const GiCascadeLayout& layout) {
    return size_t(layout.cells) * size_t(layout.cells) * size_t(layout.cells);
}
inline size_t giCellIndex(const GiCascadeLayout& layout, glm::ivec3 c) {
    const auto n = size_t(layout.cells);
    return size_t(c.x) + n * (size_t(c.y) + n * size_t(c.z));
}

// An L1 SH field over a cascade's cells: 12 planes of cellCount floats, plane 3 k + ch holding
// coefficient k (Y00, Y1-1, Y10, Y11) of channel ch. The GPU buffers use this layout.
struct GiField {
    size_t cells = 0;
    std::vector<float> data;

    explicit GiField(size_t cell_count = 0) : cells(cell_count), data(12 * cell_count, 0.0f) {}
    float& at(size_t cell, int coefficient, int channel) {
        return data[(3 * size_t(coefficient) + size_t(channel)) * cells + cell];
    }
    float at(size_t cell, int coefficient, int channel) const {
        return data[(3 * size_t(coefficient) + size_t(channel)) * cells + cell];
    }
};

// The surface of one geometry cell as a single two-sided element (empty when area is 0).
struct GiSurface {
    float area = 0.0f;        // m^2
    glm::vec3 albedo{0.0f};   // area-weighted mean
    glm::vec3 normal{0.0f};   // unit, the canonical side (largest component positive)
    glm::vec3 position{0.0f}; // world, area-weighted
};
GiSurface giSurfaceOf(const GiCascadeLayout& layout, const GiGeometryCell& cell, glm::ivec3 g);

// Fraction of light from `from` towards `direction` (unit) that reaches `distance` metres
// (infinite for a directional light) through the geometry volume: marched in steps of one cell
// (points from + direction s k, k = 1, 2, ...) while inside the geometry volume and k s <
// distance; each step's nearest geometry cell (skipping `skip`, the surface's own cell, and a
// cell equal to the previous step's) multiplies by 1 - clamp(B(direction), 0, 1), B the
// blocking's bands 0 and 2 evaluated at the direction.
float giTransmittance(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                      glm::vec3 from, glm::vec3 direction, float distance, glm::ivec3 skip);

// What a geometry cell's two sides inject (side 0: +normal, side 1: -normal).
struct GiSurfaceLight {
    std::array<int32_t, 2> target{-1, -1}; // LPV cell index, -1: none
    std::array<glm::vec3, 2> flux{};       // W per channel, reflected into the side's hemisphere
    glm::vec3 normal{0.0f};                // the surface's canonical normal
};

// Stage 2, first bounce: the lights' flux reflected by every geometry cell's surface.
std::vector<GiSurfaceLight> giSurfaceLightsDirect(const GiCascadeLayout& layout,
                                                  std::span<const GiGeometryCell> geometry,
                                                  std::span<const PunctualLight> lights);
// Stage 2, a later bounce: the flux reflected of the radiance field `previous` (one bounce's
// resolved radiance, giResolve) arriving at each side.
std::vector<GiSurfaceLight> giSurfaceLightsBounce(const GiCascadeLayout& layout,
                                                  std::span<const GiGeometryCell> geometry,
                                                  const GiField& previous);

// Sky entering the cascade through its border: per direction of travel d (+x, -x, +y, -y, +z,
// -z) the intensity SH per square metre of the border side whose inward normal is d
// [W/(sr m^2)], from the sky's radiance SH (L1 or L2; the direction light comes from), negative
// sky radiance clamped at 0. The offline LPV's borderLight for its environment, with the sky
// given as SH.
std::array<std::array<glm::vec3, 4>, 6> giBorderSky(const sh::ShRgb& sky);

// Stage 3: the injected intensity field (x s^2 for the border sky, which is per square metre).
GiField giInject(const GiCascadeLayout& layout, std::span<const GiSurfaceLight> surfaces,
                 const std::array<std::array<glm::vec3, 4>, 6>* border_sky);

// Stage 4. One step of the offline LPV's transport as a gather: every cell receives, from each
// neighbour d it lies along (source = cell - direction d), through the five faces f of the
// transfer, keep_f W_f Y(w_f) (Y(w_f) . I_source x scale), keep_f = weight x (1 - clamp(potential
// at w_f of the four geometry cells around the shared face)); `crossing` (18 planes: 3 d + ch)
// gains the flux each transfer carries. Channels whose band 0 ends negative are zeroed; the
// returned scale (per channel: (kept + dropped) / kept, 1 when nothing was dropped) is what the
// next step multiplies its source by, so that every step conserves flux as offline.
glm::vec3 giPropagateStep(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                          float weight, const GiField& current, glm::vec3 current_scale,
                          GiField& next, std::vector<float>& crossing);

// Stage 5: accumulated face crossings -> L1 radiance SH (offline propagateToRadiance), added to
// `radiance`.
void giResolve(const GiCascadeLayout& layout, const std::vector<float>& crossing,
               GiField& radiance);

// The whole update of one cascade: geometry given, `bounces` (>= 1) passes of surfaces, inject,
// `iterations` propagation steps and resolve, each later pass lit by the previous pass's
// radiance. Returns the cascade's radiance.
struct GiCascadeInputs {
    std::span<const PunctualLight> lights; // the dynamic lights
    const sh::ShRgb* sky = nullptr;        // the sky's radiance SH, or none
    uint32_t iterations = 16;
    uint32_t bounces = 1;
    float propagationWeight = 1.0f;
};
GiField giUpdateCascade(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                        const GiCascadeInputs& inputs);

// Radiance SH at world point p from the cascades (finest first, each with its radiance field):
// each sampled trilinearly between cell centres (clamped at its border); from the coarsest
// down, cascade j replaces the coarser result by the weight clamp(inside distance / (fade_cells
// s_j), 0, 1); the coarsest fades to 0 outside itself the same way. Band 2 is zero, or with
// `zonal` the hallucinated zonal band giZonal adds.
sh::ShRgb giSampleRadiance(std::span<const GiCascadeLayout> layouts,
                           std::span<const GiField> radiance, float fade_cells, bool zonal,
                           glm::vec3 p);

// The shading pass's other uses of the finest cascade's geometry volume (gi_shade.comp):
//  * giSunVisibility: the directional light's shadow at a surface point p with normal n,
//    giTransmittance from p + n s / 2 towards the light, skipping nothing;
//  * giGeometryColour (view gi-geometry): the geometry cell nearest p (clamped into the volume):
//    its mean albedo x min(1, area / s^2), black where it holds no surface;
//  * giOcclusion (view gi-ao): 1 - the mean over the six axis directions of the clamped blocking
//    of the geometry cell nearest p + n s / 2.
float giSunVisibility(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                      glm::vec3 p, glm::vec3 n, glm::vec3 to_light);
glm::vec3 giGeometryColour(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                           glm::vec3 p);
float giOcclusion(const GiCascadeLayout& layout, std::span<const GiGeometryCell> geometry,
                  glm::vec3 p, glm::vec3 n);

// The zonal band 2 hallucinated from L1 (quality level L1Zonal): along the unit direction d of
// the L1 vector, z = sqrt(5) L00 r^2 with r = |L1| / (sqrt(3) L00) clamped to [0, 1] (per
// channel), added as z Y2m(d) x sqrt(4 pi / 5) ... i.e. the zonal harmonic z P2(d . w): exact
// for a single beam (r = 1) and for uniform light (r = 0).
void giZonal(sh::ShRgb& radiance);

} // namespace probekit::runtime
