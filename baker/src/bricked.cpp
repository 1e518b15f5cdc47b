#include "bricked.hpp"

#include <algorithm>
#include <cmath>
#include <queue>
#include <unordered_map>

#include <glm/common.hpp>

#include "irradiance_error.hpp"
#include "probekit/formats/brick.hpp"
#include "ray_tracer.hpp"
#include "sampling.hpp"

namespace probekit::baker {
namespace {

using brick::Brick;
using brick::kBrickCells;
using brick::kBrickProbeCount;
using brick::kBrickSize;

struct Node {
    Brick brick;
    int parent = -1;
    int firstChild = -1;    // children are 8 consecutive nodes (x fastest)
    float predicted = 0.0f; // predicted interpolation error before testing
    // RMS disagreement at the finer probes, noise taken out; < 0 = not tested.
    float measured = -1.0f;
};

// The baked probes, one per lattice point of the finest level (3 * finest cells + 1 points per
// axis), baked on demand.
class Lattice {
public:
    Lattice(const VolumeDesc& desc, uint32_t max_level, const ProbeBatchFn& bake_batch)
        : m_desc(desc), m_bake(bake_batch) {
        m_cells = brick::finestCells(desc.grid.resolution(), max_level);
        m_points = m_cells * kBrickCells + 1u;
    }

    uint64_t key(glm::uvec3 u) const {
        return u.x + uint64_t(m_points.x) * (u.y + uint64_t(m_points.y) * u.z);
    }
    glm::uvec3 coord(uint64_t k) const {
        return glm::uvec3(uint32_t(k % m_points.x), uint32_t((k / m_points.x) % m_points.y),
                          uint32_t(k / (uint64_t(m_points.x) * m_points.y)));
    }
    glm::uvec3 points() const { return m_points; }

    glm::vec3 world(glm::uvec3 u) const {
        const grid::Aabb& box = m_desc.grid.bounds();
        const glm::vec3 t = glm::vec3(u) / glm::vec3(m_cells * kBrickCells);
        return m_desc.grid.frame().toWorld(box.min + t * box.size());
    }

    // Bakes every point of `wanted` not baked yet, in one batch.
    void ensure(const std::vector<glm::uvec3>& wanted) {
        std::vector<uint64_t> keys;
        for (const glm::uvec3& u : wanted) {
            const uint64_t k = key(u);
            if (!m_index.contains(k)) {
                keys.push_back(k);
            }
        }
        std::sort(keys.begin(), keys.end());
        keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
        if (keys.empty()) {
            return;
        }
        std::vector<glm::vec3> positions(keys.size());
        for (size_t i = 0; i < keys.size(); ++i) {
            positions[i] = world(coord(keys[i]));
        }
        std::vector<sh::ShRgb> sh(keys.size());
        std::vector<uint8_t> valid(keys.size());
        m_bake(positions, keys, sh, valid);
        for (size_t i = 0; i < keys.size(); ++i) {
            m_index.emplace(keys[i], uint32_t(m_sh.size()));
            m_sh.push_back(sh[i]);
            m_valid.push_back(valid[i]);
        }
    }

