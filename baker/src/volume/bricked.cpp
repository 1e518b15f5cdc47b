#include "volume/bricked.hpp"

#include <algorithm>
#include <cmath>
#include <queue>
#include <unordered_map>

#include <glm/common.hpp>

#include "methods/irradiance_error.hpp"
#include "probekit/formats/brick.hpp"
#include "trace/ray_tracer.hpp"
#include "trace/sampling.hpp"
#include "volume/dering.hpp"
#include "volume/visibility.hpp"

namespace probekit::baker {
namespace {

using brick::Brick;
using brick::kBrickCells;
using brick::kBrickProbeCount;
using brick::kBrickSize;

struct Node {
    Brick brick;
    int parent = -1;
    int children[8] = {-1, -1, -1, -1, -1, -1, -1, -1}; // kept finer bricks per octant
    float predicted = 0.0f; // predicted interpolation error before testing
    bool tested = false;    // its finer probes were baked and `octant` measured
    // RMS disagreement at the finer probes of each octant (the region of the finer brick
    // there), noise taken out.
    float octant[8] = {};
    // The same in the bounded measure (irradiance_error.hpp), which the prediction reports
    // (predictFromCorners sets predictedBounded, for level 0 and the untested stored bricks).
    float predictedBounded = 0.0f;
    float octantBounded[8] = {};
    float gain = 0.0f;    // the parent's disagreement in this brick's octant: what it removes
    bool removed = false; // dropped by the budget
};

// The 26 directions from a lattice point to its neighbours in the box's frame, unit length:
// the 6 axes, then the 12 edges, then the 8 corners.
const std::vector<glm::vec3>& nudgeDirections() {
    static const std::vector<glm::vec3> directions = [] {
        std::vector<glm::vec3> out;
        for (int axes = 1; axes <= 3; ++axes) {
            for (int n = 0; n < 27; ++n) {
                const glm::ivec3 d(n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1);
                if (std::abs(d.x) + std::abs(d.y) + std::abs(d.z) == axes) {
                    out.push_back(glm::normalize(glm::vec3(d)));
                }
            }
        }
        return out;
    }();
    return directions;
}

// The baked probes, one per lattice point of the finest level (3 * finest cells + 1 points per
// axis), baked on demand.
class Lattice {
public:
    Lattice(const VolumeDesc& desc, uint32_t max_level, const ProbeBatchFn& bake_batch,
            const RayTracer* tracer, float backface_threshold)
        : m_desc(desc), m_bake(bake_batch), m_tracer(tracer),
          m_backfaceThreshold(backface_threshold) {
        m_cells = brick::finestCells(desc.grid.resolution(), max_level);
        m_points = m_cells * kBrickCells + 1u;
        const glm::vec3 spacing = desc.grid.bounds().size() / glm::vec3(m_cells * kBrickCells);
        m_spacing = std::min({spacing.x, spacing.y, spacing.z});
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

    // Bakes every point of `wanted` not baked yet, in one batch; `before`, when set, is told
    // the batch's size first (not that of the nudges' re-bakes).
    void ensure(const std::vector<glm::uvec3>& wanted,
                const std::function<void(size_t)>& before = {}) {
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
        if (before) {
            before(keys.size());
        }
        m_bake(positions, keys, sh, valid);
        const std::vector<uint8_t> nudged = nudge(positions, keys, sh, valid);
        for (size_t i = 0; i < keys.size(); ++i) {
            m_nudged.push_back(nudged[i]);
            m_index.emplace(keys[i], uint32_t(m_sh.size()));
            m_sh.push_back(sh[i]);
            m_valid.push_back(valid[i]);
        }
    }

    uint32_t index(glm::uvec3 u) const { return m_index.at(key(u)); }
    const sh::ShRgb& sh(glm::uvec3 u) const { return m_sh[index(u)]; }
    bool valid(glm::uvec3 u) const { return m_valid[index(u)] == kProbeValid; }
    bool nudged(uint64_t key) const { return m_nudged[m_index.at(key)] != 0; }
    std::vector<sh::ShRgb>& allSh() { return m_sh; }
    std::vector<uint8_t>& allValid() { return m_valid; }
    size_t size() const { return m_valid.size(); }
    const std::unordered_map<uint64_t, uint32_t>& indexMap() const { return m_index; }

private:
    // Lattice points lie on the box faces, and a box is often placed against walls and floors:
    // such a probe sits on a surface, where half its rays start inside the solid and it bakes
    // invalid. Rather than dilate it from probes a whole spacing away, it is baked again just
    // inside the box: at the first of the 26 directions (axes, then edges, then corners) that
    // point into the box from every face the probe is on, and distances 1/32 and 1/8 of the
    // finest spacing, whose own test rays see few enough back faces. Probes inside the box
    // stay as they are (one inside a thin wall would take one side's light to the other), and
    // so do probes deeper inside a solid: both are dilated as before.
    // Returns 1 for each probe that was moved.
    std::vector<uint8_t> nudge(std::span<const glm::vec3> positions, std::span<const uint64_t> keys,
                               std::span<sh::ShRgb> sh, std::span<uint8_t> valid) {
        std::vector<uint8_t> nudged(keys.size(), 0);
        if (m_tracer == nullptr) {
            return nudged;
        }
        // The box's (local) axis directions, and the same in world space.
        const std::vector<glm::vec3>& directions = nudgeDirections();
        std::vector<glm::vec3> world_directions;
        for (const glm::vec3& d : directions) {
            world_directions.push_back(m_desc.grid.frame().rotation * d);
        }
        const float radii[] = {m_spacing / 32.0f, m_spacing / 8.0f};
        // Back-face share of the rays from q in the 26 directions.
        auto backfaces = [&](glm::vec3 q) {
            int back = 0;
            for (const glm::vec3& d : world_directions) {
                const std::optional<Hit> hit = m_tracer->intersect(q, d);
                back += hit && hit->backFace;
            }
            return float(back) / float(world_directions.size());
        };
        std::vector<glm::vec3> moved;
        std::vector<uint64_t> moved_keys;
        std::vector<size_t> slots;
        for (size_t i = 0; i < keys.size(); ++i) {
            if (valid[i] == kProbeValid) {
                continue;
            }
            const glm::uvec3 u = coord(keys[i]);
            glm::ivec3 inward(0); // +1 / -1 on the box's min / max face along an axis
            for (int a = 0; a < 3; ++a) {
                inward[a] = u[a] == 0 ? 1 : u[a] + 1 == m_points[a] ? -1 : 0;
            }
            if (inward == glm::ivec3(0)) {
                continue;
            }
            const glm::vec3 p = positions[i];
            for (const float r : radii) {
                size_t found = directions.size();
                for (size_t k = 0; k < directions.size() && found == directions.size(); ++k) {
                    bool into_box = true;
                    for (int a = 0; a < 3; ++a) {
                        into_box &= inward[a] == 0 || directions[k][a] * float(inward[a]) > 0.0f;
                    }
                    if (into_box && backfaces(p + r * world_directions[k]) <= m_backfaceThreshold) {
                        found = k;
                    }
                }
                if (found < directions.size()) {
                    moved.push_back(p + r * world_directions[found]);
                    moved_keys.push_back(keys[i]);
                    slots.push_back(i);
                    break;
                }
            }
        }
        if (moved.empty()) {
            return nudged;
        }
        std::vector<sh::ShRgb> moved_sh(moved.size());
        std::vector<uint8_t> moved_valid(moved.size());
        m_bake(moved, moved_keys, moved_sh, moved_valid);
        for (size_t j = 0; j < moved.size(); ++j) {
            if (moved_valid[j] == kProbeValid) {
                sh[slots[j]] = moved_sh[j];
                valid[slots[j]] = kProbeValid;
                nudged[slots[j]] = 1;
            }
        }
        return nudged;
    }

    const VolumeDesc& m_desc;
    const ProbeBatchFn& m_bake;
    const RayTracer* m_tracer;
    float m_backfaceThreshold;
    float m_spacing = 0.0f;
    std::vector<uint8_t> m_nudged; // per baked point, like m_sh
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

// True when every probe of the brick is inside geometry (invalid before dilation): a brick
// lying wholly inside a solid. Such a brick holds only values dilated from outside it, so a
// finer one is never stored ("free-space bricks": the coarser brick shows there, brick.hpp's
// nesting, and the runtime samples it unchanged). Decided from the probes' validity (the
// back-face rule, validity.hpp) alone, not a flood fill of the lattice from open space: a flood
// fill needs a seed in the level's open space, and neither the box faces (outside a sealed
// level, arena-sealed) nor any lattice point is known to be one without player start points,
// which the config does not give yet; a sealed pocket inside a block whose probes see front
// faces therefore still counts as air. Level-0 bricks are all stored, solid or not: the layout
// must cover the box (buildIndirection), and leaving them out needs an empty indirection entry
// and a rule for the runtime there, a new .pvol version.
bool insideGeometry(const Lattice& lattice, const Brick& b, uint32_t max_level) {
    const auto own = regionPoints(b, max_level, 1);
    return std::none_of(own.begin(), own.end(),
                        [&](const glm::uvec3& u) { return lattice.valid(u); });
}

// Mean over the six axis normals and the three channels of (E_a(n) - E_b(n))^2.
double squaredDifference(const sh::ShRgb& a, const sh::ShRgb& b, sh::Order order) {
    return squaredAxisIrradianceDifference(a, b, order) / 18.0;
}

// Mean over the six axis normals and three channels of E^2.
double meanSquaredIrradiance(const sh::ShRgb& a, sh::Order order) {
    return squaredAxisIrradiance(a, order) / 18.0;
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

// RMS disagreement per octant of a brick (the region of the finer brick there), relative to
// the error scale (refinement compares it with refine_error) and in the bounded measure.
struct Disagreement {
    float octant[8] = {};
    float bounded[8] = {};
};

// The error's scales, from the level-0 probes (levelZeroScales). `scale` is the RMS irradiance
// refinement measures against; the bounded measure weighs a point of mean squared irradiance
// e2 by brightPointWeight(e2, cap) and divides by boundedScale2, the weighted mean square.
struct ErrorScales {
    float scale = 1.0f;
    double cap = INFINITY;
    double boundedScale2 = 1.0;
    // The bounded measure's noise model: one probe's noise variance is relNoise2 times its
    // mean squared irradiance, or times scale^2 where darker (measureNoise). Monte Carlo noise
    // grows with the light, and adaptive sampling holds each probe to a noise relative to its
    // own irradiance: one variance for the whole volume under-subtracts it where the light is
    // bright and over-subtracts it where dark.
    double relNoise2 = 0.0;
    // Turns a squared difference already divided by scale^2, at a point of mean squared
    // irradiance `e2`, into the bounded measure's.
    double boundedFactor(double e2) const {
        return brightPointWeight(e2, cap) * double(scale) * scale / boundedScale2;
    }
    // The bounded measure's expected squared noise of a difference at a point of mean squared
    // irradiance `e2` whose coarse side interpolates with squared weights summing to `weights2`
    // (probes of about the point's own irradiance).
    double boundedNoise(double e2, double weights2) const {
        return brightPointWeight(e2, cap) * (1.0 + weights2) * relNoise2 *
               std::max(e2, double(scale) * scale) / boundedScale2;
    }
};

// Accumulates one point of a brick's finer lattice (q in 0..6 per axis) into every octant
// (finer brick region) it lies in: border points count for several.
struct OctantSums {
    ErrorSum octants[8];
    ErrorSum bounded[8];
    // `bounded_factor` turns the error into the bounded measure's, whose noise is
    // `bounded_noise` (ErrorScales).
    void add(glm::uvec3 q, double squared_error, double squared_noise, double bounded_factor,
             double bounded_noise) {
        constexpr uint32_t half = kBrickCells; // 0..3 in the low octant, 3..6 in the high one
        for (uint32_t o = 0; o < 8; ++o) {
            const glm::uvec3 hi(o & 1, (o >> 1) & 1, o >> 2);
            bool inside = true;
            for (int a = 0; a < 3; ++a) {
                inside &= hi[a] ? q[a] >= half : q[a] <= half;
            }
            if (inside) {
                octants[o].add(squared_error, squared_noise);
                bounded[o].add(squared_error * bounded_factor, bounded_noise);
            }
        }
    }
    Disagreement result() const {
        Disagreement d;
        for (int o = 0; o < 8; ++o) {
            d.octant[o] = octants[o].rms();
            d.bounded[o] = bounded[o].rms();
        }
        return d;
    }
};

// Compares the brick's trilinear interpolation with baked values at the finer lattice points
// of its region (those that are not its own probes). Points inside geometry are skipped (their
// values are dilated, not lit); the brick's own probes inside geometry take part with their
// dilated values, as the runtime will interpolate them.
// `noise2` is the relative noise variance of one probe's irradiance (see bakeBricked).
Disagreement measure(const Lattice& lattice, const Brick& b, uint32_t max_level, sh::Order order,
                     const ErrorScales& scales, double noise2) {
    std::vector<sh::ShRgb> own(kBrickProbeCount);
    const std::vector<glm::uvec3> own_points = regionPoints(b, max_level, 1);
    for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
        own[k] = lattice.sh(own_points[k]);
    }
    constexpr uint32_t kSub = 2;
    constexpr uint32_t n = kBrickCells * kSub + 1;
    const std::vector<glm::uvec3> points = regionPoints(b, max_level, kSub);
    OctantSums sums;
    const double inv_scale2 = 1.0 / (double(scales.scale) * scales.scale);
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
                const double fine2 = meanSquaredIrradiance(lattice.sh(u), order);
                const double weights2 = squaredWeightSum(local);
                sums.add(q, e2, noise2 * (1.0 + weights2), scales.boundedFactor(fine2),
                         scales.boundedNoise(fine2, weights2));
            }
        }
    }
    return sums.result();
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

// The error scales over the level-0 lattice points. `scale`: RMS over valid points, normals
// and channels of the irradiance, the brightest 0.1% of points clamped to the 99.9th
// percentile. Unclamped, the RMS of a field with point lights is set by whichever lattice
// point lies closest to a light (1/r^2 irradiance has no finite mean square near one): on the
// closed arena one probe at 9,990 W/m^2 made it 63 W/m^2 against 1.5 for the rest of the
// level, and refinement there stopped seeing any error. The bounded measure's cap and mean
// square follow irradiance_error.hpp, as --verify computes them.
ErrorScales levelZeroScales(const Lattice& lattice, const std::vector<glm::uvec3>& points,
                            sh::Order order) {
    std::vector<double> squares; // per point: mean over normals and channels of E^2
    squares.reserve(points.size());
    for (const glm::uvec3& u : points) {
        if (lattice.valid(u)) {
            squares.push_back(meanSquaredIrradiance(lattice.sh(u), order));
        }
    }
    ErrorScales scales;
    if (squares.empty()) {
        return scales;
    }
    constexpr double kClampQuantile = 0.999;
    std::vector<double> sorted = squares;
    const auto at = sorted.begin() + std::ptrdiff_t(kClampQuantile * double(sorted.size() - 1));
    std::nth_element(sorted.begin(), at, sorted.end());
    const double clamp = *at;
    scales.cap = brightPointCap(squares);
    double sum = 0.0, bounded = 0.0;
    for (double v : squares) {
        sum += std::min(v, clamp);
        bounded += brightPointWeight(v, scales.cap) * v;
    }
    const double rms = std::sqrt(sum / double(squares.size()));
    scales.scale = rms > 0.0 ? float(rms) : 1.0f;
    bounded /= double(squares.size());
    scales.boundedScale2 = bounded > 0.0 ? bounded : double(scales.scale) * scales.scale;
    return scales;
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
        for (size_t li = 0; li < m_scene.lights.size(); ++li) {
            const PunctualLight& light = m_scene.lights[li];
            const std::optional<LightDirection> to_light = directionToLight(light, p);
            if (!to_light || !m_scene.directStored(li) ||
                m_tracer->occluded(p, to_light->direction, to_light->distance)) {
                continue;
            }
            value += sh::projectDelta(to_light->direction, normalIrradianceAt(light, p), m_order);
        }
        return m_cache.emplace(key, value).first->second;
    }

