// The bake: volume placement, the probe loop on the baker's parallel loop (parallel.hpp),
// validity and dilation.
#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <optional>
#include <span>

#include <sys/resource.h>

#include <glm/gtc/matrix_access.hpp>
#include <glm/gtc/quaternion.hpp>

#include "memory_model.hpp"
#include "methods/lpv_method.hpp"
#include "methods/path_integrator.hpp"
#include "methods/vpl_gather.hpp"
#include "methods/vpl_integrator.hpp"
#include "methods/vpl_paths.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/scene_summary.hpp"
#include "probekit/baker/settings.hpp"
#include "scene/coordinate_range.hpp"
#include "scene/light_modes.hpp"
#include "trace/parallel.hpp"
#include "trace/ray_tracer.hpp"
#include "volume/bricked.hpp"
#include "volume/dering.hpp"
#include "volume/visibility.hpp"

namespace probekit::baker {

std::vector<VolumeConfig> volumeConfigs(const BakeConfig& config) {
    std::vector<VolumeConfig> configs = config.volumes;
    if (configs.empty()) {
        configs.push_back(VolumeConfig{});
    }
    return configs;
}

namespace {

std::string volumeLabel(size_t index, const VolumeConfig& v) {
    return "volumes[" + std::to_string(index) + "] ('" + v.name + "')";
}

// Finds a node by name, or by its glTF index written in decimal.
const SceneNode* findNode(const Scene& scene, const std::string& key) {
    for (const SceneNode& n : scene.nodes) {
        if (n.name == key) {
            return &n;
        }
    }
    if (!key.empty() && std::all_of(key.begin(), key.end(), ::isdigit)) {
        const int index = std::stoi(key);
        for (const SceneNode& n : scene.nodes) {
            if (n.gltfIndex == index) {
                return &n;
            }
        }
    }
    return nullptr;
}

grid::Aabb unionOf(const grid::Aabb& a, const grid::Aabb& b) {
    return grid::Aabb{glm::min(a.min, b.min), glm::max(a.max, b.max)};
}

uint32_t roundToPowerOfTwo(float probes) {
    // Nearest power of two in the log sense: 2^round(log2(n)), at least 1.
    if (!(probes > 1.0f)) {
        return 1;
    }
    return 1u << uint32_t(std::lround(std::log2(probes)));
}

// Splits a node's world matrix into a rigid frame and a per-axis scale.
void decompose(const glm::mat4& m, grid::RigidFrame& frame, glm::vec3& scale) {
    glm::mat3 r(m);
    for (int c = 0; c < 3; ++c) {
        scale[c] = glm::length(r[c]);
        r[c] = scale[c] > 0.0f ? r[c] / scale[c] : glm::vec3(0.0f);
    }
    if (glm::determinant(r) < 0.0f) {
        // A mirrored node: fold the reflection into the x scale so the frame stays rotation.
        scale.x = -scale.x;
        r[0] = -r[0];
    }
    frame.rotation = glm::normalize(glm::quat_cast(r));
    frame.translation = glm::vec3(m[3]);
}

// 3x3x3 neighbourhood average of valid probes, repeated until every reachable probe is
// filled. Newly filled probes count as sources only in the next pass, so the result does not
// depend on visiting order.
uint64_t dilate(const grid::GridLayout& g, std::vector<sh::ShRgb>& probes,
                std::vector<uint8_t> filled) {
    const glm::ivec3 res(g.resolution());
    uint64_t unreachable = 0;
    for (;;) {
        std::vector<std::pair<size_t, sh::ShRgb>> updates;
        bool any_missing = false;
        for (size_t i = 0; i < probes.size(); ++i) {
            if (filled[i]) {
                continue;
            }
            any_missing = true;
            const glm::ivec3 c(g.probeCoords(i));
            sh::ShRgb sum;
            int count = 0;
            for (int dz = -1; dz <= 1; ++dz) {
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        const glm::ivec3 n = c + glm::ivec3(dx, dy, dz);
                        if (glm::any(glm::lessThan(n, glm::ivec3(0))) ||
                            glm::any(glm::greaterThanEqual(n, res))) {
                            continue;
                        }
                        const size_t j = g.linearIndex(glm::uvec3(n));
                        if (filled[j]) {
                            sum += probes[j];
                            ++count;
                        }
                    }
                }
            }
            if (count > 0) {
                sum *= 1.0f / float(count);
                updates.emplace_back(i, sum);
            }
        }
        if (!any_missing) {
            break;
        }
        if (updates.empty()) {
            unreachable = uint64_t(std::count(filled.begin(), filled.end(), 0));
            break;
        }
        for (auto& [i, sh_value] : updates) {
            probes[i] = sh_value;
            filled[i] = 1;
        }
    }
    return unreachable;
}

uint64_t peakResidentBytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return uint64_t(usage.ru_maxrss) * 1024; // Linux reports kilobytes
}

} // namespace

float automaticDensity(const grid::Aabb& box, VolumeLayout layout) {
    const glm::vec3 extent = box.size();
    const float longest = std::max({extent.x, extent.y, extent.z});
    const float base = layout == VolumeLayout::Bricked ? kBrickedDensity : kDefaultDensity;
    return std::max(base, longest > 0.0f ? kMinAutoProbes / longest : 0.0f);
}

glm::vec3 probeSpacing(const VolumeDesc& desc) {
    if (desc.layout == VolumeLayout::Bricked) {
        const glm::uvec3 cells = brick::finestCells(desc.grid.resolution(), desc.bricks.maxLevel);
        return desc.grid.bounds().size() / glm::vec3(cells * brick::kBrickCells);
    }
    return desc.grid.spacing();
}