    bool has(glm::uvec3 u) const { return m_index.contains(key(u)); }
    uint32_t index(glm::uvec3 u) const { return m_index.at(key(u)); }
    const sh::ShRgb& sh(glm::uvec3 u) const { return m_sh[index(u)]; }
    bool valid(glm::uvec3 u) const { return m_valid[index(u)] == kProbeValid; }
    std::vector<sh::ShRgb>& allSh() { return m_sh; }
    std::vector<uint8_t>& allValid() { return m_valid; }
    const std::unordered_map<uint64_t, uint32_t>& indexMap() const { return m_index; }

private:
    const VolumeDesc& m_desc;
    const ProbeBatchFn& m_bake;
    glm::uvec3 m_cells;
    glm::uvec3 m_points;
    std::unordered_map<uint64_t, uint32_t> m_index;
    std::vector<sh::ShRgb> m_sh;
    std::vector<uint8_t> m_valid;
};

// Lattice points of a brick's region at `sub` probes per brick spacing (sub = 1: its own 64
// probes; sub = 2: the 7^3 points of the next level).
std::vector<glm::uvec3> regionPoints(const Brick& b, uint32_t max_level, uint32_t sub) {
    const uint32_t step = (1u << (max_level - b.level)) / sub;
    const glm::uvec3 origin = b.coord * kBrickCells * (1u << (max_level - b.level));
    const uint32_t n = kBrickCells * sub + 1;
    std::vector<glm::uvec3> out;
    out.reserve(size_t(n) * n * n);
    for (uint32_t z = 0; z < n; ++z) {
        for (uint32_t y = 0; y < n; ++y) {
            for (uint32_t x = 0; x < n; ++x) {
                out.push_back(origin + glm::uvec3(x, y, z) * step);
            }
        }
    }
    return out;
}

// Mean over the six axis normals and the three channels of (E_a(n) - E_b(n))^2.
double squaredDifference(const sh::ShRgb& a, const sh::ShRgb& b, sh::Order order) {
    return squaredAxisIrradianceDifference(a, b, order) / 18.0;
}

// Sum of squared trilinear weights at brick-local coordinates: how much of one probe's noise
// variance reaches the interpolated value.
double squaredWeightSum(glm::vec3 local) {
    double product = 1.0;
    for (int a = 0; a < 3; ++a) {
        const double t = double(local[a]) - std::floor(double(local[a]));
        product *= (1.0 - t) * (1.0 - t) + t * t;
    }
    return product;
}

// Accumulates squared disagreements minus what Monte Carlo noise alone would give.
struct ErrorSum {
    double excess = 0.0;
    size_t count = 0;
    void add(double squared_error, double squared_noise) {
        excess += squared_error - squared_noise;
        ++count;
    }
    // RMS interpolation error with the noise taken out (0 when noise explains it all).
    float rms() const {
        return count ? float(std::sqrt(std::max(0.0, excess / double(count)))) : 0.0f;
    }
};

struct Disagreement {
    float rms = 0.0f;
    float octant[8] = {};
};

// Compares the brick's trilinear interpolation with baked values at the finer lattice points
// of its region (those that are not its own probes). Points inside geometry are skipped (their
// values are dilated, not lit); the brick's own probes inside geometry take part with their
// dilated values, as the runtime will interpolate them.
// `noise2` is the relative noise variance of one probe's irradiance (see bakeBricked).
Disagreement measure(const Lattice& lattice, const Brick& b, uint32_t max_level, sh::Order order,
                     float scale, double noise2) {
    std::vector<sh::ShRgb> own(kBrickProbeCount);
    const std::vector<glm::uvec3> own_points = regionPoints(b, max_level, 1);
    for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
        own[k] = lattice.sh(own_points[k]);
    }
    constexpr uint32_t kSub = 2;
    constexpr uint32_t n = kBrickCells * kSub + 1;
    const std::vector<glm::uvec3> points = regionPoints(b, max_level, kSub);
    ErrorSum total;
    ErrorSum octants[8];
    const double inv_scale2 = 1.0 / (double(scale) * scale);
    for (uint32_t z = 0; z < n; ++z) {
        for (uint32_t y = 0; y < n; ++y) {
            for (uint32_t x = 0; x < n; ++x) {
                const glm::uvec3 q(x, y, z);
                const glm::uvec3 u = points[x + n * (y + n * z)];
                if ((x % kSub) + (y % kSub) + (z % kSub) == 0 || !lattice.valid(u)) {
                    continue; // one of the brick's own probes, or inside geometry
                }
                const glm::vec3 local = glm::vec3(q) / float(kSub);
                const double e2 =
                    squaredDifference(brick::interpolate(own, local), lattice.sh(u), order) *
                    inv_scale2;
                const double expected_noise = noise2 * (1.0 + squaredWeightSum(local));
                total.add(e2, expected_noise);
                // Octants: the child regions the point belongs to (border points to several).
                constexpr uint32_t half = n / 2; // 0..half in the low child, half..n-1 high
                for (uint32_t o = 0; o < 8; ++o) {
                    const glm::uvec3 hi(o & 1, (o >> 1) & 1, o >> 2);
                    bool inside = true;
                    for (int a = 0; a < 3; ++a) {
                        inside &= hi[a] ? q[a] >= half : q[a] <= half;
                    }
                    if (inside) {
                        octants[o].add(e2, expected_noise);
                    }
                }
            }
        }
    }
    Disagreement d;
    d.rms = total.rms();
    for (int o = 0; o < 8; ++o) {
        d.octant[o] = octants[o].rms();
    }
    return d;
}

// For each level, which regions have a triangle's bounding box within one probe spacing.
class GeometryReach {
public:
    GeometryReach(const Scene& scene, const VolumeDesc& desc, uint32_t max_level) {
        const grid::Aabb& box = desc.grid.bounds();
        const glm::uvec3 top = desc.grid.resolution();
        m_levels.resize(max_level + 1);
        for (uint32_t l = 0; l <= max_level; ++l) {
            m_levels[l].regions = top * (1u << l);
            const glm::uvec3 r = m_levels[l].regions;
            m_levels[l].near.assign(size_t(r.x) * r.y * r.z, 0);
        }
        for (const glm::uvec3& t : scene.triangles) {
            glm::vec3 lo(INFINITY), hi(-INFINITY);
            for (int v = 0; v < 3; ++v) {
                const glm::vec3 p = desc.grid.frame().toLocal(scene.positions[t[v]]);
                lo = glm::min(lo, p);
                hi = glm::max(hi, p);
            }
            for (Level& level : m_levels) {
                const glm::vec3 region = box.size() / glm::vec3(level.regions);
                const glm::vec3 reach = region / float(kBrickCells);
                const glm::vec3 a = (lo - reach - box.min) / region;
                const glm::vec3 b = (hi + reach - box.min) / region;
                if (glm::any(glm::lessThan(b, glm::vec3(0.0f))) ||
                    glm::any(glm::greaterThanEqual(a, glm::vec3(level.regions)))) {
                    continue;
                }
                const glm::uvec3 first(glm::max(glm::floor(a), 0.0f));
                const glm::uvec3 last = glm::min(glm::uvec3(glm::floor(b)), level.regions - 1u);
                for (uint32_t z = first.z; z <= last.z; ++z) {
                    for (uint32_t y = first.y; y <= last.y; ++y) {
                        for (uint32_t x = first.x; x <= last.x; ++x) {
                            level.near[x + size_t(level.regions.x) *
                                               (y + size_t(level.regions.y) * z)] = 1;
                        }
                    }
                }
            }
        }
    }

