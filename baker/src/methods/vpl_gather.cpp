#include "methods/vpl_gather.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

#include <glm/geometric.hpp>

#include "trace/rng.hpp"
#include "trace/sampling.hpp"

namespace probekit::baker {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;
// Widens every merged normal cone a little, so float rounding of the merge cannot make the
// cone (hence the bound) too tight.
constexpr float kConeSlack = 1e-5f;
constexpr uint64_t kRepresentativeStream = 0x726570ull; // "rep"
// A cluster wholly facing the probe is estimated at its centroid only while its bounding
// sphere's radius is below this fraction of the distance: the centroid estimate's error grows
// like (radius / distance)^2 and has one sign for a probe in front of a large flat cluster
// (cos / d^2 peaks at the centroid), so such errors would add up over the cut instead of
// cancelling like the representative's. Measured on the Cornell box: 0.5 gives 25% less
// error than representatives alone for the same cut.
constexpr float kCentroidOpening = 0.5f;
// With visibility, T never counts as less than this fraction of the probe's unoccluded total:
// a probe inside geometry sees nothing (T = 0), and a relative bound would open every cluster
// down to kMaxCutSize for no light at all.
constexpr double kUnoccludedFloor = 0.25;

struct Cone {
    glm::vec3 axis;
    float angle;
};

// Smallest cone containing both (Conty Estevez and Kulla, "Importance Sampling of Many Lights
// with Adaptive Tree Splitting", HPG 2018, Algorithm 1).
Cone mergeCones(Cone a, Cone b) {
    if (b.angle > a.angle) {
        std::swap(a, b);
    }
    const float cos_between = std::clamp(glm::dot(a.axis, b.axis), -1.0f, 1.0f);
    const float between = std::acos(cos_between);
    if (std::min(between + b.angle, kPi) <= a.angle) {
        return a;
    }
    const float merged = 0.5f * (a.angle + between + b.angle) + kConeSlack;
    if (merged >= kPi) {
        return Cone{a.axis, kPi};
    }
    // Rotate a's axis towards b's by merged - a.angle, in the plane of the two axes.
    const glm::vec3 across = b.axis - a.axis * cos_between;
    const float across_length = glm::length(across);
    if (!(across_length > 1e-6f)) {
        return Cone{a.axis, kPi}; // opposite axes: no plane, no tighter cone worth finding
    }
    const float rotation = merged - a.angle;
    const glm::vec3 axis =
        glm::normalize(a.axis * std::cos(rotation) + across / across_length * std::sin(rotation));
    return Cone{axis, merged};
}

float boxDistanceSquared(glm::vec3 lo, glm::vec3 hi, glm::vec3 p) {
    const glm::vec3 d = glm::max(glm::max(lo - p, p - hi), glm::vec3(0.0f));
    return glm::dot(d, d);
}

float luminanceOf(glm::vec3 c) {
    return float(luminance(c));
}

} // namespace

VplGatherer::VplGatherer(std::vector<Vpl> vpls, const RayTracer& tracer, const VplConfig& config,
                         uint64_t seed)
    : m_tracer(tracer), m_clamp(config.clamp), m_clampDistance(config.clampDistance.value_or(0.0f)),
      m_nearField(config.nearField.value_or(0.0f)), m_shadows(config.shadows),
      m_cutError(config.cutError) {
    assert(m_cutError >= 0.0f);
    m_vpls.reserve(vpls.size());
    for (const Vpl& v : vpls) {
        if (luminanceOf(v.intensity) > 0.0f) {
            m_vpls.push_back(v);
        }
    }
    if (m_vpls.empty() || m_cutError == 0.0f) {
        return;
    }
    // Lightcuts' 6D metric weighs normals by a fraction of the scene size: a quarter of the
    // set's diagonal separates a wall from the floor it meets once clusters are about that
    // small.
    glm::vec3 lo = m_vpls[0].position, hi = lo;
    for (const Vpl& v : m_vpls) {
        lo = glm::min(lo, v.position);
        hi = glm::max(hi, v.position);
    }
    const float normal_scale = 0.25f * glm::length(hi - lo);
    std::vector<uint32_t> order(m_vpls.size());
    for (uint32_t i = 0; i < order.size(); ++i) {
        order[i] = i;
    }
    m_nodes.reserve(2 * m_vpls.size() - 1);
    build(order, 0, order.size(), normal_scale, seed);
}