namespace {

struct PlacedBox {
    grid::Aabb box;
    grid::RigidFrame frame;
};

// The volume's box before padding: custom, the scene's or the listed nodes' world bounds, or
// one node's local bounds in its own (rigid) frame.
Result<PlacedBox> unpaddedBox(const Scene& scene, const VolumeConfig& v, const std::string& label) {
    PlacedBox placed;
    switch (v.bounds.mode) {
    case BoundsMode::Custom:
        placed.box = grid::Aabb{v.bounds.min, v.bounds.max};
        return placed;
    case BoundsMode::AutoWorld:
        if (v.bounds.nodes.empty()) {
            if (!scene.hasGeometry()) {
                return makeError(ErrorCode::InvalidArgument,
                                 label + ".bounds: the scene has no geometry, so automatic "
                                         "bounds are empty; give custom bounds");
            }
            placed.box = scene.bounds;
            return placed;
        } else {
            bool first = true;
            for (const std::string& key : v.bounds.nodes) {
                const SceneNode* node = findNode(scene, key);
                if (!node) {
                    return makeError(ErrorCode::InvalidArgument,
                                     label + ".bounds.nodes: no node named '" + key + "'");
                }
                if (!node->hasMesh) {
                    continue;
                }
                placed.box = first ? node->worldBounds : unionOf(placed.box, node->worldBounds);
                first = false;
            }
            if (first) {
                return makeError(ErrorCode::InvalidArgument,
                                 label + ".bounds.nodes: none of the listed nodes has a mesh");
            }
            return placed;
        }
    case BoundsMode::AutoLocal: {
        const SceneNode* node = findNode(scene, v.bounds.node);
        if (!node) {
            return makeError(ErrorCode::InvalidArgument,
                             label + ".bounds.node: no node named '" + v.bounds.node + "'");
        }
        if (!node->hasMesh) {
            return makeError(ErrorCode::InvalidArgument, label + ".bounds.node: node '" +
                                                             v.bounds.node +
                                                             "' has no mesh to take bounds from");
        }
        glm::vec3 scale;
        decompose(node->world, placed.frame, scale);
        // The frame is rigid, so the node's scale is folded into the local box.
        const glm::vec3 a = node->localBounds.min * scale;
        const glm::vec3 b = node->localBounds.max * scale;
        placed.box = grid::Aabb{glm::min(a, b), glm::max(a, b)};
        return placed;
    }
    }
    return placed;
}

// What the automatic padding rule (config.hpp, kAutoPadding*) saw of a lattice of test points
// in the box: those inside geometry by the bake's validity rule, and those outside geometry
// that see front faces in at least kAutoPaddingEnclosedHits of their directions (the open space
// of a room or a sealed level; outside a closed object a point sees at most about half).
struct PaddingTest {
    uint32_t points = 0;
    uint32_t inside = 0;
    uint32_t enclosed = 0;
    float insideShare() const { return float(inside) / float(points); }
    // A level seen from its solid void: at least a quarter of the open points are enclosed.
    bool sealedLevel() const { return enclosed > 0 && 4 * enclosed >= points - inside; }
};

PaddingTest paddingTest(const RayTracer& tracer, const PlacedBox& placed,
                        float backface_threshold) {
    const uint32_t n = kAutoPaddingLattice;
    const glm::vec3 size = placed.box.size();
    PaddingTest test;
    test.points = n * n * n;
    for (uint32_t i = 0; i < n * n * n; ++i) {
        const glm::vec3 cell(float(i % n), float(i / n % n), float(i / (n * n)));
        const glm::vec3 local = placed.box.min + (cell + 0.5f) / float(n) * size;
        const glm::vec3 origin = placed.frame.toWorld(local);
        uint32_t back = 0;
        uint32_t front = 0;
        for (uint32_t r = 0; r < kAutoPaddingRays; ++r) {
            // Fibonacci sphere: evenly spread, deterministic directions.
            const float z = 1.0f - (2.0f * float(r) + 1.0f) / float(kAutoPaddingRays);
            const float phi = float(r) * 2.39996323f;
            const float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
            const std::optional<Hit> hit =
                tracer.intersect(origin, glm::vec3(s * std::cos(phi), s * std::sin(phi), z));
            back += hit && hit->backFace;
            front += hit && !hit->backFace;
        }
        if (float(back) / float(kAutoPaddingRays) > backface_threshold) {
            ++test.inside;
        } else if (float(front) >= kAutoPaddingEnclosedHits * float(kAutoPaddingRays)) {
            ++test.enclosed;
        }
    }
    return test;
}

// The note for an automatic resolution that a cap changed: what was asked, what is used.
std::string resolutionNote(const std::string& label, float density, glm::vec3 size,
                           glm::uvec3 asked, glm::uvec3 res, bool bricked, const char* cap) {
    const glm::vec3 spacing = size / glm::vec3(bricked ? res * brick::kBrickCells : res);
    char text[512];
    std::snprintf(text, sizeof text,
                  "%s: %g probes/m over %.4g x %.4g x %.4g m asks %u x %u x %u %s; %s gives "
                  "%u x %u x %u (probe spacing %.3g x %.3g x %.3g m); raise it, use layout "
                  "bricked, or check the scene's units (--scale)",
                  label.c_str(), double(density), size.x, size.y, size.z, asked.x, asked.y, asked.z,
                  bricked ? "level-0 bricks" : "probes", cap, res.x, res.y, res.z, spacing.x,
                  spacing.y, spacing.z);
    return text;
}

// Per axis, `size` x `density` / `per_cell` rounded to a power of two, at most 2^30: the
// probes (per_cell 1) or bricks (per_cell kBrickCells) a density asks for before any cap.
glm::uvec3 powerOfTwoCounts(const glm::vec3& size, float density, float per_cell) {
    glm::uvec3 counts;
    for (int a = 0; a < 3; ++a) {
        const float n = size[a] * density / per_cell;
        counts[a] = n >= float(1u << 30) ? (1u << 30) : roundToPowerOfTwo(n);
    }
    return counts;
}

// The probe budget of an automatic resolution: max_probes, or its default for the layout.
uint32_t maxProbesOf(const VolumeConfig& v) {
    return v.maxProbes.value_or(v.layout == VolumeLayout::Bricked ? kDefaultMaxBrickedProbes
                                                                  : kDefaultMaxProbes);
}

// Probes (or bricks) per axis of an automatic resolution: size x density rounded to powers of
// two, each axis capped by max_resolution, then the finest axis halved until the grid holds at
// most max_probes probes; a note when either cap changed it.
glm::uvec3 automaticResolution(const VolumeConfig& v, const grid::Aabb& box, float density,
                               const std::string& label, std::vector<std::string>& notes) {
    const bool bricked = v.layout == VolumeLayout::Bricked;
    const glm::vec3 size = box.size();
    const uint32_t floor = v.position == grid::PositionMode::Corner ? 2u : 1u;
    // Bricked: level-0 bricks, each spanning 3 probe spacings.
    const glm::uvec3 asked =
        powerOfTwoCounts(size, density, bricked ? float(brick::kBrickCells) : 1.0f);
    glm::uvec3 res;
    for (int a = 0; a < 3; ++a) {
        res[a] = std::max(std::min(asked[a], v.maxResolution), floor);
    }
    if (glm::any(glm::greaterThan(asked, glm::uvec3(v.maxResolution)))) {
        notes.push_back(resolutionNote(
            label, density, size, asked, res, bricked,
            ("max_resolution " + std::to_string(v.maxResolution) + " (--max-resolution)").c_str()));
    }
    const uint64_t per_cell =
        bricked ? uint64_t(brick::kBrickCells) * brick::kBrickCells * brick::kBrickCells : 1u;
    const glm::uvec3 capped = res;
    while (uint64_t(res.x) * res.y * res.z * per_cell > maxProbesOf(v)) {
        int finest = -1;
        for (int a = 0; a < 3; ++a) {
            if (res[a] > floor &&
                (finest < 0 || size[a] / float(res[a]) < size[finest] / float(res[finest]))) {
                finest = a;
            }
        }
        if (finest < 0) {
            break; // every axis at its floor: max_probes >= 8 holds a corner grid
        }
        res[finest] /= 2;
    }
    if (res != capped) {
        notes.push_back(resolutionNote(label, density, size, asked, res, bricked,
                                       ("the budget of " + std::to_string(maxProbesOf(v)) +
                                        " probes (max_probes, --max-probes)")
                                           .c_str()));
    }
    return res;
}

} // namespace