    bool near(const Brick& b) const {
        const Level& level = m_levels[b.level];
        return level.near[b.coord.x + size_t(level.regions.x) *
                                          (b.coord.y + size_t(level.regions.y) * b.coord.z)];
    }

private:
    struct Level {
        glm::uvec3 regions;
        std::vector<uint8_t> near;
    };
    std::vector<Level> m_levels;
};

// RMS over valid points, normals and channels of the irradiance: the error scale.
float irradianceScale(const Lattice& lattice, const std::vector<glm::uvec3>& points,
                      sh::Order order) {
    double sum2 = 0.0;
    size_t count = 0;
    for (const glm::uvec3& u : points) {
        if (!lattice.valid(u)) {
            continue;
        }
        for (const glm::vec3& n : kAxisNormals) {
            const glm::vec3 e = sh::irradiance(lattice.sh(u), order, n);
            sum2 += double(glm::dot(e, e));
            count += 3;
        }
    }
    const double rms = count ? std::sqrt(sum2 / double(count)) : 0.0;
    return rms > 0.0 ? float(rms) : 1.0f;
}

// Fills invalid lattice points from the valid ones nearest on the lattice: the mean of the
// valid points among the 26 neighbours at the smallest step (1, 2, 4, ... lattice units) that
// has any. Points filled in one pass become sources in the next, so the result does not
// depend on visiting order. Returns the points left unfilled.
uint64_t dilateLattice(Lattice& lattice, const std::vector<uint64_t>& used, uint32_t max_step) {
    std::vector<uint8_t>& valid = lattice.allValid();
    std::vector<uint8_t> filled = valid;
    std::vector<sh::ShRgb>& sh = lattice.allSh();
    const glm::ivec3 points(lattice.points());
    std::vector<uint64_t> missing;
    for (uint64_t k : used) {
        if (!filled[lattice.indexMap().at(k)]) {
            missing.push_back(k);
        }
    }
    while (!missing.empty()) {
        std::vector<std::pair<uint32_t, sh::ShRgb>> updates;
        std::vector<uint64_t> still;
        for (uint64_t k : missing) {
            const glm::ivec3 u(lattice.coord(k));
            sh::ShRgb sum;
            int count = 0;
            for (uint32_t step = 1; step <= max_step && count == 0; step *= 2) {
                for (int n = 0; n < 27; ++n) {
                    const glm::ivec3 d(n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1);
                    const glm::ivec3 v = u + d * int(step);
                    if (n == 13 || glm::any(glm::lessThan(v, glm::ivec3(0))) ||
                        glm::any(glm::greaterThanEqual(v, points))) {
                        continue;
                    }
                    const auto it = lattice.indexMap().find(lattice.key(glm::uvec3(v)));
                    if (it != lattice.indexMap().end() && filled[it->second]) {
                        sum += sh[it->second];
                        ++count;
                    }
                }
            }
            if (count > 0) {
                sum *= 1.0f / float(count);
                updates.emplace_back(lattice.indexMap().at(k), sum);
            } else {
                still.push_back(k);
            }
        }
        if (updates.empty()) {
            return still.size();
        }
        for (auto& [i, value] : updates) {
            sh[i] = value;
            filled[i] = 1;
        }
        missing = std::move(still);
    }
    return 0;
}

// Direct light from the scene's punctual lights at lattice points, computed on demand.
class DirectField {
public:
    DirectField(const Scene& scene, const RayTracer* tracer, const Lattice& lattice,
                sh::Order order)
        : m_scene(scene), m_tracer(tracer), m_lattice(lattice), m_order(order) {}

