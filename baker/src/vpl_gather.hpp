// probekit::baker::VplGatherer — gathering a VPL set (vpl_paths.hpp) at probes, into radiance SH.
//
// One VPL of intensity I along its normal n at point x gives a probe at p (d = |x - p|,
// w = (x - p) / d) a directional delta of irradiance e = I max(0, -n.w) / d^2 from w, projected
// exactly: coefficients e Y_lm(w) (formats/CONVENTIONS.md). The VPL reflects only into the
// hemisphere it was lit from, so VPLs facing away contribute nothing and are culled.
//
// Clamping (VplClamp) removes the 1 / d^2 spike of a VPL close to the probe; r = clampDistance:
//  * None: as above, unbiased with respect to the VPL set, unbounded near surfaces.
//  * Distance: d^2 replaced by max(d^2, r^2).
//  * Spherical: the virtual spherical light of Hasan, Krivanek, Walter and Bala, "Virtual
//    Spherical Lights for Many-Light Rendering of Glossy Scenes" (SIGGRAPH Asia 2009): the VPL's
//    intensity spread over a Lambertian sphere of radius r, whose radiance I / (pi r^2) fills
//    the cone of half-angle alpha, sin alpha = r / max(d, r), about w. The cone's exact SH
//    (Funk-Hecke: band l scaled by 2 pi times the integral of P_l over [cos alpha, 1]) is
//    e Y_lm(w) x (2 / (1 + c), 1, c) for bands (0, 1, 2), c = cos alpha and
//    e = I max(0, -n.w) / max(d, r)^2. Band 1 (the irradiance a surface facing it receives)
//    is exactly the point light's outside the sphere, band 0 gains (1 - c) / (1 + c) ~ r^2 /
//    (4 d^2); inside the sphere (d < r) the probe sees a hemisphere of radiance I / (pi r^2).
//    The spike is bounded by 2 I / r^2 and spread over a hemisphere instead of a direction.
//
// Lightcuts (Walter et al., "Lightcuts: A Scalable Approach to Illumination", SIGGRAPH 2005):
// the VPLs are the leaves of a binary tree (top-down median splits along the widest of the
// three position axes and the three normal axes scaled by a quarter of the set's diagonal,
// Lightcuts' 6D metric). A cluster C keeps its members' summed intensity, their bounding box,
// a cone bounding their normals, a representative member j chosen at build time with
// probability lum(I_j) / lum(I_C) (hashed from the seed and the node), its luminance-weighted
// centroid and, per channel, the sum of intensity x normal. Its estimate at a probe:
//  * if every member faces the probe and the cluster is small seen from it (bounding radius <
//    kCentroidOpening x distance to the centroid): its exact summed intensity towards the
//    probe, -sum_j I_j n_j.w, placed at the centroid;
//  * otherwise the representative's contribution x lum(I_C) / lum(I_j) (unbiased, per
//    channel, over the choice of representative).
// Visibility is the representative's.
//
// The error bound. The magnitude of a contribution is m = lum(e) x band-0 factor, the
// luminance of the probe's scalar irradiance (integral of radiance over the sphere). For a
// cluster, U_C = lum(I_C) x cosBound x F(dmin^2): cosBound bounds max(0, n_j.(p - x_j)) /
// |p - x_j| over the cluster by the smaller of an angular bound (normal cone and the box's
// bounding sphere, Conty Estevez and Kulla 2018) and a plane bound (exact for flat clusters),
// and F is the clamped falloff (band-0 factor included) at the box's nearest point (F
// decreases with distance). The true sum of the members' magnitudes and the estimate both lie
// in [0, U_C] (whatever the visibility), so the cluster's error in the luminance of E_L2(n) is
// at most 1.11 U_C for every normal n (per unit magnitude, the L2 irradiance of a delta or VSL,
// f0/4 + t/2 + (5/32) f2 (3t^2 - 1) over f0 with t = n.w, lies in [-0.04, 1.0625]). The cut
// starts at the root and repeatedly replaces the cluster of largest U_C by its children until
// every cluster has U_C <= cutError x T, T the probe's current total magnitude (the `direct`
// light given to gather() plus the cut's estimates, with visibility), or the cut holds
// kMaxCutSize clusters. So each cluster's error is at most 1.11 cutError T, the whole cut's at
// most 1.11 sum U_C (VplGatherResult::errorBound). Clusters with cosBound 0 face away from the
// probe and are dropped exactly.
//
// Visibility (shadows on): one ray from the probe to each cut member's representative
// (Vpl::shadowTarget), traced in batches through RayTracer's stream query. The cut is refined
// without visibility first, then the unoccluded total T is corrected by the traced visibility
// and the refinement resumes against it (at most kVisibilityRounds times), so that shadowed
// probes are held to the same relative bound as lit ones.
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

#include "probekit/baker/bake.hpp"
#include "probekit/formats/sh.hpp"
#include "ray_tracer.hpp"
#include "vpl_paths.hpp"

namespace probekit::baker {

struct VplGatherSettings {
    VplClamp clamp = VplClamp::Spherical;
    float clampDistance = 0.0f; // metres, distance and spherical clamps
    bool shadows = true;
    float cutError = 0.02f; // lightcut bound per cluster / probe total; 0 = every VPL
};

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
    VplGatherer(std::vector<Vpl> vpls, const RayTracer& tracer, VplGatherSettings settings,
                uint64_t seed);

    // `direct` is the probe's light from other sources (radiance SH, e.g. the direct light):
    // its scalar irradiance joins the total T the cut's relative bound refers to, as Lightcuts
    // compares each cluster with the whole pixel estimate.
    VplGatherResult gather(glm::vec3 position, sh::Order order, const sh::ShRgb& direct) const;

    const std::vector<Vpl>& vpls() const { return m_vpls; }

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
        float band0;          // band factors (spherical clamp; 1 otherwise)
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
    // U_C (0: no member faces the probe), and whether every member faces it.
    struct Bounds {
        float upper;
        bool allFacing;
    };
    Bounds bounds(const Node& node, glm::vec3 position) const;

    uint32_t build(std::vector<uint32_t>& order, size_t begin, size_t end, float normal_scale,
                   uint64_t seed);

    void project(const Contribution& c, sh::Order order,
                 std::array<glm::dvec3, sh::kMaxCoefficients>& acc) const;
    VplGatherResult gatherAll(glm::vec3 position, sh::Order order) const;
    VplGatherResult gatherCut(glm::vec3 position, sh::Order order, double baseline) const;

    std::vector<Vpl> m_vpls;
    std::vector<Node> m_nodes;
    const RayTracer& m_tracer;
    VplGatherSettings m_settings;
};

} // namespace probekit::baker