uint64_t VplGatherer::heldBytes(uint64_t count) {
    return count * sizeof(Vpl) + (count > 0 ? 2 * count - 1 : 0) * sizeof(Node);
}

uint64_t VplGatherer::buildBytes(uint64_t count) {
    return heldBytes(count) + count * (sizeof(Vpl) + sizeof(uint32_t));
}

uint32_t VplGatherer::build(std::vector<uint32_t>& order, size_t begin, size_t end,
                            float normal_scale, uint64_t seed) {
    const auto index = uint32_t(m_nodes.size());
    m_nodes.emplace_back();
    if (end - begin == 1) {
        m_nodes[index] = leafNode(order[begin]);
        return index;
    }
    sortAlongWidestAxis(order, begin, end, normal_scale);
    const size_t middle = begin + (end - begin) / 2;
    const uint32_t first = build(order, begin, middle, normal_scale, seed);
    const uint32_t second = build(order, middle, end, normal_scale, seed);
    m_nodes[index] = parentNode(first, second, index, seed);
    return index;
}

VplGatherer::Node VplGatherer::leafNode(uint32_t vpl) const {
    const Vpl& v = m_vpls[vpl];
    Node leaf;
    leaf.boxMin = leaf.boxMax = leaf.sphereCentre = v.position;
    leaf.sphereRadius = 0.0f;
    leaf.representative = vpl;
    leaf.secondChild = 0;
    leaf.coneAxis = v.normal;
    leaf.coneAngle = 0.0f;
    leaf.coneCos = 1.0f;
    leaf.coneSin = 0.0f;
    leaf.coneDeviation = 0.0f;
    leaf.centroid = v.position;
    leaf.luminance = luminanceOf(v.intensity);
    for (int c = 0; c < 3; ++c) {
        leaf.normalIntensity[c] = v.intensity[c] * v.normal;
    }
    leaf.repScale = 1.0f;
    return leaf;
}

void VplGatherer::sortAlongWidestAxis(std::vector<uint32_t>& order, size_t begin, size_t end,
                                      float normal_scale) const {
    // Split at the median of the widest of the six coordinates (position, scaled normal).
    float lo[6], hi[6];
    std::fill(lo, lo + 6, INFINITY);
    std::fill(hi, hi + 6, -INFINITY);
    const auto coordinate = [&](uint32_t vpl, int axis) {
        const Vpl& v = m_vpls[vpl];
        return axis < 3 ? v.position[axis] : normal_scale * v.normal[axis - 3];
    };
    for (size_t i = begin; i < end; ++i) {
        for (int axis = 0; axis < 6; ++axis) {
            const float c = coordinate(order[i], axis);
            lo[axis] = std::min(lo[axis], c);
            hi[axis] = std::max(hi[axis], c);
        }
    }
    int split = 0;
    for (int axis = 1; axis < 6; ++axis) {
        if (hi[axis] - lo[axis] > hi[split] - lo[split]) {
            split = axis;
        }
    }
    // Ties broken by index: the order (hence the tree) is the same on every platform.
    std::sort(order.begin() + std::ptrdiff_t(begin), order.begin() + std::ptrdiff_t(end),
              [&](uint32_t a, uint32_t b) {
                  const float ca = coordinate(a, split), cb = coordinate(b, split);
                  return ca < cb || (ca == cb && a < b);
              });
}