namespace {

// A tracer built on first use: only volumes with automatic padding need one, and it is the
// planning's first big allocation, so the bake's memory model (without volumes) must allow it.
class LazyTracer {
public:
    LazyTracer(const Scene& scene, const BakeConfig& config) : m_scene(scene), m_config(config) {}

    Result<const RayTracer*> get() {
        if (!m_tracer) {
            if (Result<void> fits = checkBakeMemory(
                    predictBakeMemory({m_scene, m_config, {}, 0, 1, processBytes(m_scene)}),
                    m_config);
                !fits) {
                return fits.error();
            }
            Result<std::unique_ptr<RayTracer>> made = RayTracer::create(m_scene);
            if (!made) {
                return made.error();
            }
            m_tracer = std::move(made).value();
        }
        return m_tracer.get();
    }

private:
    const Scene& m_scene;
    const BakeConfig& m_config;
    std::unique_ptr<RayTracer> m_tracer;
};

// The padding of volume `v` in metres: bounds.padding when set; otherwise 0, or for automatic
// bounds that hug a closed object kAutoPaddingGrowth x the box's longest side (with a note).
Result<float> volumePadding(const Scene& scene, const BakeConfig& config, const VolumeConfig& v,
                            const PlacedBox& placed, const std::string& label, LazyTracer& tracer,
                            std::vector<std::string>& notes) {
    if (v.bounds.padding || v.bounds.mode == BoundsMode::Custom || !scene.hasGeometry()) {
        return v.bounds.padding.value_or(0.0f);
    }
    Result<const RayTracer*> traced = tracer.get();
    if (!traced) {
        return traced.error();
    }
    const PaddingTest test = paddingTest(*traced.value(), placed, config.backfaceThreshold);
    const float share = test.insideShare();
    if (share <= kAutoPaddingInsideShare) {
        return 0.0f;
    }
    if (test.sealedLevel()) {
        char text[320];
        std::snprintf(text, sizeof text,
                      "%s: %.0f%% of the test points in the scene's box lie inside geometry, "
                      "but %u of the %u outside it see walls in %.0f%%+ of directions: a level "
                      "seen from its solid space, not a closed object, so no padding",
                      label.c_str(), 100.0 * share, test.enclosed, test.points - test.inside,
                      100.0 * kAutoPaddingEnclosedHits);
        notes.emplace_back(text);
        return 0.0f;
    }
    const glm::vec3 size = placed.box.size();
    const float padding = kAutoPaddingGrowth * std::max({size.x, size.y, size.z});
    char text[320];
    std::snprintf(text, sizeof text,
                  "%s: %.0f%% of the test points in the scene's box lie inside "
                  "geometry (a closed object): padding %.4g m on every side so that "
                  "most probes lie outside it (set bounds.padding or --padding to "
                  "choose)",
                  label.c_str(), 100.0 * share, double(padding));
    notes.emplace_back(text);
    return padding;
}

// Probes per metre of volume `v` over `box` (bricked: at level 0): its density, or the
// automatic rule for its layout.
float volumeDensity(const VolumeConfig& v, const grid::Aabb& box) {
    return v.density ? *v.density : automaticDensity(box, v.layout.value_or(VolumeLayout::Dense));
}

// Volume `v` with its layout decided: an automatic layout is bricked when the resolution is
// automatic, probes are centred and a dense grid at the volume's density over `box` would hold
// more than kDefaultMaxProbes probes (config.hpp, VolumeConfig::layout); otherwise dense.
VolumeConfig withLayout(VolumeConfig v, const grid::Aabb& box, const std::string& label,
                        std::vector<std::string>& notes) {
    if (v.layout) {
        return v;
    }
    v.layout = VolumeLayout::Dense;
    if (v.resolution || v.position == grid::PositionMode::Corner) {
        return v;
    }
    const float density = volumeDensity(v, box);
    const glm::uvec3 counts = powerOfTwoCounts(box.size(), density, 1.0f);
    const double probes = double(counts.x) * double(counts.y) * double(counts.z);
    if (probes <= double(kDefaultMaxProbes)) {
        return v;
    }
    v.layout = VolumeLayout::Bricked;
    char text[320];
    std::snprintf(text, sizeof text,
                  "%s: layout auto is bricked: a dense grid at %g probes/m over %.4g x %.4g x "
                  "%.4g m would need %.4g probes, more than %u; level 0 at %g probes/m, finer "
                  "near geometry (set layout or --layout to choose)",
                  label.c_str(), double(density), box.size().x, box.size().y, box.size().z, probes,
                  kDefaultMaxProbes, double(volumeDensity(v, box)));
    notes.emplace_back(text);
    return v;
}

// The volume's grid over its padded `box` and its description.
Result<VolumeDesc> placeVolume(const VolumeConfig& v, grid::Aabb box, const grid::RigidFrame& frame,
                               const std::string& label, std::vector<std::string>& notes) {
    const float density = volumeDensity(v, box);
    // A flat scene (a single floor quad) has zero thickness; give it one probe spacing.
    if (v.bounds.mode != BoundsMode::Custom) {
        for (int a = 0; a < 3; ++a) {
            if (box.max[a] - box.min[a] <= 0.0f) {
                box.min[a] -= 0.5f / density;
                box.max[a] += 0.5f / density;
            }
        }
    }
    if (Result<void> inside = checkVolumeCoordinates(box, label); !inside) {
        return inside.error();
    }
    const bool bricked = v.layout == VolumeLayout::Bricked;
    const glm::uvec3 res =
        v.resolution ? *v.resolution : automaticResolution(v, box, density, label, notes);
    Result<grid::GridLayout> layout =
        grid::GridLayout::make(box, res, bricked ? grid::PositionMode::Center : v.position, frame);
    if (!layout) {
        return makeError(layout.error().code, label + ": " + layout.error().message);
    }
    if (Result<void> inside = checkVolumeCoordinates(layout.value().worldBounds(), label);
        !inside) {
        return inside.error();
    }
    VolumeDesc desc;
    desc.name = v.name;
    desc.grid = layout.value();
    desc.shOrder = v.shOrder;
    desc.storage = v.storage;
    desc.blendPriority = v.blendPriority;
    desc.fadeDistance = v.fadeDistance;
    if (bricked) {
        desc.layout = VolumeLayout::Bricked;
        desc.bricks.maxLevel = v.maxLevel;
    }
    return desc;
}

// For a scene far from the origin for its finest probe spacing, what float32 costs there.
void addPrecisionNote(const Scene& scene, VolumePlan& plan) {
    if (plan.volumes.empty()) {
        return;
    }
    grid::Aabb all = plan.volumes[0].grid.worldBounds();
    float finest = INFINITY;
    for (const VolumeDesc& d : plan.volumes) {
        all = unionOf(all, d.grid.worldBounds());
        const glm::vec3 s = probeSpacing(d);
        finest = std::min({finest, s.x, s.y, s.z});
    }
    if (std::string note = precisionNote(scene, all, finest); !note.empty()) {
        plan.notes.push_back((scene.source.empty() ? "scene" : scene.source) + ": " + note);
    }
}

} // namespace