    // RMS disagreement (relative to `scale`) between the brick's interpolation of its own
    // direct light and the direct light at the finer lattice points of its region, in all and
    // per octant.
    // The bounded measure weighs points by their direct light alone (a lower bound of their
    // irradiance): the finer probes are not baked yet.
    Disagreement disagreement(const Brick& b, uint32_t max_level, const ErrorScales& scales) {
        if (m_scene.lights.empty() || m_tracer == nullptr) {
            return {};
        }
        std::vector<sh::ShRgb> own(kBrickProbeCount);
        const auto own_points = regionPoints(b, max_level, 1);
        for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
            own[k] = at(own_points[k]);
        }
        constexpr uint32_t n = kBrickCells * 2 + 1;
        const auto points = regionPoints(b, max_level, 2);
        OctantSums sums;
        for (uint32_t k = 0; k < n * n * n; ++k) {
            const glm::uvec3 q(k % n, (k / n) % n, k / (n * n));
            if ((q.x % 2) + (q.y % 2) + (q.z % 2) == 0) {
                continue;
            }
            const sh::ShRgb& fine = at(points[k]);
            sums.add(
                q,
                squaredDifference(brick::interpolate(own, glm::vec3(q) * 0.5f), fine, m_order) /
                    (double(scales.scale) * scales.scale),
                0.0, scales.boundedFactor(meanSquaredIrradiance(fine, m_order)), 0.0);
        }
        return sums.result();
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
                         sh::Order order, Storage storage, bool visibility) {
    const glm::uvec3 cells = brick::finestCells(top_bricks, max_level);
    return bricks * kBrickProbeCount * planeCount(order) * 4 * bytesPerComponent(storage) +
           uint64_t(cells.x) * cells.y * cells.z * sizeof(uint32_t) +
           (visibility ? bricks * kBrickProbeCount * 8 : 0);
}

namespace {

// The state a bricked bake carries from phase to phase (bakeBricked lists the phases).
struct BrickedBake {
    BrickedBake(const Scene& s, const VolumeDesc& d, sh::Order o, const BrickedSettings& bs,
                const ProbeBatchFn& bake_batch)
        : scene(s), desc(d), order(o), settings(bs), bake(bake_batch), maxLevel(bs.volume.maxLevel),
          top(d.grid.resolution()),
          lattice(d, maxLevel, bake_batch, bs.config.nudge ? bs.tracer : nullptr,
                  bs.config.backfaceThreshold),
          reach(s, d, maxLevel) {}