VplGatherer::Node VplGatherer::parentNode(uint32_t first, uint32_t second, uint32_t index,
                                          uint64_t seed) const {
    const Node& a = m_nodes[first];
    const Node& b = m_nodes[second];
    Node node;
    node.boxMin = glm::min(a.boxMin, b.boxMin);
    node.boxMax = glm::max(a.boxMax, b.boxMax);
    node.sphereCentre = 0.5f * (node.boxMin + node.boxMax);
    node.sphereRadius = 0.5f * glm::length(node.boxMax - node.boxMin);
    const Cone cone = mergeCones(Cone{a.coneAxis, a.coneAngle}, Cone{b.coneAxis, b.coneAngle});
    node.coneAxis = cone.axis;
    node.coneAngle = cone.angle;
    node.coneCos = std::cos(cone.angle);
    node.coneSin = std::sin(cone.angle);
    node.coneDeviation = 2.0f * std::sin(0.5f * cone.angle);
    node.luminance = a.luminance + b.luminance;
    node.centroid = (a.luminance * a.centroid + b.luminance * b.centroid) / node.luminance;
    // Kept inside the box against rounding: the bound U_C assumes it.
    node.centroid = glm::clamp(node.centroid, node.boxMin, node.boxMax);
    for (int c = 0; c < 3; ++c) {
        node.normalIntensity[c] = a.normalIntensity[c] + b.normalIntensity[c];
    }
    // The representative: one of the children's, with probability proportional to luminance,
    // so it is each member with probability lum(I_j) / lum(I_C).
    const float u = Rng(hashKeys(seed, kRepresentativeStream, index)).uniform();
    node.representative = u * node.luminance < a.luminance ? a.representative : b.representative;
    node.repScale = node.luminance / luminanceOf(m_vpls[node.representative].intensity);
    node.secondChild = second;
    return node;
}

VplGatherer::Contribution VplGatherer::clamped(glm::vec3 offset, float d2,
                                               glm::vec3 towards_probe) const {
    const glm::vec3 direction = offset / std::sqrt(d2);
    const float r2 = m_clampDistance * m_clampDistance;
    switch (m_clamp) {
    case VplClamp::None:
        break;
    case VplClamp::Distance:
        return Contribution{towards_probe / std::max(d2, r2), direction, 1.0f, 1.0f};
    case VplClamp::Spherical: {
        // The delta spread evenly over the cone the sphere subtends (d >= r here, see
        // contribution()): same energy, bands 1 and 2 scaled by the cone's Funk-Hecke factors
        // over its solid angle.
        const float c = std::sqrt(std::max(0.0f, 1.0f - r2 / std::max(d2, r2)));
        return Contribution{towards_probe / std::max(d2, r2), direction, 0.5f * (1.0f + c),
                            0.5f * c * (1.0f + c)};
    }
    }
    return Contribution{towards_probe / d2, direction, 1.0f, 1.0f};
}

std::optional<VplGatherer::Contribution>
VplGatherer::contribution(const Vpl& vpl, glm::vec3 position, glm::vec3 intensity) const {
    glm::vec3 offset = vpl.position - position;
    // The probe's height above the VPL's tangent plane.
    const float height = -glm::dot(vpl.normal, offset);
    if (!(height > 0.0f)) {
        return std::nullopt; // the probe is behind the lit side
    }
    if (glm::dot(offset, offset) < m_nearField * m_nearField) {
        return std::nullopt; // the near field is path-traced
    }
    const float r = m_clampDistance;
    if (lifts() && height < r) {
        // The VSL tangent-plane lift (see the header): seen as from height r.
        offset -= (r - height) * vpl.normal;
        const float d2 = glm::dot(offset, offset);
        return clamped(offset, d2, intensity * (r / std::sqrt(d2)));
    }
    const float d2 = glm::dot(offset, offset);
    return clamped(offset, d2, intensity * (height / std::sqrt(d2)));
}

std::optional<VplGatherer::Contribution> VplGatherer::estimate(const Node& node, glm::vec3 position,
                                                               bool all_facing) const {
    const Vpl& rep = m_vpls[node.representative];
    if (all_facing && node.secondChild != 0) {
        const glm::vec3 offset = node.centroid - position;
        const float d2 = glm::dot(offset, offset);
        if (d2 > 0.0f &&
            node.sphereRadius * node.sphereRadius < kCentroidOpening * kCentroidOpening * d2) {
            const glm::vec3 w = offset / std::sqrt(d2);
            const glm::vec3 towards_probe(std::max(0.0f, -glm::dot(node.normalIntensity[0], w)),
                                          std::max(0.0f, -glm::dot(node.normalIntensity[1], w)),
                                          std::max(0.0f, -glm::dot(node.normalIntensity[2], w)));
            return clamped(offset, d2, towards_probe);
        }
    }
    return contribution(rep, position, rep.intensity * node.repScale);
}