Result<VolumePlan> planVolumes(const Scene& scene, const BakeConfig& config) {
    if (Result<void> inside = checkSceneCoordinates(scene); !inside) {
        return inside.error();
    }
    const std::vector<VolumeConfig> configs = volumeConfigs(config);
    VolumePlan plan;
    LazyTracer tracer(scene, config);
    for (size_t index = 0; index < configs.size(); ++index) {
        const VolumeConfig& v = configs[index];
        const std::string label = volumeLabel(index, v);
        Result<PlacedBox> placed = unpaddedBox(scene, v, label);
        if (!placed) {
            return placed.error();
        }
        const Result<float> padding =
            volumePadding(scene, config, v, placed.value(), label, tracer, plan.notes);
        if (!padding) {
            return padding.error();
        }
        grid::Aabb box = placed.value().box;
        box.min -= glm::vec3(padding.value());
        box.max += glm::vec3(padding.value());
        Result<VolumeDesc> desc = placeVolume(withLayout(v, box, label, plan.notes), box,
                                              placed.value().frame, label, plan.notes);
        if (!desc) {
            return desc.error();
        }
        plan.volumes.push_back(std::move(desc).value());
        plan.padding.push_back(padding.value());
    }
    addPrecisionNote(scene, plan);
    const uint64_t bytes = estimateBakeMemory(plan.volumes);
    if (bytes > config.maxMemoryBytes) {
        return makeError(
            ErrorCode::OutOfRange,
            "volumes: the grids need " + std::to_string(bytes >> 20) +
                " MiB, more than max_memory_mb = " + std::to_string(config.maxMemoryBytes >> 20) +
                " (lower the resolution or raise --max-memory)");
    }
    return plan;
}

Result<std::vector<VolumeDesc>> resolveVolumes(const Scene& scene, const BakeConfig& config) {
    Result<VolumePlan> plan = planVolumes(scene, config);
    if (!plan) {
        return plan.error();
    }
    return std::move(plan).value().volumes;
}

VplConfig resolveVplConfig(const Scene& scene, const std::vector<VolumeDesc>& volumes,
                           const BakeConfig& config) {
    VplConfig v = config.vpl;
    double area = 0.0;
    for (const glm::uvec3& t : scene.triangles) {
        const glm::vec3 p0 = scene.positions[t.x];
        area +=
            0.5 *
            double(glm::length(glm::cross(scene.positions[t.y] - p0, scene.positions[t.z] - p0)));
    }
    if (!v.count) {
        // VPL spacing sqrt(area / count) at most half the smallest probe spacing h:
        // count >= 4 area / h^2.
        double spacing = INFINITY;
        for (const VolumeDesc& d : volumes) {
            const glm::vec3 s = probeSpacing(d);
            spacing = std::min(spacing, double(std::min({s.x, s.y, s.z})));
        }
        const double wanted = spacing > 0.0 ? 4.0 * area / (spacing * spacing) : 0.0;
        const double clamped = std::clamp(std::isfinite(wanted) ? wanted : 0.0,
                                          double(kMinDefaultVplCount), double(kMaxDefaultVplCount));
        v.count = std::bit_ceil(uint32_t(std::ceil(clamped)));
    }
    if (!v.clampDistance) {
        // Twice the radius of the disc of surface each VPL stands for: the clamp shrinks (and
        // its bias vanishes) as the count grows.
        v.clampDistance = float(2.0 * std::sqrt(area / (std::numbers::pi * double(*v.count))));
    }
    if (!v.nearField) {
        v.nearField = 2.0f * *v.clampDistance;
    }
    return v;
}

namespace {
// The probes a volume's plan holds: its grid's, or for a bricked volume its level 0 (3 probes
// per brick and axis, plus one); refinement is bounded by the budget afterwards.
uint64_t plannedProbes(const VolumeDesc& d) {
    const glm::uvec3 lattice = d.grid.resolution() * brick::kBrickCells + 1u;
    return d.layout == VolumeLayout::Bricked ? uint64_t(lattice.x) * lattice.y * lattice.z
                                             : d.grid.probeCount();
}

// The probes the progress expects of a volume not started yet: a dense grid's; a bricked
// volume's level 0 and as many again for each level refinement may test
// (BrickedSettings::expectFurther).
uint64_t expectedProbes(const VolumeDesc& d) {
    const uint64_t levels = d.layout == VolumeLayout::Bricked ? 1u + d.bricks.maxLevel : 1u;
    return plannedProbes(d) * levels;
}
} // namespace

uint64_t estimateBakeMemory(const std::vector<VolumeDesc>& volumes) {
    uint64_t total = 0;
    for (const VolumeDesc& d : volumes) {
        const uint64_t probes = plannedProbes(d);
        const uint64_t texels = uint64_t(planeCount(d.shOrder)) * 4 * 4; // float staging
        total += probes *
                 (sizeof(sh::ShRgb) + 1 + texels + texels / 2 * (d.storage == Storage::Float16));
    }
    return total;
}