    const sh::ShRgb& at(glm::uvec3 u) {
        const uint64_t key = m_lattice.key(u);
        auto it = m_cache.find(key);
        if (it != m_cache.end()) {
            return it->second;
        }
        const glm::vec3 p = m_lattice.world(u);
        sh::ShRgb value;
        for (const PunctualLight& light : m_scene.lights) {
            const std::optional<LightDirection> to_light = directionToLight(light, p);
            if (!to_light || m_tracer->occluded(p, to_light->direction, to_light->distance)) {
                continue;
            }
            value += sh::projectDelta(to_light->direction, light.irradianceAt(p), m_order);
        }
        return m_cache.emplace(key, value).first->second;
    }

    // RMS disagreement (relative to `scale`) between the brick's interpolation of its own
    // direct light and the direct light at the finer lattice points of its region.
    float disagreement(const Brick& b, uint32_t max_level, float scale) {
        if (m_scene.lights.empty() || m_tracer == nullptr) {
            return 0.0f;
        }
        std::vector<sh::ShRgb> own(kBrickProbeCount);
        const auto own_points = regionPoints(b, max_level, 1);
        for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
            own[k] = at(own_points[k]);
        }
        constexpr uint32_t n = kBrickCells * 2 + 1;
        const auto points = regionPoints(b, max_level, 2);
        ErrorSum sum;
        for (uint32_t k = 0; k < n * n * n; ++k) {
            const glm::uvec3 q(k % n, (k / n) % n, k / (n * n));
            if ((q.x % 2) + (q.y % 2) + (q.z % 2) == 0) {
                continue;
            }
            sum.add(squaredDifference(brick::interpolate(own, glm::vec3(q) * 0.5f), at(points[k]),
                                      m_order) /
                        (double(scale) * scale),
                    0.0);
        }
        return sum.rms();
    }

private:
    const Scene& m_scene;
    const RayTracer* m_tracer;
    const Lattice& m_lattice;
    sh::Order m_order;
    std::unordered_map<uint64_t, sh::ShRgb> m_cache;
};

} // namespace