float VplGatherer::magnitudeFalloff(float d2) const {
    const float r2 = m_clampDistance * m_clampDistance;
    const float clamped = m_clamp == VplClamp::None ? d2 : std::max(d2, r2);
    return clamped > 0.0f ? 1.0f / clamped : INFINITY;
}

VplGatherer::Bounds VplGatherer::bounds(const Node& node, glm::vec3 position) const {
    const float near_d2 = boxDistanceSquared(node.boxMin, node.boxMax, position);
    const glm::vec3 far_offset =
        glm::max(glm::abs(position - node.boxMin), glm::abs(position - node.boxMax));
    const float far_d2 = glm::dot(far_offset, far_offset);
    const float near_field2 = m_nearField * m_nearField;
    if (far_d2 < near_field2) {
        return Bounds{0.0f, false}; // wholly in the path-traced near field
    }
    float cos_upper = 1.0f;
    bool all_facing = false;
    if (node.coneAngle < kPi) {
        const std::optional<Bounds> angular = angularBound(node, position);
        if (!angular) {
            return Bounds{0.0f, false};
        }
        const std::optional<Bounds> plane = planeBound(node, position, near_d2, far_d2, *angular);
        if (!plane) {
            return Bounds{0.0f, false};
        }
        cos_upper = plane->upper;
        all_facing = plane->allFacing;
    }
    if (lifts() && m_clampDistance > 0.0f) {
        // A lifted member contributes I (r / d') / d'^2 with d' >= max(d, r): its cosine
        // factor is at most r / d_near.
        cos_upper =
            std::max(cos_upper,
                     near_d2 > 0.0f ? std::min(1.0f, m_clampDistance / std::sqrt(near_d2)) : 1.0f);
    }
    // The centroid estimate counts every member: not for clusters reaching into the near field.
    all_facing = all_facing && near_d2 >= near_field2;
    return Bounds{node.luminance * cos_upper * magnitudeFalloff(near_d2), all_facing};
}

// Angular bound: the angle between the cone axis and the direction from the cluster's bounding
// sphere to the probe, less the cone's and the sphere's half-angles, bounds every member's angle
// from below; plus them, from above. Written with cosines and sines (angle differences by the
// subtraction formulas) to keep trig out of the cut. Returns the upper cosine and whether every
// member faces the probe.
std::optional<VplGatherer::Bounds> VplGatherer::angularBound(const Node& node,
                                                             glm::vec3 position) const {
    float cos_upper = 1.0f;
    bool all_facing = false;
    const glm::vec3 to_probe = position - node.sphereCentre;
    const float distance2 = glm::dot(to_probe, to_probe);
    const float radius2 = node.sphereRadius * node.sphereRadius;
    if (distance2 > radius2) {
        const float inverse = 1.0f / std::sqrt(distance2);
        const float cos_axis = std::clamp(glm::dot(node.coneAxis, to_probe) * inverse, -1.0f, 1.0f);
        const float sin_axis = std::sqrt(std::max(0.0f, 1.0f - cos_axis * cos_axis));
        const float sin_spread = node.sphereRadius * inverse;
        const float cos_spread = std::sqrt(std::max(0.0f, 1.0f - sin_spread * sin_spread));
        if (cos_axis < node.coneCos) {
            // axis - cone in (0, pi]: its cosine and (non-negative) sine.
            const float cos_less = cos_axis * node.coneCos + sin_axis * node.coneSin;
            const float sin_less = sin_axis * node.coneCos - cos_axis * node.coneSin;
            if (cos_less < cos_spread) {
                const float nearest = cos_less * cos_spread + sin_less * sin_spread;
                if (!(nearest > 0.0f)) {
                    return std::nullopt; // every member faces away
                }
                cos_upper = nearest;
            }
        }
        if (cos_axis > 0.0f && node.coneCos > 0.0f) {
            // axis + cone < pi here, so a positive cosine means below 90 degrees.
            const float cos_more = cos_axis * node.coneCos - sin_axis * node.coneSin;
            const float sin_more = sin_axis * node.coneCos + cos_axis * node.coneSin;
            all_facing = cos_more > 0.0f && cos_more * cos_spread - sin_more * sin_spread > 0.0f;
        }
    }
    return Bounds{cos_upper, all_facing};
}