namespace {

// What every phase of one bake shares: its inputs, the tracer, the thread count and the
// counters the probe threads update.
struct BakeRun {
    const Scene& scene;
    const BakeConfig& config;
    const BakeOptions& options;
    const RayTracer& tracer;
    std::chrono::steady_clock::time_point start;
    uint32_t threads;
    const MemoryPrediction& memory;
    // Grows as batches are queued: a bricked volume's probes are known only as it refines.
    std::atomic<uint64_t> totalProbes{0};
    std::atomic<uint64_t> probesDone{0};
    // The planned probes of the volumes not started yet: the progress's total covers them, so
    // its ETA is the whole bake's (BakeProgress).
    std::atomic<uint64_t> plannedAhead{0};
    std::atomic<uint64_t> rays{0};
    std::atomic<uint64_t> cutTotal{0};
    std::atomic<uint64_t> samplesTotal{0}; // directions the path-traced parts took
    std::atomic<uint32_t> samplesMax{0};
    std::atomic<uint64_t> overTarget{0}; // adaptive: valid probes that stopped above the target
    std::mutex statsMutex;               // a batch's chunks add their ProbeChunkStats under it
    DeringTally dering;                  // summed over the volumes as they finish, in order

    double elapsedSeconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    void report() const {
        if (options.progress) {
            options.progress(BakeProgress{
                probesDone.load(), totalProbes.load() + plannedAhead.load(), elapsedSeconds()});
        }
    }
};

// What a method prepares once for the whole bake, before any volume.
struct MethodState {
    std::optional<VplConfig> vplConfig;
    std::optional<VplGatherer> vplGatherer;
    std::optional<LpvLights> lpvLights;
};

// Method vpl: one VPL set for the whole bake, from the seed alone; each probe then gathers it
// on top of the direct light the path integrator computes with no bounce.
void prepareVpl(BakeRun& run, const std::vector<VolumeDesc>& descs, MethodState& method,
                BakeStats& stats) {
    const BakeConfig& config = run.config;
    const VplConfig& vpl = method.vplConfig.emplace(resolveVplConfig(run.scene, descs, config));
    VplSet set = traceVpls(run.scene, run.tracer, *vpl.count, vpl, config.seed);
    run.rays.fetch_add(set.rays);
    stats.vplLightPaths = set.lightPaths;
    method.vplGatherer.emplace(std::move(set.vpls), run.tracer, vpl, config.seed);
    stats.vpls = method.vplGatherer->vpls().size();
}

// Method lpv: the lights the grids carry, once for the whole bake; each volume then
// propagates its own cascades and every probe adds them to its direct light.
void prepareLpv(BakeRun& run, const std::vector<VolumeDesc>& descs, MethodState& method,
                BakeStats& stats) {
    const LpvLights& lights = method.lpvLights.emplace(prepareLpvLights(
        run.scene, run.tracer, run.config.lpv, descs, run.config.seed, run.threads));
    run.rays.fetch_add(lights.rays);
    stats.vpls = lights.vpls;
}

MethodState prepareMethod(BakeRun& run, const std::vector<VolumeDesc>& descs, BakeStats& stats) {
    const BakeConfig& config = run.config;
    MethodState method;
    if (config.method == Method::Vpl) {
        prepareVpl(run, descs, method, stats);
    }
    if (config.method == Method::Lpv) {
        prepareLpv(run, descs, method, stats);
    }
    return method;
}

// The path integrator's settings for every probe: the whole light for method path, the
// direct light (and validity) for vpl, validity and optionally traced direct light for lpv.
PathConfig methodPathConfig(const BakeConfig& config, const MethodState& method) {
    PathConfig settings = config.path;
    if (method.lpvLights) {
        settings.samples =
            config.lpv.direct == LpvDirect::Traced ? config.lpv.directSamples : kLpvValiditySamples;
        settings.maxBounces = 0;
        if (config.lpv.direct != LpvDirect::Traced) {
            settings.noiseTarget = 0.0f; // the samples only decide validity
        }
    }
    return settings;
}

// One volume's probe integrator: the path integrator, plus the method's VPL gather or
// propagated LPV cascades.
class VolumeIntegrator {
public:
    VolumeIntegrator(const BakeRun& run, const MethodState& method, const VolumeDesc& desc,
                     uint32_t volume_index)
        : m_config(run.config), m_volume(volume_index),
          m_lpvCascades(method.lpvLights
                            ? std::optional<LpvCascades>(propagateLpv(
                                  run.scene, *method.lpvLights, m_config.lpv, desc, run.threads))
                            : std::nullopt),
          m_path(run.scene, run.tracer, methodPathConfig(m_config, method), desc.shOrder) {
        // Dilation replaces every invalid probe's value, so the paths of one are never traced.
        // Without it the file keeps invalid probes' traced values, and they are traced.
        if (m_config.dilate) {
            m_path.stopInsideGeometry(m_config.backfaceThreshold);
        }
        if (method.vplGatherer) {
            m_vpl.emplace(run.scene, run.tracer, *method.vplGatherer, *method.vplConfig,
                          m_config.path, desc.shOrder);
        }
    }

    // Adaptive sampling's target for the path-traced part (0: fixed sampling).
    float noiseTarget() const { return m_path.config().noiseTarget; }

