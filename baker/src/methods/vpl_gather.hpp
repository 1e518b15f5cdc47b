// probekit::baker::VplGatherer — gathering a VPL set (vpl_paths.hpp) at probes, into radiance SH.
//
// One VPL of intensity I along its normal n at point x gives a probe at p (d = |x - p|,
// w = (x - p) / d, height h = n.(p - x) above the VPL's tangent plane) a directional delta of
// irradiance e = I (h / d) / d^2 from w, projected exactly: coefficients e Y_lm(w)
// (formats/CONVENTIONS.md). The VPL reflects only into the hemisphere it was lit from: h <= 0
// contributes nothing and is culled.
//
// Clamping (VplClamp) tames the 1 / d^2 spike of a VPL close to the probe; r = clampDistance:
//  * None: as above; unbiased over VPL sets, unbounded near surfaces.
//  * Distance: d^2 replaced by max(d^2, r^2). Bounded by I / r^2; a probe at height h < r
//    above a uniformly lit plane receives h (2r - h) / r^2 of its light.
//  * Spherical: virtual spherical lights (Hasan, Krivanek, Walter and Bala, "Virtual Spherical
//    Lights for Many-Light Rendering of Glossy Scenes", SIGGRAPH Asia 2009): the VPL's light
//    spread over a sphere of radius r, which a probe at distance d >= r sees as a cone of
//    half-angle asin(r / d). Its energy e is averaged over the cone's solid angle: by
//    Funk-Hecke, bands (0, 1, 2) of e Y_lm(w) scale by (1, (1 + c) / 2, c (1 + c) / 2),
//    c = cos(half-angle). A probe nearer than r to the VPL's surface (h < r) sees it as from
//    the sphere's rim, lifted to height r above the tangent plane: e = I (r / d') / d'^2 from
//    the lifted point, d' >= r. This is our addition to the VSL: clamping d instead would lose
//    h (2r - h) / r^2 of a plane's light near it, while the lift keeps a uniformly lit plane's
//    light and its angular distribution exact at every height (a uniform plane looks the same
//    from any height). Bounded by I / r^2; what remains is the smoothing of the lighting over
//    about r, and the VPL set's own noise, which near a surface comes from the ~(r / spacing)^2
//    VPLs within r.
//
// Near field (nearField > 0): no clamp resolves a surface only a few VPL spacings from the
// probe (5 cm from a corner, clamping alone leaves 20-50% error at 16384 VPLs: the near field
// holds a handful of VPLs). So VPLs nearer to the probe than nearField are skipped here and
// the probe path-traces the directions whose first hit is that near (vpl_integrator.hpp); with
// visibility the two partition the sphere exactly (a visible VPL at distance d is the first
// hit in its direction), in the spirit of Kollig and Keller's bias compensation ("Illumination
// in the Presence of Weak Singularities", 2004). The spherical clamp's lift is then off: it
// trades light a plane's near part loses for more from its far part.
//
// Lightcuts (Walter et al., "Lightcuts: A Scalable Approach to Illumination", SIGGRAPH 2005):
// the VPLs are the leaves of a binary tree (top-down median splits along the widest of the
// three position axes and the three normal axes scaled by a quarter of the set's diagonal,
// Lightcuts' 6D metric). A cluster C keeps its members' summed intensity, their bounding box,
// a cone bounding their normals, a representative member j chosen at build time with
// probability lum(I_j) / lum(I_C) (hashed from the seed and the node), its luminance-weighted
// centroid and, per channel, the sum of intensity x normal. Its estimate at a probe:
//  * if every member faces the probe (for the spherical clamp: from at least r) and the
//    cluster is small seen from it (bounding radius < kCentroidOpening x distance to the
//    centroid): its exact summed intensity towards the probe, -sum_j I_j n_j.w, placed at the
//    centroid;
//  * otherwise the representative's contribution x lum(I_C) / lum(I_j) (unbiased, per
//    channel, over the choice of representative).
// Visibility is the representative's.
//
// The error bound. The magnitude of a contribution is m = lum(e), the luminance of the
// probe's scalar irradiance (integral of radiance over the sphere). For a cluster,
// U_C = lum(I_C) x cosBound x F(dmin^2): cosBound bounds h_j / d_j over the members by the
// smaller of an angular bound (normal cone and the box's bounding sphere, Conty Estevez and
// Kulla 2018) and a plane bound (exact for flat clusters), raised to r / dmin for the
// spherical clamp's lifted members; F(d^2) = 1 / d^2 (None) or 1 / max(d^2, r^2), at the box's
// nearest point. Clusters wholly inside the near field are dropped; those reaching into it
// keep U_C (their skipped members contribute 0 <= U_C) and no centroid estimate. The true sum of
// the members' magnitudes and the estimate both lie in [0, U_C] (whatever the visibility), so the
// cluster's error in the luminance of E_L2(n) is at most 1.11 U_C for every normal n (per unit
// magnitude, the L2 irradiance of a delta or an averaged cone, 1/4 + b1 t/2 + (5/32) b2 (3t^2 - 1)
// with t = n.w and band factors b1, b2, lies in [-0.04, 1.0625]). The cut takes every cluster with
// U_C <= cutError x T, T the probe's total magnitude (the `direct` light given to gather() plus the
// cut's estimates, with visibility), opening larger ones (depth first, from the root): a first T
// from the bounds of the clusters kSeedDepth levels down, then clusters over the bound for the T
// now known are opened again, until none is (at most kRefinementRounds times per phase) or the cut
// holds kMaxCutSize clusters. So each cluster's error is at most 1.11 cutError T, the whole cut's
// at most 1.11 sum U_C (VplGatherResult::errorBound). Clusters with cosBound 0 face away from the
// probe and are dropped exactly.
//
// Visibility (shadows on): one ray from the probe to each cut member's representative
// (Vpl::shadowTarget), traced in batches through RayTracer's batched query. The cut is
// settled without visibility first (no rays for clusters about to be opened), then T is
// corrected by the traced visibility and the opening resumes against it, so that shadowed
// probes are held to the same relative bound as lit ones; a cluster keeping its parent's
// representative reuses the parent's ray. Two exceptions: T never counts as less than
// kUnoccludedFloor x the unoccluded T (so a probe inside geometry does not open every cluster
// for no light), and when no representative is visible at all (the probe is enclosed) the cut
// stays as it is.
//
// cutError = 0 gathers every VPL individually (no tree), the exact sum over the set.
//
// Immutable after construction, thread-safe, deterministic: a gather depends only on the set,
// the settings, the seed and the probe position.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "methods/vpl_paths.hpp"
#include "probekit/baker/config.hpp"
#include "probekit/formats/sh.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {

struct VplGatherResult {
    sh::ShRgb sh;            // radiance SH of the VPLs' light at the probe, `order` coefficients
    uint64_t rays = 0;       // visibility rays traced
    uint32_t cutSize = 0;    // clusters (or single VPLs) in the final cut
    float errorBound = 0.0f; // sum of the cut's cluster bounds U_C, luminance W/m^2
};

constexpr uint32_t kMaxCutSize = 4096;
constexpr int kSeedDepth = 5;        // levels below the root whose bounds give a first T
constexpr int kRefinementRounds = 8; // re-openings against the updated T, each phase

class VplGatherer {
public:
    // Takes the VPLs (those of zero intensity are dropped) and builds the light tree (unless
    // cutError is 0). `tracer` must outlive the gatherer.
    // `config` as resolveVplConfig leaves it (clamp, clampDistance, nearField, shadows,
    // cutError are read; an unset clampDistance or nearField counts as 0: no clamp radius, no
    // near field).
    VplGatherer(std::vector<Vpl> vpls, const RayTracer& tracer, const VplConfig& config,
                uint64_t seed);

    // `direct` is the probe's light from other sources (radiance SH, e.g. the direct light):
    // its scalar irradiance joins the total T the cut's relative bound refers to, as Lightcuts
    // compares each cluster with the whole pixel estimate.
    VplGatherResult gather(glm::vec3 position, sh::Order order, const sh::ShRgb& direct) const;

    const std::vector<Vpl>& vpls() const { return m_vpls; }