uint64_t brickedGpuBytes(glm::uvec3 top_bricks, uint32_t max_level, uint64_t bricks,
                         sh::Order order, Storage storage) {
    const glm::uvec3 cells = brick::finestCells(top_bricks, max_level);
    return bricks * kBrickProbeCount * planeCount(order) * 4 * bytesPerComponent(storage) +
           uint64_t(cells.x) * cells.y * cells.z * sizeof(uint32_t);
}

Result<BrickedOutcome> bakeBricked(const Scene& scene, const VolumeDesc& desc, sh::Order order,
                                   const BrickedSettings& settings,
                                   const ProbeBatchFn& bake_batch) {
    const uint32_t max_level = settings.maxLevel;
    const glm::uvec3 top = desc.grid.resolution();
    Lattice lattice(desc, max_level, bake_batch);
    const GeometryReach reach(scene, desc, max_level);

    // Level 0: every brick, baked in one batch.
    std::vector<Node> nodes;
    for (const Brick& b : brick::uniformLayout(top, 0).bricks) {
        nodes.push_back(Node{b});
    }
    std::vector<glm::uvec3> wanted;
    for (const Node& n : nodes) {
        const auto pts = regionPoints(n.brick, max_level, 1);
        wanted.insert(wanted.end(), pts.begin(), pts.end());
    }
    // Invalid probes take dilated values as soon as they are baked: the refinement test then
    // sees what the runtime will interpolate.
    auto dilate_all = [&] {
        if (!settings.dilate) {
            return;
        }
        std::vector<uint64_t> invalid;
        for (const auto& [key, index] : lattice.indexMap()) {
            if (lattice.allValid()[index] != kProbeValid) {
                invalid.push_back(key);
            }
        }
        std::sort(invalid.begin(), invalid.end());
        dilateLattice(lattice, invalid, 1u << max_level);
    };
    lattice.ensure(wanted);
    dilate_all();
    const float scale = irradianceScale(lattice, wanted, order);

    // Monte Carlo noise: a second, independent bake of up to kNoiseProbes valid level-0 probes
    // (ids with the top bit set seed other sample sequences). Half the mean squared difference
    // of the two estimates is one estimate's noise variance.
    double noise2 = 0.0;
    {
        constexpr size_t kNoiseProbes = 64;
        std::vector<glm::uvec3> valid_points;
        for (const glm::uvec3& u : wanted) {
            if (lattice.valid(u)) {
                valid_points.push_back(u);
            }
        }
        std::sort(valid_points.begin(), valid_points.end(),
                  [&](glm::uvec3 x, glm::uvec3 y) { return lattice.key(x) < lattice.key(y); });
        valid_points.erase(std::unique(valid_points.begin(), valid_points.end()),
                           valid_points.end());
        const size_t stride = std::max<size_t>(1, valid_points.size() / kNoiseProbes);
        std::vector<glm::vec3> positions;
        std::vector<uint64_t> ids;
        std::vector<glm::uvec3> picked;
        for (size_t i = 0; i < valid_points.size() && picked.size() < kNoiseProbes; i += stride) {
            picked.push_back(valid_points[i]);
            positions.push_back(lattice.world(valid_points[i]));
            ids.push_back(lattice.key(valid_points[i]) | (uint64_t(1) << 63));
        }
        std::vector<sh::ShRgb> again(picked.size());
        std::vector<uint8_t> again_valid(picked.size());
        bake_batch(positions, ids, again, again_valid);
        double sum = 0.0;
        for (size_t i = 0; i < picked.size(); ++i) {
            sum += squaredDifference(again[i], lattice.sh(picked[i]), order);
        }
        noise2 = picked.empty() ? 0.0 : 0.5 * sum / double(picked.size()) / (double(scale) * scale);
    }

    // Level-0 prediction: how far the brick's probes stray from its 8 corners' interpolation
    // (noise taken out), scaled by (1/3)^2 for the brick's own 3x finer spacing.
    for (Node& n : nodes) {
        const auto pts = regionPoints(n.brick, max_level, 1);
        std::vector<sh::ShRgb> corner_brick(kBrickProbeCount);
        for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
            // A brick whose probes are its corners' values spread over 0..3: interpolating it
            // at local / 3 is the corner lattice's interpolation.
            const glm::uvec3 l(k % 4, (k / 4) % 4, k / 16);
            const glm::uvec3 c = glm::min(l, glm::uvec3(1)) * 3u;
            corner_brick[k] = lattice.sh(pts[c.x + 4 * (c.y + 4 * c.z)]);
        }
        ErrorSum sum;
        for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
            const glm::uvec3 l(k % 4, (k / 4) % 4, k / 16);
            if (!lattice.valid(pts[k]) || glm::all(glm::equal(l % 3u, glm::uvec3(0)))) {
                continue;
            }
            const glm::vec3 t = glm::vec3(l) / 3.0f; // position in the corner lattice
            const double e2 =
                squaredDifference(brick::interpolate(corner_brick, t), lattice.sh(pts[k]), order) /
                (double(scale) * scale);
            sum.add(e2, noise2 * (1.0 + squaredWeightSum(t)));
        }
        // (1/3)^2 for the brick's 3x finer spacing in smooth light, 1/3 near surfaces.
        n.predicted = sum.rms() / (reach.near(n.brick) ? 3.0f : 9.0f);
    }

    BrickedOutcome out;
    std::vector<int> frontier(nodes.size());
    for (size_t i = 0; i < nodes.size(); ++i) {
        frontier[i] = int(i);
    }
    // The cheap pre-pass: direct light from punctual lights (one shadow ray per light, exact,
    // no noise) on the finer lattice; its disagreement finds shadow edges, also in open air.
    DirectField direct(scene, settings.tracer, lattice, order);
    for (uint32_t level = 0; level < max_level; ++level) {
        // A brick's share of the volume's squared error is its volume (1/8 per level) times
        // its squared RMS error: splitting pays where that share exceeds a level-0 brick's at
        // refine_error, so the threshold grows by sqrt(8) per level.
        const float threshold = settings.refineError * std::pow(8.0f, 0.5f * float(level));
        std::vector<int> candidates;
        std::vector<float> direct_error;
        wanted.clear();
        for (int i : frontier) {
            Node& n = nodes[size_t(i)];
            const auto own = regionPoints(n.brick, max_level, 1);
            if (std::none_of(own.begin(), own.end(),
                             [&](const glm::uvec3& u) { return lattice.valid(u); })) {
                continue; // inside geometry: never spent on
            }
            const float from_direct = direct.disagreement(n.brick, max_level, scale);
            if (std::max(n.predicted, from_direct) <= threshold) {
                continue;
            }
            candidates.push_back(i);
            direct_error.push_back(from_direct);
            const auto finer = regionPoints(n.brick, max_level, 2);
            wanted.insert(wanted.end(), finer.begin(), finer.end());
        }
        lattice.ensure(wanted);
        dilate_all();
        out.refineCandidates += candidates.size();
        std::vector<int> next;
        for (size_t c = 0; c < candidates.size(); ++c) {
            const int i = candidates[c];
            const Disagreement d =
                measure(lattice, nodes[size_t(i)].brick, max_level, order, scale, noise2);
            // The full bake's disagreement decides; the exact direct-light one is a floor
            // under it (noise subtraction can only hide an edge the pre-pass sees exactly).
            nodes[size_t(i)].measured = std::max(d.rms, direct_error[c]);
            if (nodes[size_t(i)].measured <= threshold) {
                continue; // the prediction was wrong: the finer probes stay unused
            }
            nodes[size_t(i)].firstChild = int(nodes.size());
            const Brick parent = nodes[size_t(i)].brick;
            // Error falls with the square of the spacing in smooth light, but near surfaces
            // (contact shading, occlusion) only about linearly.
            const float decay = reach.near(parent) ? 2.0f : 4.0f;
            for (uint32_t o = 0; o < 8; ++o) {
                Node child;
                child.brick.level = uint8_t(level + 1);
                child.brick.coord = parent.coord * 2u + glm::uvec3(o & 1, (o >> 1) & 1, o >> 2);
                child.parent = i;
                child.predicted = d.octant[o] / decay;
                next.push_back(int(nodes.size()));
                nodes.push_back(child);
            }
        }
        frontier = std::move(next);
    }

    // The budget: merge the cheapest splits (all of whose children are leaves) until it fits.
    // Leaves are counted per level, so the bytes (which depend on the deepest level in use)
    // cost nothing to recompute after each merge. Nodes removed by merging are marked with
    // parent = -2 and skipped from then on.
    uint64_t leaves_at[brick::kMaxLevel + 1] = {};
    for (const Node& n : nodes) {
        leaves_at[n.brick.level] += n.firstChild < 0;
    }
    auto deepest = [&] {
        uint32_t d = max_level;
        while (d > 0 && leaves_at[d] == 0) {
            --d;
        }
        return d;
    };
    auto bytes = [&] {
        const uint64_t leaves = leaves_at[0] + leaves_at[1] + leaves_at[2] + leaves_at[3];
        return brickedGpuBytes(top, deepest(), leaves, order, desc.storage);
    };
    if (bytes() > settings.budgetBytes) {
        using Entry = std::pair<float, int>;
        std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
        auto mergeable = [&](int i) {
            const Node& n = nodes[size_t(i)];
            if (n.firstChild < 0) {
                return false;
            }
            for (int c = 0; c < 8; ++c) {
                if (nodes[size_t(n.firstChild + c)].firstChild >= 0) {
                    return false;
                }
            }
            return true;
        };
        for (size_t i = 0; i < nodes.size(); ++i) {
            if (nodes[i].parent != -2 && mergeable(int(i))) {
                heap.emplace(nodes[i].measured, int(i));
            }
        }
        while (bytes() > settings.budgetBytes && !heap.empty()) {
            const auto [error, i] = heap.top();
            heap.pop();
            Node& n = nodes[size_t(i)];
            for (int c = 0; c < 8; ++c) {
                nodes[size_t(n.firstChild + c)].parent = -2;
                nodes[size_t(n.firstChild + c)].firstChild = -1;
            }
            n.firstChild = -1;
            leaves_at[n.brick.level + 1] -= 8;
            leaves_at[n.brick.level] += 1;
            ++out.budgetDropped;
            out.budgetError = std::max(out.budgetError, double(error));
            if (n.parent >= 0 && mergeable(n.parent)) {
                heap.emplace(nodes[size_t(n.parent)].measured, n.parent);
            }
        }
        if (bytes() > settings.budgetBytes) {
            return makeError(ErrorCode::OutOfRange,
                             "volume '" + desc.name + "': level 0 alone needs " +
                                 std::to_string((bytes() + (1 << 20) - 1) >> 20) +
                                 " MiB, more than max_memory_mb = " +
                                 std::to_string(settings.budgetBytes >> 20) +
                                 " (fewer level-0 bricks: lower the density or resolution)");
        }
    }

    // The leaves, coarse first, then z, y, x.
    std::vector<int> leaf_nodes;
    for (size_t i = 0; i < nodes.size(); ++i) {
        if (nodes[i].parent != -2 && nodes[i].firstChild < 0) {
            leaf_nodes.push_back(int(i));
        }
    }
    std::sort(leaf_nodes.begin(), leaf_nodes.end(), [&](int a, int b) {
        const Brick& x = nodes[size_t(a)].brick;
        const Brick& y = nodes[size_t(b)].brick;
        return std::tuple(x.level, x.coord.z, x.coord.y, x.coord.x) <
               std::tuple(y.level, y.coord.z, y.coord.y, y.coord.x);
    });

    // Predicted interpolation error: per leaf the RMS disagreement where it was measured,
    // otherwise its prediction, weighted by the leaf's volume times its share of valid probes
    // (error is only ever measured in open space).
    double sum_w = 0.0, sum_e2 = 0.0;
    for (int i : leaf_nodes) {
        const Node& n = nodes[size_t(i)];
        const double e = n.measured >= 0.0f ? n.measured : n.predicted;
        const auto own = regionPoints(n.brick, max_level, 1);
        const double valid_share =
            double(std::count_if(own.begin(), own.end(),
                                 [&](const glm::uvec3& u) { return lattice.valid(u); })) /
            double(kBrickProbeCount);
        const double w = std::ldexp(valid_share, -3 * int(n.brick.level));
        sum_w += w;
        sum_e2 += w * e * e;
    }
    out.predictedError = sum_w > 0.0 ? std::sqrt(sum_e2 / sum_w) : 0.0;

    // Re-express every leaf on the lattice of the deepest level actually used.
    const uint32_t used_level = deepest();
    out.desc = desc;
    out.desc.layout = VolumeLayout::Bricked;
    out.desc.bricks.maxLevel = used_level;
    std::vector<uint64_t> used_keys;
    for (int i : leaf_nodes) {
        const Brick& b = nodes[size_t(i)].brick;
        out.desc.bricks.bricks.push_back(b);
        ++out.bricksPerLevel[b.level];
        for (const glm::uvec3& u : regionPoints(b, max_level, 1)) {
            used_keys.push_back(lattice.key(u));
        }
    }
    std::vector<uint8_t> original_valid = lattice.allValid();
    if (settings.dilate) {
        std::vector<uint64_t> unique = used_keys;
        std::sort(unique.begin(), unique.end());
        unique.erase(std::unique(unique.begin(), unique.end()), unique.end());
        const uint64_t unreachable = dilateLattice(lattice, unique, 1u << max_level);
        if (unreachable > 0) {
            out.warnings.push_back("volume '" + desc.name + "': " + std::to_string(unreachable) +
                                   " invalid probes have no valid probe to dilate from");
        }
    }
    out.probes.reserve(used_keys.size());
    out.validity.reserve(used_keys.size());
    for (uint64_t k : used_keys) {
        const uint32_t index = lattice.indexMap().at(k);
        out.probes.push_back(lattice.allSh()[index]);
        out.validity.push_back(original_valid[index]);
        out.invalidProbes += original_valid[index] == kProbeInvalid;
    }
    Result<std::vector<uint32_t>> indirection =
        brick::buildIndirection(top, out.desc.bricks, "volume '" + desc.name + "'");
    if (!indirection) {
        return indirection.error();
    }
    brick::stitchBorders(top, out.desc.bricks, indirection.value(), out.probes);
    return out;
}

} // namespace probekit::baker
