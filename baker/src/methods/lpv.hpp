// probekit::baker — light propagation volumes (LPV) for the "lpv" method: Kaplanyan and
// Dachsbacher, "Cascaded Light Propagation Volumes for Real-Time Indirect Illumination"
// (I3D 2010). Private to baker/ (and its tests).
//
// A cascade is a box of cubic cells of side s [m]. Each cell holds an L1 SH *intensity* I(w)
// [W/sr]: the light travelling through the cell in direction w, as if it left the cell centre.
//
// Injection. A lit Lambertian surface element that reflects (or emits) flux Phi [W] into the
// hemisphere of its normal n radiates I(w) = Phi / pi max(0, n.w), whose SH is
// Phi / pi A_l Y_lm(n) = Phi (Y00, 2/3 Y1m(n)) (A_l as in formats/CONVENTIONS.md). It goes into
// the cell holding the element moved half a cell along n (the paper's offset: a surface does not
// light its own cell). Light that meets another surface within a cell (a lamp 1 cm under a
// ceiling, a corner) is beyond the geometry volume, which blocks only between cells, and its
// reflection is a light of the next bounce already: so each element casts kEscapeRays jittered
// cosine-distributed rays and injects only those that travel one cell unblocked, each as a
// beam of Phi / kEscapeRays along its direction (SH Phi / K Y(w)); unblocked, that is the
// cosine lobe above on average. (Without this the Cornell box's rel RMSE is 84%: the lamp's
// upward light, trapped 1 cm under the ceiling, would be injected below the lamp; any reach
// from half a cell to 1.5 cells gives 7.4..7.9%.)
//
// Propagation, one iteration = light moves one cell. A cell sends its light to each of its 6
// neighbours through the 5 faces of the neighbour that do not touch it (the paper's scheme):
// face f subtends the solid angle W_f from the source centre (the far face 4 asin(1/10) =
// 0.4007 sr, each side face (4 pi / 6 - 0.4007) / 4 = 0.4234 sr, so the five tile the shared
// face exactly) and receives the flux W_f I(w_f), w_f towards its centre, unclamped as in the
// paper. The neighbour re-emits that flux as a beam along w_f, SH flux Y(w_f); the paper uses a
// cosine lobe about the face normal, which turns light sideways at every step (measured 1.5 m
// over a uniformly lit plane: irradiance facing away from the plane is 51% of that facing it
// with the cosine lobe, ~0 with the beam, as it should be; Cornell box rel RMSE at 32
// iterations 18% against 7.6%). So one step applies, per neighbour d, the symmetric 4x4 matrix
// T_d = sum_f keep_f W_f Y(w_f) Y(w_f)^T to each channel.
// The 30 directions integrate L1 functions exactly (sum W_f = 4 pi, sum W_f w_f = 0), so without
// occlusion a step moves exactly the flux sqrt(4 pi) I_00 a cell holds. The transfer is linear,
// negative lobes (L1 ringing) included; but where the ringing of several neighbours sums to a
// negative net flux in a cell channel, that channel holds no light and would pass the negative
// on as "anti-light". It is set to zero, and the negative flux so removed is taken back from all
// the positive light of the step in proportion (per channel), so every step conserves flux
// exactly. (Zeroing alone would add 14% of the flux at the first step after injection and ~3%
// per step later on. Cornell box rel RMSE at 32 iterations: 7.6% so, 6.2% zeroing alone,
// 12.5% plain linear transport.)
//
// Geometry volume (occlusion). A grid offset by half a cell: its cells are centred on the LPV
// cell corners, so every face between two LPV cells lies on a plane of geometry-cell centres.
// A two-sided surface element of area A with normal n blocks a path crossing a cell along w
// with probability ~ A |n.w| / s^2; that is even in w, so its L1 projection keeps only the
// direction average and cannot tell a wall across the light from one along it. Each geometry
// cell therefore stores bands 0 and 2 of A (n.w)^2 / s^2 — SH (4 pi / 3, 0, 8 pi / 15) Y_lm(n)
// A / s^2 — exact for light along and across the element, 1/2 instead of 0.71 at 45 degrees.
// A transfer through face f keeps (1 - clamp(B(w_f), 0, 1)) of its flux (times
// propagationWeight), B averaged over the four geometry cells around the shared face's centre.
// Blocked light is absorbed: what the surface reflects is injected as the next bounce's light.
//
// Radiance. The energy crossing a plane does not depend on how fast light moves, and a path
// that moves cell by cell towards its target crosses as many cell faces of each axis as the
// straight ray does; the time a cell holds light does (the paper's radiance I_acc / s^2 counts
// a diagonal path up to 1.7 times). So the flux crossing each face is summed over all
// iterations; the one-sided irradiance at a cell centre from the side +a is the mean of the two
// crossings along -a around it divided by s^2 (one crossing at the grid border), and the six
// one-sided irradiances give the L1 radiance SH exactly: L00 = sum E / (6 pi Y00),
// L1 along a = (E(+a) - E(-a)) / (2 (2 pi / 3) Y1). Irradiance E in W/m^2, radiance in
// W/(sr m^2), indexed by the direction light comes from, as probes store it.
//
// Cascades (paper, section 6). 1 to 4 nested grids with the same number of cells, each
// `cascadeRatio` times finer than the next coarser one. The coarsest covers the output volume
// and the scene; the finer ones are centred on the output volume (kept inside the coarsest where
// they fit) and snapped to their own cell lattice anchored at the coarsest cascade's corner, so
// cell faces of all cascades line up for integer ratios. Cascade k propagates (a) all lights
// inside it, used where it is the finest cascade, and (b) for k > 0, the lights inside it but
// outside cascade k - 1, used in the finer regions. So at any point each light is counted once,
// propagated by the finest cascade that holds both the light and the point. A band of `fadeCells`
// cells along the border of each finer cascade blends it linearly into the next coarser result.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/sh.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {

// A lit surface element whose reflected or emitted light the LPV carries.
struct LpvSurfaceLight {
    glm::vec3 position; // world, metres, on the surface
    glm::vec3 normal;   // unit geometric normal, on the side the light leaves
    glm::vec3 flux;     // W per channel into that hemisphere, cosine distributed
};

// L1 SH per channel: c[k] holds coefficient k (Y00, Y1-1, Y10, Y11) of red, green and blue.
struct Sh1Rgb {
    std::array<glm::vec3, 4> c{};

    Sh1Rgb& operator+=(const Sh1Rgb& other);
    Sh1Rgb& operator*=(float scale);
    friend bool operator==(const Sh1Rgb&, const Sh1Rgb&) = default;
};

// Light added to one cell as it is (punctual lights, and sky or sun entering through the grid's
// border, when direct light is propagated).
struct LpvPointLight {
    glm::vec3 position; // world, metres
    Sh1Rgb intensity;   // W/sr by direction of travel
};

// Integral of an intensity over the sphere [W per channel]: sqrt(4 pi) x band 0.
glm::vec3 totalFlux(const Sh1Rgb& intensity);

// The L1 SH of a beam: `amount` x delta(w - direction) (unit direction), i.e. amount Y(direction).
Sh1Rgb beamSh(glm::vec3 direction, glm::vec3 amount);

struct LpvSettings {
    uint32_t grid = 32;             // cells along the longest axis of every cascade (4..256)
    uint32_t cascades = 1;          // nested grids (1..4)
    float cascadeRatio = 2.0f;      // cell size of cascade k + 1 / that of cascade k (> 1)
    uint32_t iterations = 32;       // propagation steps per cascade (>= 1)
    float propagationWeight = 1.0f; // fraction of the flux a step passes on (1 = lossless)
    float fadeCells = 2.0f;         // cells of a finer cascade over which it fades out (>= 0)
    bool occlusion = true;          // geometry volume on
};

// One cascade: cells (x fastest) of side cellSize from origin.
struct LpvCascadeLayout {
    glm::vec3 origin{0.0f}; // world min corner, metres
    float cellSize = 1.0f;  // metres
    glm::ivec3 cells{1};    // per axis

    glm::vec3 max() const { return origin + glm::vec3(cells) * cellSize; }
    size_t cellCount() const { return size_t(cells.x) * size_t(cells.y) * size_t(cells.z); }
    size_t index(glm::ivec3 cell) const {
        return size_t(cell.x) + size_t(cells.x) * (size_t(cell.y) + size_t(cells.y) * cell.z);
    }
    bool contains(glm::vec3 p) const;
    bool containsCell(glm::ivec3 cell) const;
    // The cell holding p, clamped into the grid.
    glm::ivec3 cellOf(glm::vec3 p) const;
    // Distance from p to the box's nearest face (negative outside), metres.
    float insideDistance(glm::vec3 p) const;
};

// The cascades for an output volume whose world bounds are `volume`, in a scene with bounds
// `scene` (an empty scene: pass the volume again), finest first. The coarsest covers both boxes
// and one cell more on every side (so the outermost surfaces have empty cells beyond them, and
// sky and sun enter through empty cells), with cubic cells: settings.grid of them along its
// longest axis and as many as needed (at least 3) along the others, centred on the union. The
// finer ones keep those cell counts (placement: file comment). Preconditions: the settings'
// documented ranges.
std::vector<LpvCascadeLayout> layoutLpvCascades(const grid::Aabb& volume, const grid::Aabb& scene,
                                                const LpvSettings& settings);

// An L1 SH field over a cascade's cells, stored as 12 planes (plane 3 k + ch: coefficient k of
// channel ch, cells x fastest) so that a propagation step runs along x in SIMD lanes.
class LpvField {
public:
    explicit LpvField(size_t cells = 0);
    size_t cellCount() const { return m_planes[0].size(); }
    float* plane(int coefficient, int channel) {
        return m_planes[3 * coefficient + channel].data();
    }
    const float* plane(int coefficient, int channel) const {
        return m_planes[3 * coefficient + channel].data();
    }
    Sh1Rgb at(size_t cell) const;
    void add(size_t cell, const Sh1Rgb& value);
    // Sum over cells of the flux sqrt(4 pi) x band 0 [W per channel], in double.
    glm::dvec3 totalFlux() const;

private:
    std::array<std::vector<float>, 12> m_planes;
};