    // The probe at `p`, seeded by (seed, volume, id); adds the VPL cut's size to `cut`.
    ProbeSample bakeProbe(glm::vec3 p, uint64_t id, uint64_t& cut) const {
        ProbeSample s;
        if (m_vpl) {
            const VplProbeSample v = m_vpl->bakeProbe(p, m_config.seed, m_volume, id);
            s = v.probe;
            cut += v.cutSize;
        } else if (m_lpvCascades && m_path.config().noiseTarget > 0.0f) {
            // The traced direct light's noise counts against the whole probe, cascades included.
            const sh::ShRgb cascades = lpvProbe(*m_lpvCascades, m_config.lpv, p, sh::ShRgb{});
            s = m_path.bakeProbe(p, m_config.seed, m_volume, id, &cascades);
        } else {
            s = m_path.bakeProbe(p, m_config.seed, m_volume, id);
        }
        if (m_lpvCascades) {
            s.sh = lpvProbe(*m_lpvCascades, m_config.lpv, p, s.sh);
        }
        return s;
    }

private:
    const BakeConfig& m_config;
    uint32_t m_volume;
    std::optional<LpvCascades> m_lpvCascades;
    PathIntegrator m_path;
    std::optional<VplProbeIntegrator> m_vpl;
};

// Bakes any set of positions on the parallel loop, or across processes through the
// distributor (each chunk on the parallel loop of the process that takes it). Each probe's
// result depends only on (seed, volume, id), so scheduling never changes the output.
void bakeBatch(BakeRun& run, const VolumeIntegrator& integrator,
               std::span<const glm::vec3> positions, std::span<const uint64_t> ids,
               std::span<sh::ShRgb> out_sh, std::span<uint8_t> out_valid) {
    const size_t count = positions.size();
    run.totalProbes.fetch_add(count);
    // Small chunks keep both threads busy to the end.
    constexpr size_t kChunk = 4;
    const auto probes = [&](size_t begin, size_t end, ProbeChunkStats& total) {
        ProbeChunkStats stats;
        const float target = integrator.noiseTarget();
        for (size_t i = begin; i < end; ++i) {
            const ProbeSample s = integrator.bakeProbe(positions[i], ids[i], stats.cut);
            out_sh[i] = s.sh;
            out_valid[i] = probeValidity(s, run.config.backfaceThreshold);
            stats.rays += s.rays;
            stats.samples += s.samples;
            stats.most = std::max(stats.most, s.samples);
            stats.over += target > 0.0f && s.noise > target && out_valid[i] == kProbeValid ? 1 : 0;
        }
        run.probesDone.fetch_add(end - begin);
        const std::lock_guard<std::mutex> lock(run.statsMutex);
        total += stats;
    };
    // [begin, end) on this process's threads.
    const auto local = [&](size_t begin, size_t end) {
        ProbeChunkStats total;
        const auto body = [&](size_t b, size_t e) { probes(begin + b, begin + e, total); };
        if (run.options.progress) {
            // The calling thread only reports, so callbacks never run on a loop thread
            // (BakeOptions::progress).
            parallelForWatched(end - begin, run.threads, kChunk, body,
                               std::chrono::milliseconds(100), [&] { run.report(); });
        } else {
            parallelFor(end - begin, run.threads, kChunk, body);
        }
        return total;
    };
    ProbeChunkStats stats;
    if (run.options.distributor) {
        const uint64_t done_before = run.probesDone.load();
        stats = run.options.distributor->run(count, out_sh, out_valid, local);
        run.probesDone.store(done_before + count);
    } else {
        stats = local(0, count);
    }
    run.rays.fetch_add(stats.rays);
    run.cutTotal.fetch_add(stats.cut);
    run.samplesTotal.fetch_add(stats.samples);
    run.overTarget.fetch_add(stats.over);
    run.samplesMax.store(std::max(run.samplesMax.load(), stats.most));
}

BrickedSettings brickedSettings(BakeRun& run, const VolumeConfig& vc, uint32_t volume_index) {
    // The working memory: max_memory_mb less what the rest of the bake holds meanwhile
    // (memory_model.hpp).
    BrickedSettings s{run.config, vc, run.memory.brickedWorkingBytes[volume_index], &run.tracer,
                      run.threads};
    // The refinement's expected probes join the progress's total (BakeProgress), replacing
    // the previous expectation.
    s.expectFurther = [&run, expected = uint64_t(0)](uint64_t probes) mutable {
        run.plannedAhead.fetch_add(probes);
        run.plannedAhead.fetch_sub(expected);
        expected = probes;
    };
    return s;
}

// Adds a bricked volume's statistics and warnings to the bake's.
void addBrickedOutcome(const BrickedOutcome& b, BakeResult& result) {
    for (int l = 0; l < 4; ++l) {
        result.stats.bricksPerLevel[l] += b.bricksPerLevel[l];
        result.stats.solidBricksPerLevel[l] += b.solidBricksPerLevel[l];
    }
    result.stats.refineCandidates += b.refineCandidates;
    result.stats.budgetDropped += b.budgetDropped;
    result.stats.memoryUntested += b.memoryUntested;
    result.stats.budgetError = std::max(result.stats.budgetError, b.budgetError);
    result.stats.predictedInterpolationError =
        std::max(result.stats.predictedInterpolationError, b.predictedError);
    result.stats.invalidProbes += b.invalidProbes;
    result.stats.nudgedProbes += b.nudgedProbes;
    result.warnings.insert(result.warnings.end(), b.warnings.begin(), b.warnings.end());
}

float maxComponent(glm::vec3 v) {
    return std::max({v.x, v.y, v.z});
}

// Half storage holds coefficients up to kHalfMax (65504). A volume whose probes pass it (a
// light's intensity in other units, a probe beside a bright light) is stored in float and the
// bake says so, rather than failing once the work is done.
VolumeDesc storableDesc(VolumeDesc desc, std::span<const sh::ShRgb> probes,
                        std::vector<std::string>& warnings) {
    if (desc.storage != Storage::Float16) {
        return desc;
    }
    float largest = 0.0f;
    size_t largest_probe = 0;
    const int count = sh::coefficientCount(desc.shOrder);
    for (size_t i = 0; i < probes.size(); ++i) {
        for (int k = 0; k < count; ++k) {
            const float m = maxComponent(glm::abs(probes[i].rgb[size_t(k)]));
            if (m > largest) { // NaN never is: makeVolume refuses it
                largest = m;
                largest_probe = i;
            }
        }
    }
    if (largest > kHalfMax) {
        char value[64];
        std::snprintf(value, sizeof value, "%.4g (probe %zu)", double(largest), largest_probe);
        warnings.push_back("volume '" + desc.name + "': SH coefficient " + value +
                           " is past the half-float maximum 65504; stored as float (--format "
                           "float chooses it up front)");
        desc.storage = Storage::Float32;
    }
    return desc;
}

// makeVolume refuses coefficients that are not finite or beyond the texel bound (volume.hpp).
// In a bake that means the light was too strong for float sums somewhere (the loader refuses
// intensities and emission above kMaxEmission, but a light or emitter almost touching a probe can
// still overflow): name the scene and its brightest light, so the user knows where to look.
Result<Volume> checkedVolume(const Scene& scene, Result<Volume> volume) {
    if (volume) {
        return volume;
    }
    std::string where = scene.source.empty() ? std::string() : scene.source + ": ";
    std::string hint;
    const PunctualLight* brightest = nullptr;
    for (const PunctualLight& light : scene.lights) {
        const float peak = maxComponent(light.intensity);
        if (brightest == nullptr || peak > maxComponent(brightest->intensity)) {
            brightest = &light;
        }
    }
    if (brightest != nullptr) {
        char text[64];
        std::snprintf(text, sizeof text, "%g", double(maxComponent(brightest->intensity)));
        hint = " (the scene's brightest light" +
               (brightest->name.empty() ? std::string() : " '" + brightest->name + "'") +
               " has intensity " + text + "; check light intensities, emission and units)";
    }
    return makeError(volume.error().code, where + volume.error().message + hint);
}

// The last deringing pass of a volume, on its probes as stored (after dilation and stitching),
// and its statistics. `changes` holds what earlier passes did (dering.hpp).
void deringStored(BakeRun& run, const VolumeDesc& desc, std::span<sh::ShRgb> probes,
                  std::span<float> changes) {
    deringProbes(probes, desc.shOrder, desc.storage, run.threads, changes);
    const DeringTally t = tallyDering(changes);
    run.dering.probes += t.probes;
    run.dering.sumChange += t.sumChange;
    run.dering.maxChange = std::max(run.dering.maxChange, t.maxChange);
}

Result<Volume> bakeBrickedVolume(BakeRun& run, const VolumeDesc& desc, const VolumeConfig& vc,
                                 uint32_t volume_index, const ProbeBatchFn& bake_batch,
                                 BakeResult& result) {
    Result<BrickedOutcome> bricked = bakeBricked(
        run.scene, desc, desc.shOrder, brickedSettings(run, vc, volume_index), bake_batch);
    if (!bricked) {
        return bricked.error();
    }
    BrickedOutcome& b = bricked.value();
    addBrickedOutcome(b, result);
    if (!b.visibility.empty()) {
        run.rays.fetch_add(kVisibilityRaysPerProbe * b.desc.probeCount());
    }
    if (run.config.dering) {
        // bakeBricked deringed the probes before stitching; stitched probes are interpolations
        // of those and pass but for rounding, which this pass catches (dering.hpp).
        deringStored(run, b.desc, b.probes, b.deringChanges);
    }
    const VolumeDesc stored = storableDesc(b.desc, b.probes, result.warnings);
    return checkedVolume(run.scene, makeVolume(stored, b.probes, b.validity, b.visibility));
}

// Relocation (visibility.hpp, relocationTarget): every invalid probe of a dense volume that
// has free space within one cell is baked again there; those the bake finds valid there replace
// it. Returns the moves (zero where a probe stays in place).
std::vector<glm::vec3>
relocateInvalidProbes(BakeRun& run, const VolumeDesc& desc, std::span<const glm::vec3> positions,
                      std::span<const uint64_t> ids, const ProbeBatchFn& bake_batch,
                      std::vector<sh::ShRgb>& probes, std::vector<uint8_t>& validity) {
    std::vector<glm::vec3> moves(positions.size(), glm::vec3(0.0f));
    std::vector<size_t> invalid;
    for (size_t i = 0; i < validity.size(); ++i) {
        if (validity[i] == kProbeInvalid) {
            invalid.push_back(i);
        }
    }
    if (invalid.empty()) {
        return moves;
    }
    const glm::vec3 spacing = desc.grid.spacing();
    const float cell = std::min(spacing.x, std::min(spacing.y, spacing.z));
    std::vector<std::optional<glm::vec3>> targets(invalid.size());
    parallelFor(invalid.size(), run.threads, 4, [&](size_t begin, size_t end) {
        const ScopedFloatMode float_mode;
        for (size_t k = begin; k < end; ++k) {
            targets[k] = relocationTarget(run.tracer, positions[invalid[k]], cell, cell,
                                          run.config.backfaceThreshold);
        }
    });
    std::vector<size_t> moved;
    std::vector<glm::vec3> new_positions;
    std::vector<uint64_t> new_ids;
    for (size_t k = 0; k < invalid.size(); ++k) {
        if (targets[k]) {
            moved.push_back(invalid[k]);
            new_positions.push_back(*targets[k]);
            new_ids.push_back(ids[invalid[k]]);
        }
    }
    std::vector<sh::ShRgb> new_sh(moved.size());
    std::vector<uint8_t> new_valid(moved.size(), kProbeValid);
    bake_batch(new_positions, new_ids, new_sh, new_valid);
    for (size_t k = 0; k < moved.size(); ++k) {
        if (new_valid[k] == kProbeValid) {
            const size_t i = moved[k];
            probes[i] = new_sh[k];
            validity[i] = kProbeValid;
            moves[i] = new_positions[k] - positions[i];
        }
    }
    return moves;
}

Result<Volume> bakeDenseVolume(BakeRun& run, const VolumeDesc& desc, const ProbeBatchFn& bake_batch,
                               BakeResult& result) {
    const size_t count = desc.grid.probeCount();
    std::vector<glm::vec3> positions(count);
    std::vector<uint64_t> ids(count);
    for (size_t i = 0; i < count; ++i) {
        positions[i] = desc.grid.probeWorld(desc.grid.probeCoords(i));
        ids[i] = i;
    }
    std::vector<sh::ShRgb> probes(count);
    std::vector<uint8_t> validity(count, kProbeValid);
    bake_batch(positions, ids, probes, validity);

    std::vector<glm::vec3> moves;
    if (run.config.relocate) {
        moves = relocateInvalidProbes(run, desc, positions, ids, bake_batch, probes, validity);
        result.stats.relocatedProbes += uint64_t(std::count_if(
            moves.begin(), moves.end(), [](glm::vec3 m) { return m != glm::vec3(0.0f); }));
    }
    const uint64_t invalid = uint64_t(std::count(validity.begin(), validity.end(), 0));
    result.stats.invalidProbes += invalid;
    if (run.config.dilate && invalid > 0) {
        const uint64_t unreachable = dilate(desc.grid, probes, validity);
        if (unreachable > 0) {
            result.warnings.push_back("volume '" + desc.name + "': " + std::to_string(unreachable) +
                                      " invalid probes have no valid probe to dilate from");
        }
    }
    // The storage is settled before deringing, whose rounding margin depends on it.
    const VolumeDesc stored = storableDesc(desc, probes, result.warnings);
    if (run.config.dering) {
        std::vector<float> changes(count, kNotDeringed);
        deringStored(run, stored, probes, changes);
    }
    // Visibility from the validity before dilation: dilated probes stay hidden.
    std::vector<uint8_t> vis;
    if (run.config.visibility) {
        vis = traceVolumeVisibility(run.tracer, desc, validity, run.threads, moves);
        run.rays.fetch_add(kVisibilityRaysPerProbe * count);
    }
    return checkedVolume(run.scene, makeVolume(stored, probes, validity, vis));
}

Result<Volume> bakeVolume(BakeRun& run, const MethodState& method, const VolumeDesc& desc,
                          uint32_t volume_index, const VolumeConfig& vc, BakeResult& result) {
    const VolumeIntegrator integrator(run, method, desc, volume_index);
    const ProbeBatchFn bake_batch = [&](std::span<const glm::vec3> positions,
                                        std::span<const uint64_t> ids, std::span<sh::ShRgb> out_sh,
                                        std::span<uint8_t> out_valid) {
        bakeBatch(run, integrator, positions, ids, out_sh, out_valid);
    };
    if (desc.layout == VolumeLayout::Bricked) {
        return bakeBrickedVolume(run, desc, vc, volume_index, bake_batch, result);
    }
    return bakeDenseVolume(run, desc, bake_batch, result);
}

// The memory model's prediction next to the measured peak (BakeStats).
void recordPrediction(const MemoryPrediction& memory, BakeStats& stats) {
    stats.predictedPeakBytes = memory.peakBytes;
    stats.predictedRefinementBytes = memory.refinementBoundBytes;
    const MemoryPhase& peak = memory.phases[memory.peakPhase];
    stats.predictedPeakPhase = peak.name;
    for (const MemoryTerm& t : peak.terms) {
        stats.predictedTerms.emplace_back(t.what, t.bytes);
    }
}

void finishStats(const BakeRun& run, const MethodState& method, BakeStats& stats) {
    stats.seconds = run.elapsedSeconds();
    stats.probes = run.totalProbes.load();
    stats.rays = run.rays.load();
    stats.mraysPerSecond = stats.seconds > 0 ? double(stats.rays) / stats.seconds * 1e-6 : 0;
    stats.peakMemoryBytes = peakResidentBytes();
    if (method.vplGatherer && run.totalProbes.load() > 0) {
        stats.vplMeanCut = double(run.cutTotal.load()) / double(run.totalProbes.load());
    }
    if (run.totalProbes.load() > 0) {
        stats.meanSamples = double(run.samplesTotal.load()) / double(run.totalProbes.load());
    }
    stats.maxSamples = run.samplesMax.load();
    stats.probesOverTarget = run.overTarget.load();
    stats.deringedProbes = run.dering.probes;
    stats.deringMeanChange =
        run.dering.probes > 0 ? run.dering.sumChange / double(run.dering.probes) : 0.0;
    stats.deringMaxChange = run.dering.maxChange;
}

// The metadata records what was actually baked: the resolved resolution of every volume and
// the method's resolved settings.
BakeMetadata bakeMetadata(const BakeRun& run, const VolumePlan& plan, const MethodState& method) {
    const std::vector<VolumeDesc>& descs = plan.volumes;
    const BakeConfig& config = run.config;
    BakeMetadata m;
    m.toolVersion = "probekit " PROBEKIT_VERSION_STRING;
    m.method = std::string(toString(config.method));
    BakeConfig resolved = config;
    resolved.volumes = volumeConfigs(config);
    for (size_t i = 0; i < resolved.volumes.size(); ++i) {
        resolved.volumes[i].resolution = descs[i].grid.resolution();
        resolved.volumes[i].layout = descs[i].layout; // an automatic layout as decided
        resolved.volumes[i].bounds.padding = plan.padding[i];
    }
    if (method.vplConfig) {
        resolved.vpl = *method.vplConfig; // the chosen count and clamp distance
    }
    if (method.lpvLights) {
        resolved.lpv.iterations = resolveLpvSettings(config.lpv).iterations;
    }
    m.parametersJson = describeConfig(resolved);
    m.seed = config.seed;
    m.sceneHash = run.scene.sourceHash;
    // Wall time stays out of the file so that the same input gives the same bytes
    // (ARCHITECTURE.md: output is deterministic); BakeStats::seconds carries it.
    m.bakeSeconds = 0.0;
    return m;
}

} // namespace