    const Scene& scene;
    const VolumeDesc& desc;
    sh::Order order;
    const BrickedSettings& settings;
    const ProbeBatchFn& bake;
    uint32_t maxLevel;
    glm::uvec3 top;
    Lattice lattice;
    GeometryReach reach;
    std::vector<Node> nodes; // level 0 first, then each level's finer bricks as they are kept
    ErrorScales scales;      // the error scales (levelZeroScales)
    double noise2 = 0.0;     // one probe's relative noise variance (measureNoise)
    BrickedOutcome out;
};

// The progress's outlook (BrickedSettings::expectFurther) for a batch after which
// `levels_after` levels are still to be tested: each is expected to bake as many probes as the
// batch. Passed to Lattice::ensure.
std::function<void(size_t)> expectLevelsAfter(const BrickedBake& b, uint32_t levels_after) {
    return [&b, levels_after](size_t batch) {
        if (b.settings.expectFurther) {
            b.settings.expectFurther(uint64_t(batch) * levels_after);
        }
    };
}

// Invalid probes take dilated values as soon as they are baked: the refinement test then
// sees what the runtime will interpolate.
void dilateBaked(BrickedBake& b) {
    if (!b.settings.config.dilate) {
        return;
    }
    std::vector<uint64_t> invalid;
    for (const auto& [key, index] : b.lattice.indexMap()) {
        if (b.lattice.allValid()[index] != kProbeValid) {
            invalid.push_back(key);
        }
    }
    std::sort(invalid.begin(), invalid.end());
    dilateLattice(b.lattice, invalid, 1u << b.maxLevel);
}

// Level 0: every brick, baked in one batch, and the error scale from its probes. Returns the
// level-0 lattice points (shared ones once per brick).
std::vector<glm::uvec3> bakeLevelZero(BrickedBake& b) {
    for (const Brick& brick : brick::uniformLayout(b.top, 0).bricks) {
        b.nodes.push_back(Node{brick});
    }
    std::vector<glm::uvec3> wanted;
    for (const Node& n : b.nodes) {
        const auto pts = regionPoints(n.brick, b.maxLevel, 1);
        wanted.insert(wanted.end(), pts.begin(), pts.end());
    }
    b.lattice.ensure(wanted, expectLevelsAfter(b, b.maxLevel));
    dilateBaked(b);
    b.scales = levelZeroScales(b.lattice, wanted, b.order);
    return wanted;
}

// Monte Carlo noise: a second, independent bake of up to kNoiseProbes valid level-0 probes
// (ids with the top bit set seed other sample sequences). Half the mean squared difference
// of the two estimates is one estimate's noise variance.
void measureNoise(BrickedBake& b, const std::vector<glm::uvec3>& level_zero) {
    const Lattice& lattice = b.lattice;
    constexpr size_t kNoiseProbes = 64;
    std::vector<glm::uvec3> valid_points; // baked where they are (not nudged)
    for (const glm::uvec3& u : level_zero) {
        if (lattice.valid(u) && !lattice.nudged(lattice.key(u))) {
            valid_points.push_back(u);
        }
    }
    std::sort(valid_points.begin(), valid_points.end(),
              [&](glm::uvec3 x, glm::uvec3 y) { return lattice.key(x) < lattice.key(y); });
    valid_points.erase(std::unique(valid_points.begin(), valid_points.end()), valid_points.end());
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
    b.bake(positions, ids, again, again_valid);
    double sum = 0.0, relative = 0.0;
    const double floor2 = double(b.scales.scale) * b.scales.scale;
    for (size_t i = 0; i < picked.size(); ++i) {
        const double d2 = squaredDifference(again[i], lattice.sh(picked[i]), b.order);
        sum += d2;
        relative += d2 / std::max(meanSquaredIrradiance(lattice.sh(picked[i]), b.order), floor2);
    }
    b.scales.relNoise2 = picked.empty() ? 0.0 : 0.5 * relative / double(picked.size());
    b.noise2 = picked.empty()
                   ? 0.0
                   : 0.5 * sum / double(picked.size()) / (double(b.scales.scale) * b.scales.scale);
}

// A brick's own prediction: how far its probes stray from its 8 corners' interpolation (noise
// taken out), scaled by (1/3)^2 for its own 3x finer spacing in smooth light, 1/3 near
// surfaces. Sets `predicted` and `predictedBounded`.
void predictFromCorners(const BrickedBake& b, Node& n) {
    const Lattice& lattice = b.lattice;
    const auto pts = regionPoints(n.brick, b.maxLevel, 1);
    std::vector<sh::ShRgb> corner_brick(kBrickProbeCount);
    for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
        // A brick whose probes are its corners' values spread over 0..3: interpolating it at
        // local / 3 is the corner lattice's interpolation.
        const glm::uvec3 l(k % 4, (k / 4) % 4, k / 16);
        const glm::uvec3 c = glm::min(l, glm::uvec3(1)) * 3u;
        corner_brick[k] = lattice.sh(pts[c.x + 4 * (c.y + 4 * c.z)]);
    }
    ErrorSum sum, bounded;
    for (uint32_t k = 0; k < kBrickProbeCount; ++k) {
        const glm::uvec3 l(k % 4, (k / 4) % 4, k / 16);
        if (!lattice.valid(pts[k]) || glm::all(glm::equal(l % 3u, glm::uvec3(0)))) {
            continue;
        }
        const glm::vec3 t = glm::vec3(l) / 3.0f; // position in the corner lattice
        const sh::ShRgb& fine = lattice.sh(pts[k]);
        const double e2 = squaredDifference(brick::interpolate(corner_brick, t), fine, b.order) /
                          (double(b.scales.scale) * b.scales.scale);
        const double weights2 = squaredWeightSum(t);
        sum.add(e2, b.noise2 * (1.0 + weights2));
        const double fine2 = meanSquaredIrradiance(fine, b.order);
        bounded.add(e2 * b.scales.boundedFactor(fine2), b.scales.boundedNoise(fine2, weights2));
    }
    const float spacing = b.reach.near(n.brick) ? 3.0f : 9.0f;
    n.predicted = sum.rms() / spacing;
    n.predictedBounded = bounded.rms() / spacing;
}

// Level 0's prediction, before any brick is tested.
void predictLevelZero(BrickedBake& b) {
    for (Node& n : b.nodes) {
        predictFromCorners(b, n);
    }
}

// After refinement every stored brick's probes are baked: an untested one (the deepest level,
// or below the threshold) is predicted from its own probes rather than from its parent's
// disagreement over the decay, which assumes the error keeps falling at the rate of smooth
// light or of contact shading (near the Cornell box's ceiling light the level-3 bricks measure
// a small part of what their parents' disagreement over 2 predicted).
void predictUntestedFromCorners(BrickedBake& b, const std::vector<int>& stored) {
    for (int i : stored) {
        Node& n = b.nodes[size_t(i)];
        if (!n.tested && n.brick.level > 0) {
            predictFromCorners(b, n);
        }
    }
}

// The bricks of one level worth testing, with their direct-light disagreement.
struct Candidates {
    std::vector<int> nodes;
    std::vector<Disagreement> direct;
};

// Picks the frontier's bricks whose prediction (or direct-light disagreement) exceeds
// `threshold` and that have a probe outside geometry, and bakes their finer probes, after
// which `levels_after` levels are still to be tested (the progress's outlook). When their
// probes would not fit in the working memory, the bricks with the largest disagreement are
// kept and the rest go untested (counted in memoryUntested).
Candidates chooseCandidates(BrickedBake& b, DirectField& direct, const std::vector<int>& frontier,
                            float threshold, uint32_t levels_after) {
    struct Eligible {
        int node;
        float priority;
        Disagreement direct;
    };
    std::vector<Eligible> eligible;
    for (int i : frontier) {
        Node& n = b.nodes[size_t(i)];
        if (insideGeometry(b.lattice, n.brick, b.maxLevel)) {
            continue; // inside geometry: never spent on
        }
        const Disagreement from_direct = direct.disagreement(n.brick, b.maxLevel, b.scales);
        const float most_direct =
            *std::max_element(std::begin(from_direct.octant), std::end(from_direct.octant));
        const float priority = std::max(n.predicted, most_direct);
        if (priority <= threshold) {
            continue;
        }
        eligible.push_back({i, priority, from_direct});
    }
    // Every candidate adds at most this many probes (neighbours share some).
    const uint64_t side = 2 * kBrickCells + 1;
    const uint64_t per_brick = side * side * side;
    const uint64_t room = b.settings.workingBytes / kBakedProbeBytes;
    const uint64_t held = b.lattice.size();
    const uint64_t fit = room > held ? (room - held) / per_brick : 0;
    if (eligible.size() > fit) {
        std::stable_sort(
            eligible.begin(), eligible.end(),
            [](const Eligible& x, const Eligible& y) { return x.priority > y.priority; });
        b.out.memoryUntested += eligible.size() - fit;
        eligible.resize(size_t(fit));
        std::sort(eligible.begin(), eligible.end(),
                  [](const Eligible& x, const Eligible& y) { return x.node < y.node; });
    }
    Candidates out;
    std::vector<glm::uvec3> wanted;
    for (const Eligible& e : eligible) {
        out.nodes.push_back(e.node);
        out.direct.push_back(e.direct);
        const auto finer = regionPoints(b.nodes[size_t(e.node)].brick, b.maxLevel, 2);
        wanted.insert(wanted.end(), finer.begin(), finer.end());
    }
    b.lattice.ensure(wanted, expectLevelsAfter(b, levels_after));
    dilateBaked(b);
    return out;
}

// Measures each candidate's disagreement per octant and adds the finer brick of every octant
// where it exceeds `threshold` (on level `level + 1`). Returns the added bricks.
std::vector<int> keepFinerBricks(BrickedBake& b, const Candidates& candidates, uint32_t level,
                                 float threshold) {
    std::vector<Node>& nodes = b.nodes;
    std::vector<int> next;
    for (size_t c = 0; c < candidates.nodes.size(); ++c) {
        const int i = candidates.nodes[c];
        const Disagreement d =
            measure(b.lattice, nodes[size_t(i)].brick, b.maxLevel, b.order, b.scales, b.noise2);
        // The full bake's disagreement decides; the exact direct-light one is a floor
        // under it (noise subtraction can only hide an edge the pre-pass sees exactly).
        Node& n = nodes[size_t(i)];
        n.tested = true;
        for (int o = 0; o < 8; ++o) {
            n.octant[o] = std::max(d.octant[o], candidates.direct[c].octant[o]);
            n.octantBounded[o] = std::max(d.bounded[o], candidates.direct[c].bounded[o]);
        }
        // Error falls with the square of the spacing in smooth light, but near surfaces
        // (contact shading, occlusion) only about linearly.
        const float decay = b.reach.near(n.brick) ? 2.0f : 4.0f;
        const Brick parent = n.brick;
        for (uint32_t o = 0; o < 8; ++o) {
            if (nodes[size_t(i)].octant[o] <= threshold) {
                continue; // the parent's interpolation is good enough there
            }
            Node child;
            child.brick.level = uint8_t(level + 1);
            child.brick.coord = parent.coord * 2u + glm::uvec3(o & 1, (o >> 1) & 1, o >> 2);
            if (!b.settings.storeSolidBricks &&
                insideGeometry(b.lattice, child.brick, b.maxLevel)) {
                continue; // a free-space brick: only dilated values, the parent shows there
            }
            child.parent = i;
            child.gain = nodes[size_t(i)].octant[o];
            child.predicted = child.gain / decay;
            nodes[size_t(i)].children[o] = int(nodes.size());
            next.push_back(int(nodes.size()));
            nodes.push_back(child);
        }
    }
    return next;
}

// Refinement, one level at a time from every level-0 brick (the rule is in bricked.hpp).
void refine(BrickedBake& b) {
    std::vector<int> frontier(b.nodes.size());
    for (size_t i = 0; i < b.nodes.size(); ++i) {
        frontier[i] = int(i);
    }
    // The cheap pre-pass: direct light from punctual lights (one shadow ray per light, exact,
    // no noise) on the finer lattice; its disagreement finds shadow edges, also in open air.
    DirectField direct(b.scene, b.settings.tracer, b.lattice, b.order);
    for (uint32_t level = 0; level < b.maxLevel; ++level) {
        // Every stored brick costs the same bytes; a finer brick removes about its volume
        // (1/8 per level) times the squared disagreement in its octant from the volume's
        // squared error. It is kept where that exceeds a fixed price per brick, which means
        // where its octant's disagreement exceeds refine_error x sqrt(8)^level.
        const float threshold = b.settings.volume.refineError * std::pow(8.0f, 0.5f * float(level));
        const Candidates candidates =
            chooseCandidates(b, direct, frontier, threshold, b.maxLevel - level - 1);
        b.out.refineCandidates += candidates.nodes.size();
        frontier = keepFinerBricks(b, candidates, level, threshold);
    }
    if (b.settings.expectFurther) {
        b.settings.expectFurther(0);
    }
}

// Stored bricks counted per level, so the bytes (which depend on the deepest level in use)
// cost nothing to recompute after each removal.
struct StoredCounts {
    uint64_t at[brick::kMaxLevel + 1] = {};