// The transfers of one cascade (file comment): the six free matrices T_d (+x, -x, +y, -y, +z,
// -z; row-major), and a correction T_d - free T_d for every transfer across a face a surface
// touches. Free transfers are by far the most, so a step applies them everywhere and then the
// corrections.
struct LpvTransfer {
    using Matrix = std::array<float, 16>;
    struct Correction {
        uint32_t destination; // cell index receiving the transfer
        uint32_t source;      // cell index sending it (destination - direction)
        uint32_t direction;   // 0..5
        Matrix delta;         // T_d - free T_d
    };
    std::array<Matrix, 6> free{};
    std::vector<Correction> corrections; // destinations inside the grid, by (destination, d)
    std::vector<Correction> border;      // transfers out of the grid (destination unused)
};

// Triangle t's corners and bounding box.
struct TriangleCorners {
    glm::vec3 a, b, c;
    glm::vec3 lo, hi;
};
TriangleCorners triangleCorners(const Scene& scene, glm::uvec3 t);

// Transfers through the geometry volume of `layout` built from the scene's triangles
// (deterministic area samples, sub-triangles of at most half a cell), or, without occlusion, the
// free transfers alone. Both scale by settings.propagationWeight.
LpvTransfer buildLpvTransfer(const Scene& scene, const LpvCascadeLayout& layout,
                             const LpvSettings& settings);

// One propagation step: `next` (overwritten) receives what every cell of `current` sends its
// neighbours. Deterministic for any `threads` (>= 1). Flux bookkeeping [W per channel]:
// flux(current) = flux(next) + escaped + what the transfers held back (occlusion,
// propagationWeight < 1), to float rounding.
struct LpvStepFlux {
    glm::vec3 escaped{0.0f};       // sent out of the grid
    glm::vec3 redistributed{0.0f}; // negative net flux zeroed and taken from the rest (<= 0)
};
LpvStepFlux propagateStep(const LpvCascadeLayout& layout, const LpvTransfer& transfer,
                          const LpvField& current, LpvField& next, uint32_t threads);

// Injected intensities -> L1 radiance SH per cell (file comment) after `iterations` steps.
std::vector<Sh1Rgb> propagateToRadiance(const LpvCascadeLayout& layout, const LpvTransfer& transfer,
                                        LpvField injected, uint32_t iterations, uint32_t threads);

// Rays each surface light casts to find what blocks it within one cell.
constexpr uint32_t kEscapeRays = 4;

// Surface lights with their escape rays traced once for every cascade: per light kEscapeRays
// directions and the free distance along each (metres, capped at `max_distance`).
struct LpvInjection {
    std::vector<LpvSurfaceLight> lights;
    std::vector<std::array<glm::vec3, kEscapeRays>> directions;
    std::vector<std::array<float, kEscapeRays>> freeDistance;
    std::vector<LpvPointLight> pointLights;
    // Light entering through the coarsest cascade's border (sky and sun): per direction of
    // travel d (+x, -x, +y, -y, +z, -z), the intensity SH per square metre of the border whose
    // inward normal is d [W/(sr m^2)]; each border cell on that side receives it x s^2.
    std::array<Sh1Rgb, 6> borderPerArea{};
};
LpvInjection traceLpvInjection(const RayTracer& tracer, std::vector<LpvSurfaceLight> lights,
                               std::vector<LpvPointLight> point_lights, float max_distance,
                               uint64_t seed, uint32_t threads);

// Adds the injection's light that lies inside `region` (everything when null, and then the
// border light too) and outside `excluded` (when given) to `cells`.
void injectLights(const LpvCascadeLayout& layout, const LpvInjection& injection,
                  const LpvCascadeLayout* region, const LpvCascadeLayout* excluded,
                  LpvField& cells);

// The cascades of one output volume, propagated; then a read-only, thread-safe radiance field.
class LpvCascades {
public:
    // `layouts` from layoutLpvCascades. `threads` >= 1 parallelises propagation; the result does
    // not depend on it.
    LpvCascades(const Scene& scene, const LpvInjection& injection,
                std::vector<LpvCascadeLayout> layouts, const LpvSettings& settings,
                uint32_t threads);

    // Incident radiance at world point p [W/(sr m^2)] as SH (band 2 zero): each cascade
    // interpolated trilinearly between cell centres (clamped at its border), cascades combined
    // as in the file comment.
    sh::ShRgb radiance(glm::vec3 p) const;

    const std::vector<LpvCascadeLayout>& layouts() const { return m_layouts; }

private:
    Sh1Rgb sampleField(size_t cascade, const std::vector<Sh1Rgb>& field, glm::vec3 p) const;

    std::vector<LpvCascadeLayout> m_layouts;
    std::vector<std::vector<Sh1Rgb>> m_all;   // per cascade: radiance of the lights inside it
    std::vector<std::vector<Sh1Rgb>> m_outer; // per cascade k > 0: inside k, outside k - 1
    float m_fadeCells;
};

} // namespace probekit::baker