std::optional<VplGatherer::Bounds> VplGatherer::planeBound(const Node& node, glm::vec3 position,
                                                           float near_d2, float far_d2,
                                                           Bounds angular) const {
    float cos_upper = angular.upper;
    bool all_facing = angular.allFacing;
    // Plane bound, tight for flat clusters (a wall seen from in front of it): with
    // |n_j - axis| <= 2 sin(cone / 2) = deviation, n_j.(p - x_j) lies within
    // axis.(p - x_j) +- deviation |p - x_j|, and axis.x over the box between the box's
    // support values.
    const float far = std::sqrt(far_d2);
    const glm::vec3 a = node.coneAxis;
    const glm::vec3 at_min = a * node.boxMin;
    const glm::vec3 at_max = a * node.boxMax;
    const glm::vec3 support_high = glm::max(at_min, at_max);
    const glm::vec3 support_low = glm::min(at_min, at_max);
    const float along = glm::dot(a, position);
    const float highest =
        along - (support_low.x + support_low.y + support_low.z) + node.coneDeviation * far;
    const float lowest =
        along - (support_high.x + support_high.y + support_high.z) - node.coneDeviation * far;
    if (!(highest > 0.0f)) {
        return std::nullopt;
    }
    if (near_d2 > 0.0f) {
        cos_upper = std::min(cos_upper, highest / std::sqrt(near_d2));
    }
    all_facing = all_facing || lowest > 0.0f;
    if (lifts()) {
        // Members closer than r to their tangent plane are lifted: the centroid estimate
        // (no lift) is only for clusters whose every member lies farther.
        all_facing = lowest >= m_clampDistance;
    }
    return Bounds{cos_upper, all_facing};
}

void VplGatherer::project(const Contribution& c, sh::Order order,
                          std::array<glm::dvec3, sh::kMaxCoefficients>& acc) const {
    const sh::Coeffs y = sh::evalBasis(c.direction);
    const int count = sh::coefficientCount(order);
    for (int i = 0; i < count; ++i) {
        const int band = sh::bandOf(i);
        const float factor = band == 0 ? 1.0f : (band == 1 ? c.band1 : c.band2);
        acc[i] += glm::dvec3(c.irradiance) * double(y[i] * factor);
    }
}

VplGatherResult VplGatherer::gather(glm::vec3 position, sh::Order order,
                                    const sh::ShRgb& direct) const {
    const ScopedFloatMode float_mode;
    if (m_vpls.empty()) {
        return VplGatherResult{};
    }
    if (m_cutError == 0.0f) {
        return gatherAll(position, order);
    }
    // Scalar irradiance (the integral of radiance over the sphere) is sqrt(4 pi) L00.
    const double baseline =
        std::max(0.0, luminance(direct.rgb[0]) * std::sqrt(4.0 * std::numbers::pi));
    return gatherCut(position, order, baseline);
}

VplGatherResult VplGatherer::gatherAll(glm::vec3 position, sh::Order order) const {
    std::vector<Contribution> contributions;
    std::vector<RayTracer::OcclusionRay> rays;
    for (const Vpl& v : m_vpls) {
        if (const std::optional<Contribution> c = contribution(v, position, v.intensity)) {
            contributions.push_back(*c);
            rays.push_back({position, v.shadowTarget - position, 1.0f});
        }
    }
    std::vector<uint8_t> occluded(rays.size(), 0);
    VplGatherResult result;
    if (m_shadows) {
        m_tracer.occluded(rays, occluded, true);
        result.rays = rays.size();
    }
    std::array<glm::dvec3, sh::kMaxCoefficients> acc{};
    for (size_t i = 0; i < contributions.size(); ++i) {
        if (!occluded[i]) {
            project(contributions[i], order, acc);
        }
    }
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        result.sh.rgb[i] = glm::vec3(acc[i]);
    }
    result.cutSize = uint32_t(contributions.size());
    return result;
}

// One probe's lightcut while it is settled (the file comment of vpl_gather.hpp has the rule):
// the clusters taken so far, live or opened again, and the total T they give.
class VplGatherer::Cut {
public:
    Cut(const VplGatherer& gatherer, glm::vec3 position, double baseline)
        : m_g(gatherer), m_position(position), m_baseline(baseline), m_total(baseline) {}