    uint32_t deepest(uint32_t max_level) const {
        uint32_t d = max_level;
        while (d > 0 && at[d] == 0) {
            --d;
        }
        return d;
    }
};

uint64_t storedBytes(const BrickedBake& b, const StoredCounts& counts) {
    const uint64_t stored = counts.at[0] + counts.at[1] + counts.at[2] + counts.at[3];
    return brickedGpuBytes(b.top, counts.deepest(b.maxLevel), stored, b.order, b.desc.storage,
                           b.settings.config.visibility);
}

// Drops the finer bricks whose removal costs the least error (volume times squared gain)
// until the bytes fit or none is left to drop; a brick goes only after its own finer bricks.
void dropCheapest(BrickedBake& b, StoredCounts& counts) {
    std::vector<Node>& nodes = b.nodes;
    using Entry = std::pair<double, int>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
    auto removable = [&](int i) {
        const Node& n = nodes[size_t(i)];
        return n.brick.level > 0 && !n.removed &&
               std::all_of(std::begin(n.children), std::end(n.children),
                           [&](int c) { return c < 0 || nodes[size_t(c)].removed; });
    };
    auto cost = [&](int i) {
        const Node& n = nodes[size_t(i)];
        return std::ldexp(double(n.gain) * n.gain, -3 * int(n.brick.level));
    };
    for (size_t i = 0; i < nodes.size(); ++i) {
        if (removable(int(i))) {
            heap.emplace(cost(int(i)), int(i));
        }
    }
    while (storedBytes(b, counts) > b.settings.config.maxMemoryBytes && !heap.empty()) {
        const int i = heap.top().second;
        heap.pop();
        Node& n = nodes[size_t(i)];
        n.removed = true;
        --counts.at[n.brick.level];
        ++b.out.budgetDropped;
        b.out.budgetError = std::max(b.out.budgetError, double(n.gain));
        if (removable(n.parent)) {
            heap.emplace(cost(n.parent), n.parent);
        }
    }
}

// The budget: drops finer bricks until the GPU bytes fit. Returns the deepest level still in
// use, or an error when level 0 alone does not fit.
Result<uint32_t> applyBudget(BrickedBake& b) {
    StoredCounts counts;
    for (const Node& n : b.nodes) {
        ++counts.at[n.brick.level];
    }
    if (storedBytes(b, counts) > b.settings.config.maxMemoryBytes) {
        dropCheapest(b, counts);
        const uint64_t bytes = storedBytes(b, counts);
        if (bytes > b.settings.config.maxMemoryBytes) {
            return makeError(ErrorCode::OutOfRange,
                             "volume '" + b.desc.name + "': level 0 alone needs " +
                                 std::to_string((bytes + (1 << 20) - 1) >> 20) +
                                 " MiB, more than max_memory_mb = " +
                                 std::to_string(b.settings.config.maxMemoryBytes >> 20) +
                                 " (fewer level-0 bricks: lower the density or resolution)");
        }
    }
    return counts.deepest(b.maxLevel);
}

// The stored bricks, coarse first, then z, y, x.
std::vector<int> storedBricks(const std::vector<Node>& nodes) {
    std::vector<int> stored;
    for (size_t i = 0; i < nodes.size(); ++i) {
        if (!nodes[i].removed) {
            stored.push_back(int(i));
        }
    }
    std::sort(stored.begin(), stored.end(), [&](int a, int b) {
        const Brick& x = nodes[size_t(a)].brick;
        const Brick& y = nodes[size_t(b)].brick;
        return std::tuple(x.level, x.coord.z, x.coord.y, x.coord.x) <
               std::tuple(y.level, y.coord.z, y.coord.y, y.coord.x);
    });
    return stored;
}

// Predicted interpolation error in the bounded measure (--verify's), over the part of each
// stored brick that shows: where it was tested, each octant without a finer brick at its
// measured disagreement; otherwise the whole brick at its prediction. Weights are volumes
// times the brick's share of valid probes (error is only ever measured in open space).
double predictedError(const BrickedBake& b, const std::vector<int>& stored) {
    const std::vector<Node>& nodes = b.nodes;
    double sum_w = 0.0, sum_e2 = 0.0;
    for (int i : stored) {
        const Node& n = nodes[size_t(i)];
        const auto own = regionPoints(n.brick, b.maxLevel, 1);
        const double valid_share =
            double(std::count_if(own.begin(), own.end(),
                                 [&](const glm::uvec3& u) { return b.lattice.valid(u); })) /
            double(kBrickProbeCount);
        const double w = std::ldexp(valid_share, -3 * int(n.brick.level));
        if (!n.tested) {
            sum_w += w;
            sum_e2 += w * double(n.predictedBounded) * n.predictedBounded;
            continue;
        }
        for (int o = 0; o < 8; ++o) {
            if (n.children[o] < 0 || nodes[size_t(n.children[o])].removed) {
                sum_w += w / 8.0;
                sum_e2 += w / 8.0 * double(n.octantBounded[o]) * n.octantBounded[o];
            }
        }
    }
    return sum_w > 0.0 ? std::sqrt(sum_e2 / sum_w) : 0.0;
}

// Re-expresses every stored brick on the lattice of the deepest level actually used. Returns
// the lattice keys of the bricks' probes, brick by brick.
std::vector<uint64_t> layOutBricks(BrickedBake& b, const std::vector<int>& stored,
                                   uint32_t used_level) {
    b.out.desc = b.desc;
    b.out.desc.layout = VolumeLayout::Bricked;
    b.out.desc.bricks.maxLevel = used_level;
    std::vector<uint64_t> used_keys;
    for (int i : stored) {
        const Brick& brick = b.nodes[size_t(i)].brick;
        b.out.desc.bricks.bricks.push_back(brick);
        ++b.out.bricksPerLevel[brick.level];
        b.out.solidBricksPerLevel[brick.level] += insideGeometry(b.lattice, brick, b.maxLevel);
        for (const glm::uvec3& u : regionPoints(brick, b.maxLevel, 1)) {
            used_keys.push_back(b.lattice.key(u));
        }
    }
    return used_keys;
}

// Fills the used probes still invalid from the nearest valid ones on the lattice.
void dilateUsed(BrickedBake& b, const std::vector<uint64_t>& used_keys) {
    std::vector<uint64_t> unique = used_keys;
    std::sort(unique.begin(), unique.end());
    unique.erase(std::unique(unique.begin(), unique.end()), unique.end());
    const uint64_t unreachable = dilateLattice(b.lattice, unique, 1u << b.maxLevel);
    if (unreachable > 0) {
        b.out.warnings.push_back("volume '" + b.desc.name + "': " + std::to_string(unreachable) +
                                 " invalid probes have no valid probe to dilate from");
    }
}

// Copies the used probes out: values after dilation, validity from before it.
void copyProbes(BrickedBake& b, const std::vector<uint64_t>& used_keys,
                const std::vector<uint8_t>& original_valid) {
    b.out.probes.reserve(used_keys.size());
    b.out.validity.reserve(used_keys.size());
    for (uint64_t k : used_keys) {
        const uint32_t index = b.lattice.indexMap().at(k);
        b.out.probes.push_back(b.lattice.allSh()[index]);
        b.out.validity.push_back(original_valid[index]);
        b.out.invalidProbes += original_valid[index] == kProbeInvalid;
        b.out.nudgedProbes += b.lattice.nudged(k);
    }
}

// Traces the visibility (when asked for) and stitches the bricks' borders through the
// indirection.
Result<void> stitch(BrickedBake& b) {
    Result<std::vector<uint32_t>> indirection =
        brick::buildIndirection(b.top, b.out.desc.bricks, "volume '" + b.desc.name + "'");
    if (!indirection) {
        return indirection.error();
    }
    if (b.settings.config.visibility && b.settings.tracer != nullptr) {
        b.out.visibility = traceVolumeVisibility(*b.settings.tracer, b.out.desc, b.out.validity,
                                                 b.settings.threads);
    }
    brick::stitchBorders(b.top, b.out.desc.bricks, indirection.value(), b.out.probes,
                         b.out.visibility);
    return {};
}

} // namespace