namespace {

// A volume whose every probe is black (no light reaches any of them: a sealed level lit only by
// the sky, probes all inside geometry) is a file of zeros; said, not left for the render to show.
std::string blackVolumeWarning(const Volume& volume) {
    for (size_t i = 0; i < volume.probeCount(); ++i) {
        if (volume.probe(i).rgb[0] != glm::vec3(0.0f)) {
            return {};
        }
    }
    return "volume '" + volume.desc.name +
           "': every probe is black: no light reaches any of them (a sealed level lit only by "
           "its sky? every probe inside geometry?)";
}

// bake() once the config is checked and the light modes applied to `scene`.
Result<BakeResult> bakeScene(const Scene& scene, const BakeConfig& config,
                             const BakeOptions& options,
                             std::chrono::steady_clock::time_point start) {
    // An unlit scene bakes to zeros by construction: an error, not a file of zeros in silence.
    Result<void> lit = checkSceneLit(scene);
    if (!lit && !options.allowUnlit) {
        return lit.error();
    }
    Result<VolumePlan> plan = planVolumes(scene, config);
    if (!plan) {
        return plan.error();
    }
    const std::vector<VolumeDesc>& descs = plan.value().volumes;
    // Everything big is allocated from here on: the memory model decides first.
    const uint32_t threads = resolveThreads(options.threads);
    const MemoryPrediction memory = predictBakeMemory(
        {scene, config, descs,
         config.method == Method::Vpl ? *resolveVplConfig(scene, descs, config).count : 0, threads,
         processBytes(scene)});
    if (Result<void> fits = checkBakeMemory(memory, config); !fits) {
        return fits.error();
    }
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    if (!tracer) {
        return tracer.error();
    }
    BakeRun run{scene, config, options, *tracer.value(), start, threads, memory};
    BakeResult result;
    result.warnings = plan.value().notes;
    result.stats.threads = run.threads;
    recordPrediction(memory, result.stats);
    if (!lit) {
        result.warnings.push_back(lit.error().message);
    }
    const MethodState method = prepareMethod(run, descs, result.stats);
    const std::vector<VolumeConfig> volume_configs = volumeConfigs(config);
    for (const VolumeDesc& d : descs) {
        run.plannedAhead.fetch_add(expectedProbes(d));
    }
    for (uint32_t vi = 0; vi < descs.size(); ++vi) {
        run.plannedAhead.fetch_sub(expectedProbes(descs[vi]));
        Result<Volume> volume = bakeVolume(run, method, descs[vi], vi, volume_configs[vi], result);
        if (!volume) {
            return volume.error();
        }
        // An unlit scene's volumes are black by construction, and already said to be.
        if (std::string black = lit ? blackVolumeWarning(volume.value()) : std::string();
            !black.empty()) {
            result.warnings.push_back(std::move(black));
        }
        result.file.volumes.push_back(std::move(volume).value());
    }
    run.report();
    finishStats(run, method, result.stats);
    result.file.metadata = bakeMetadata(run, plan.value(), method);
    return result;
}

} // namespace

Result<BakeResult> bake(const Scene& scene, const BakeConfig& config, const BakeOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    if (Result<void> valid = validateBakeConfig(config); !valid) {
        return valid.error();
    }
    if (scene.unitScale != config.scale) {
        return makeError(ErrorCode::InvalidArgument,
                         "scale: the config says " + std::to_string(config.scale) +
                             " m per scene unit, but the scene was loaded with " +
                             std::to_string(scene.unitScale) + " (LoadOptions::scale)");
    }
    // Light modes other than baked bake a copy of the scene with them applied (its arrays once
    // more in memory, for as long as the bake runs).
    Result<std::optional<Scene>> moded = applyLightModes(scene, config);
    if (!moded) {
        return moded.error();
    }
    return bakeScene(moded.value() ? *moded.value() : scene, config, options, start);
}

} // namespace probekit::baker