    // Bytes a gatherer of `count` VPLs holds (its copy of the VPLs and the light tree's
    // 2 count - 1 nodes), and at most while it is built (the set it is given and the build
    // order besides): the memory model's (memory_model.hpp).
    static uint64_t heldBytes(uint64_t count);
    static uint64_t buildBytes(uint64_t count);

private:
    struct Node {
        glm::vec3 boxMin;
        uint32_t representative; // index into m_vpls
        glm::vec3 boxMax;
        uint32_t secondChild; // the first child is the next node; 0 = leaf
        glm::vec3 coneAxis;
        float coneAngle; // radians: every member's normal is within it of coneAxis
        float coneCos;   // cos, sin and 2 sin(angle / 2) of coneAngle, for trig-free bounds
        float coneSin;
        float coneDeviation;
        glm::vec3 sphereCentre;
        float sphereRadius; // bounding sphere of the box
        glm::vec3 centroid; // luminance-weighted mean position of the members
        float luminance;    // lum of the members' summed intensity
        // Per colour channel c, sum over members of intensity_c x normal: the cluster's
        // summed intensity towards w is -dot(normalIntensity[c], w) when every member faces w.
        glm::vec3 normalIntensity[3];
        float repScale; // luminance / lum(representative's intensity)
    };

    // A clamped contribution at a probe (see the file comment).
    struct Contribution {
        glm::vec3 irradiance; // e, W/m^2 per channel
        glm::vec3 direction;  // unit, probe to the light
        float band1;          // band factors (spherical clamp; 1 otherwise)
        float band2;
    };
    // Light of radiant intensity `towards_probe` (W/sr, its cosine included) from `offset`
    // (light - probe, non-zero) after clamping.
    Contribution clamped(glm::vec3 offset, float d2, glm::vec3 towards_probe) const;
    std::optional<Contribution> contribution(const Vpl& vpl, glm::vec3 position,
                                             glm::vec3 intensity) const;
    // The cluster's estimate: for a cluster wholly facing the probe, its summed intensity
    // towards the probe (exact, through normalIntensity) placed at its centroid; otherwise the
    // representative's contribution x repScale (unbiased over the representative's choice).
    // Either lies in [0, U_C].
    std::optional<Contribution> estimate(const Node& node, glm::vec3 position,
                                         bool all_facing) const;
    // Band-0-weighted falloff at squared distance d2: the largest F of any point at that
    // distance (spherical: 2 / (1 + c) / max(d2, r^2)).
    float magnitudeFalloff(float d2) const;
    // The spherical clamp's tangent-plane lift is on only without a near field: it trades the
    // light a plane's near part loses for more from its far part, which is wrong once the
    // near part is path-traced.
    bool lifts() const { return m_clamp == VplClamp::Spherical && m_nearField == 0.0f; }
    // U_C (0: no member faces the probe), and whether every member faces it.
    struct Bounds {
        float upper;
        bool allFacing;
    };
    Bounds bounds(const Node& node, glm::vec3 position) const;
    // The parts of bounds() for a node whose normals span less than a hemisphere's cone: the
    // cone-and-sphere angular bound on the members' cosine towards `position` (nullopt when
    // every member faces away), then the plane bound that tightens it for flat clusters.
    std::optional<Bounds> angularBound(const Node& node, glm::vec3 position) const;
    std::optional<Bounds> planeBound(const Node& node, glm::vec3 position, float near_d2,
                                     float far_d2, Bounds angular) const;

    uint32_t build(std::vector<uint32_t>& order, size_t begin, size_t end, float normal_scale,
                   uint64_t seed);
    Node leafNode(uint32_t vpl) const;
    // The parent of nodes `first` and `second`; its representative drawn with `seed`.
    Node parentNode(uint32_t first, uint32_t second, uint32_t index, uint64_t seed) const;
    // Sorts order[begin, end) along the widest of the six coordinates (position, scaled normal).
    void sortAlongWidestAxis(std::vector<uint32_t>& order, size_t begin, size_t end,
                             float normal_scale) const;

    void project(const Contribution& c, sh::Order order,
                 std::array<glm::dvec3, sh::kMaxCoefficients>& acc) const;
    VplGatherResult gatherAll(glm::vec3 position, sh::Order order) const;
    VplGatherResult gatherCut(glm::vec3 position, sh::Order order, double baseline) const;
    class Cut; // one probe's lightcut while gatherCut settles it

    std::vector<Vpl> m_vpls;
    std::vector<Node> m_nodes;
    const RayTracer& m_tracer;
    VplClamp m_clamp;
    float m_clampDistance; // metres, distance and spherical clamps
    float m_nearField;     // metres: VPLs nearer to the probe are left to paths (0 = none)
    bool m_shadows;
    float m_cutError; // lightcut bound per cluster / probe total; 0 = every VPL
};

} // namespace probekit::baker