Result<BrickedOutcome> bakeBricked(const Scene& scene, const VolumeDesc& desc, sh::Order order,
                                   const BrickedSettings& settings,
                                   const ProbeBatchFn& bake_batch) {
    BrickedBake b(scene, desc, order, settings, bake_batch);
    const std::vector<glm::uvec3> level_zero = bakeLevelZero(b);
    measureNoise(b, level_zero);
    predictLevelZero(b);
    refine(b);
    if (b.out.memoryUntested > 0) {
        b.out.warnings.push_back(
            "volume '" + desc.name + "': " + std::to_string(b.out.memoryUntested) +
            " candidate bricks were not refined: their probes would not fit in the " +
            std::to_string(settings.workingBytes >> 20) +
            " MiB max_memory_mb leaves the refinement (about " + std::to_string(kBakedProbeBytes) +
            " bytes per baked probe); the bricks that disagreed most were refined first");
    }
    const Result<uint32_t> used_level = applyBudget(b);
    if (!used_level) {
        return used_level.error();
    }
    const std::vector<int> stored = storedBricks(b.nodes);
    predictUntestedFromCorners(b, stored);
    b.out.predictedError = predictedError(b, stored);
    const std::vector<uint64_t> used_keys = layOutBricks(b, stored, used_level.value());
    const std::vector<uint8_t> original_valid = b.lattice.allValid();
    if (settings.config.dilate) {
        dilateUsed(b, used_keys);
    }
    copyProbes(b, used_keys, original_valid);
    if (settings.config.dering) {
        b.out.deringChanges.assign(b.out.probes.size(), kNotDeringed);
        deringProbes(b.out.probes, order, desc.storage, settings.threads, b.out.deringChanges);
    }
    const Result<void> stitched = stitch(b);
    if (!stitched) {
        return stitched.error();
    }
    return std::move(b.out);
}

} // namespace probekit::baker