    // A first T that cannot be too small: the baseline plus the upper bounds of the clusters
    // kSeedDepth levels down. Too large a T only costs another round below; too small a one
    // would open clusters for nothing.
    double seedTotal() const {
        double first_total = m_baseline;
        std::vector<std::pair<uint32_t, int>> seeds{{0u, 0}};
        while (!seeds.empty()) {
            const auto [index, depth] = seeds.back();
            seeds.pop_back();
            const Node& node = m_g.m_nodes[index];
            if (node.secondChild == 0) {
                const Vpl& v = m_g.m_vpls[node.representative];
                if (const std::optional<Contribution> c =
                        m_g.contribution(v, m_position, v.intensity)) {
                    first_total += luminanceOf(c->irradiance);
                }
            } else if (depth < kSeedDepth) {
                seeds.emplace_back(node.secondChild, depth + 1);
                seeds.emplace_back(index + 1, depth + 1);
            } else {
                first_total += m_g.bounds(node, m_position).upper;
            }
        }
        return first_total;
    }

    // Depth-first from `start`: every cluster with U_C <= threshold (or single VPL) facing the
    // probe joins the cut, larger ones are opened. `known` is the visibility of start's
    // representative when already traced: the cluster keeping that representative inherits it.
    void descend(uint32_t start, float threshold, std::optional<bool> known) {
        const uint32_t start_representative = m_g.m_nodes[start].representative;
        m_stack.push_back(start);
        while (!m_stack.empty()) {
            const uint32_t index = m_stack.back();
            m_stack.pop_back();
            if (const std::optional<Cluster> c = visit(index, threshold)) {
                const bool inherits = m_g.m_nodes[index].representative == start_representative;
                join(*c, inherits ? known : std::nullopt);
            }
        }
    }

    // Re-opens every cluster whose bound exceeds cutError x T for the T now known (never less
    // than kUnoccludedFloor x the unoccluded T once visibility is traced), at most
    // kRefinementRounds times or until none does, tracing the new clusters' visibility after
    // each round when `trace`.
    void reopenRounds(bool trace) {
        for (int round = 0; round < kRefinementRounds && reopen(); ++round) {
            if (trace) {
                traceVisibility();
            }
        }
    }

    // With shadows: corrects T by the traced visibility and resumes the opening against it.
    void settleVisibility() {
        m_unoccluded = m_total;
        traceVisibility();
        // No representative visible: the probe is enclosed (inside geometry); opening clusters
        // would look for light that is not there.
        if (m_total > m_baseline) {
            reopenRounds(true);
        }
        traceVisibility(); // clusters opened in a last round
    }

    // The live clusters' visible light, projected, with the cut's size and error bound.
    VplGatherResult result(sh::Order order) const {
        VplGatherResult result;
        result.rays = m_rays;
        std::array<glm::dvec3, sh::kMaxCoefficients> acc{};
        double bound_sum = 0.0;
        for (const Cluster& c : m_cut) {
            if (!c.live) {
                continue;
            }
            ++result.cutSize;
            bound_sum += c.bound;
            if (c.hasContribution && c.visible) {
                m_g.project(c.contribution, order, acc);
            }
        }
        for (int i = 0; i < sh::kMaxCoefficients; ++i) {
            result.sh.rgb[i] = glm::vec3(acc[i]);
        }
        result.errorBound = float(bound_sum);
        return result;
    }

private:
    struct Cluster {
        uint32_t node;
        float bound;    // U_C; 0 for single VPLs (exact)
        float estimate; // magnitude of its estimate, before visibility
        Contribution contribution;
        bool hasContribution;
        bool live;
        bool traced;
        bool visible;
    };

    // The cluster node `index` gives the cut at `threshold`; none when it faces away or is
    // opened (its children then wait on the stack).
    std::optional<Cluster> visit(uint32_t index, float threshold) {
        const Node& node = m_g.m_nodes[index];
        Cluster c{};
        c.node = index;
        std::optional<Contribution> contribution;
        if (node.secondChild == 0) {
            const Vpl& v = m_g.m_vpls[node.representative];
            contribution = m_g.contribution(v, m_position, v.intensity);
            if (!contribution) {
                return std::nullopt; // faces away
            }
        } else {
            const Bounds b = m_g.bounds(node, m_position);
            if (!(b.upper > 0.0f)) {
                return std::nullopt; // no member faces the probe
            }
            if (b.upper > threshold && m_live + m_stack.size() + 2 <= kMaxCutSize) {
                m_stack.push_back(node.secondChild);
                m_stack.push_back(index + 1);
                return std::nullopt;
            }
            c.bound = b.upper;
            contribution = m_g.estimate(node, m_position, b.allFacing);
        }
        c.hasContribution = contribution.has_value();
        if (contribution) {
            c.contribution = *contribution;
            c.estimate = luminanceOf(contribution->irradiance);
        }
        return c;
    }

    // Adds a cluster to the cut as live, with `known` as its visibility when it inherits one.
    void join(Cluster c, std::optional<bool> known) {
        c.live = true;
        c.visible = true;
        // Nothing to trace without shadows or without a contribution.
        c.traced = !m_g.m_shadows || !c.hasContribution;
        if (known && !c.traced) {
            c.traced = true;
            c.visible = *known;
        }
        m_total += c.visible ? c.estimate : 0.0f;
        ++m_live;
        m_cut.push_back(c);
    }

    // One round of re-opening; false when no cluster exceeded the bound.
    bool reopen() {
        const auto threshold =
            float(double(m_g.m_cutError) * std::max(m_total, kUnoccludedFloor * m_unoccluded));
        m_violating.clear();
        for (uint32_t i = 0; i < m_cut.size(); ++i) {
            if (m_cut[i].live && m_cut[i].bound > threshold && m_live < kMaxCutSize) {
                m_violating.push_back(i);
            }
        }
        for (const uint32_t i : m_violating) {
            Cluster& c = m_cut[i];
            c.live = false;
            --m_live;
            m_total -= c.visible ? c.estimate : 0.0f;
            const std::optional<bool> known =
                c.traced && c.hasContribution ? std::optional<bool>(c.visible) : std::nullopt;
            descend(c.node, threshold, known);
        }
        return !m_violating.empty();
    }

    // One batch of rays to the representatives of the live clusters not traced yet; T loses
    // the occluded ones' estimates.
    void traceVisibility() {
        m_rayBatch.clear();
        m_tracedClusters.clear();
        for (uint32_t i = 0; i < m_cut.size(); ++i) {
            const Cluster& c = m_cut[i];
            if (c.live && !c.traced) {
                const Vpl& rep = m_g.m_vpls[m_g.m_nodes[c.node].representative];
                m_rayBatch.push_back({m_position, rep.shadowTarget - m_position, 1.0f});
                m_tracedClusters.push_back(i);
            }
        }
        m_occluded.assign(m_rayBatch.size(), 0);
        m_g.m_tracer.occluded(m_rayBatch, m_occluded, true);
        m_rays += m_rayBatch.size();
        for (size_t k = 0; k < m_tracedClusters.size(); ++k) {
            Cluster& c = m_cut[m_tracedClusters[k]];
            c.traced = true;
            if (m_occluded[k]) {
                c.visible = false;
                m_total -= c.estimate;
            }
        }
    }

    const VplGatherer& m_g;
    glm::vec3 m_position;
    double m_baseline;
    std::vector<Cluster> m_cut;
    std::vector<uint32_t> m_stack;
    uint32_t m_live = 0;
    double m_total;            // T: baseline + live estimates, with visibility where traced
    double m_unoccluded = 0.0; // T before visibility: the floor's reference
    uint64_t m_rays = 0;       // visibility rays traced
    // Scratch reused between rounds.
    std::vector<uint32_t> m_violating;
    std::vector<RayTracer::OcclusionRay> m_rayBatch;
    std::vector<uint32_t> m_tracedClusters;
    std::vector<uint8_t> m_occluded;
};

VplGatherResult VplGatherer::gatherCut(glm::vec3 position, sh::Order order, double baseline) const {
    Cut cut(*this, position, baseline);
    cut.descend(0, float(double(m_cutError) * cut.seedTotal()), std::nullopt);
    // First without visibility: no rays for clusters about to be opened.
    cut.reopenRounds(false);
    if (m_shadows) {
        cut.settleVisibility();
    }
    return cut.result(order);
}

} // namespace probekit::baker
