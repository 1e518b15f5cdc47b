// The bake: volume placement, the probe loop on a thread pool, validity and dilation.
#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>
#include <thread>

#include <sys/resource.h>

#include <glm/gtc/matrix_access.hpp>
#include <glm/gtc/quaternion.hpp>

#include "bricked.hpp"
#include "lpv_method.hpp"
#include "path_integrator.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/settings.hpp"
#include "ray_tracer.hpp"
#include "visibility.hpp"
#include "vpl_gather.hpp"
#include "vpl_integrator.hpp"
#include "vpl_paths.hpp"

namespace probekit::baker {
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

glm::vec3 probeSpacing(const VolumeDesc& desc) {
    if (desc.layout == VolumeLayout::Bricked) {
        const glm::uvec3 cells = brick::finestCells(desc.grid.resolution(), desc.bricks.maxLevel);
        return desc.grid.bounds().size() / glm::vec3(cells * brick::kBrickCells);
    }
    return desc.grid.spacing();
}

Result<std::vector<VolumeDesc>> resolveVolumes(const Scene& scene, const BakeConfig& config) {
    std::vector<VolumeConfig> configs = config.volumes;
    if (configs.empty()) {
        configs.push_back(VolumeConfig{});
    }
    std::vector<VolumeDesc> out;
    for (size_t index = 0; index < configs.size(); ++index) {
        const VolumeConfig& v = configs[index];
        const std::string label = volumeLabel(index, v);
        grid::Aabb box;
        grid::RigidFrame frame;
        switch (v.bounds.mode) {
        case BoundsMode::Custom:
            box = grid::Aabb{v.bounds.min, v.bounds.max};
            break;
        case BoundsMode::AutoWorld:
            if (v.bounds.nodes.empty()) {
                if (!scene.hasGeometry()) {
                    return makeError(ErrorCode::InvalidArgument,
                                     label + ".bounds: the scene has no geometry, so automatic "
                                             "bounds are empty; give custom bounds");
                }
                box = scene.bounds;
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
                    box = first ? node->worldBounds : unionOf(box, node->worldBounds);
                    first = false;
                }
                if (first) {
                    return makeError(ErrorCode::InvalidArgument,
                                     label + ".bounds.nodes: none of the listed nodes has a mesh");
                }
            }
            break;
        case BoundsMode::AutoLocal: {
            const SceneNode* node = findNode(scene, v.bounds.node);
            if (!node) {
                return makeError(ErrorCode::InvalidArgument,
                                 label + ".bounds.node: no node named '" + v.bounds.node + "'");
            }
            if (!node->hasMesh) {
                return makeError(ErrorCode::InvalidArgument,
                                 label + ".bounds.node: node '" + v.bounds.node +
                                     "' has no mesh to take bounds from");
            }
            glm::vec3 scale;
            decompose(node->world, frame, scale);
            // The frame is rigid, so the node's scale is folded into the local box.
            const glm::vec3 a = node->localBounds.min * scale;
            const glm::vec3 b = node->localBounds.max * scale;
            box = grid::Aabb{glm::min(a, b), glm::max(a, b)};
            break;
        }
        }
        box.min -= glm::vec3(v.bounds.padding);
        box.max += glm::vec3(v.bounds.padding);
        const glm::vec3 extent = box.size();
        const float longest = std::max({extent.x, extent.y, extent.z});
        const float density =
            v.density ? *v.density
                      : std::max(kDefaultDensity, longest > 0.0f ? kMinAutoProbes / longest : 0.0f);
        // A flat scene (a single floor quad) has zero thickness; give it one probe spacing.
        if (v.bounds.mode != BoundsMode::Custom) {
            for (int a = 0; a < 3; ++a) {
                if (box.max[a] - box.min[a] <= 0.0f) {
                    box.min[a] -= 0.5f / density;
                    box.max[a] += 0.5f / density;
                }
            }
        }
        const bool bricked = v.layout == VolumeLayout::Bricked;
        glm::uvec3 res;
        if (v.resolution) {
            res = *v.resolution;
        } else {
            const glm::vec3 size = box.size();
            for (int a = 0; a < 3; ++a) {
                // Bricked: level-0 bricks, each spanning 3 probe spacings.
                const float probes =
                    size[a] * density / (bricked ? float(brick::kBrickCells) : 1.0f);
                res[a] = std::min(roundToPowerOfTwo(probes), v.maxResolution);
                if (v.position == grid::PositionMode::Corner) {
                    res[a] = std::max(res[a], 2u);
                }
            }
        }
        Result<grid::GridLayout> layout = grid::GridLayout::make(
            box, res, bricked ? grid::PositionMode::Center : v.position, frame);
        if (!layout) {
            return makeError(layout.error().code, label + ": " + layout.error().message);
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
        out.push_back(std::move(desc));
    }
    const uint64_t bytes = estimateBakeMemory(out);
    if (bytes > config.maxMemoryBytes) {
        return makeError(
            ErrorCode::OutOfRange,
            "volumes: the grids need " + std::to_string(bytes >> 20) +
                " MiB, more than max_memory_mb = " + std::to_string(config.maxMemoryBytes >> 20) +
                " (lower the resolution or raise --max-memory)");
    }
    return out;
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

uint64_t estimateBakeMemory(const std::vector<VolumeDesc>& volumes) {
    uint64_t total = 0;
    for (const VolumeDesc& d : volumes) {
        // Bricked: level 0 (3 probes per brick and axis, plus one); refinement is bounded by
        // the budget afterwards.
        const glm::uvec3 lattice = d.grid.resolution() * brick::kBrickCells + 1u;
        const uint64_t probes = d.layout == VolumeLayout::Bricked
                                    ? uint64_t(lattice.x) * lattice.y * lattice.z
                                    : d.grid.probeCount();
        const uint64_t texels = uint64_t(planeCount(d.shOrder)) * 4 * 4; // float staging
        total += probes *
                 (sizeof(sh::ShRgb) + 1 + texels + texels / 2 * (d.storage == Storage::Float16));
    }
    return total;
}

Result<BakeResult> bake(const Scene& scene, const BakeConfig& config, const BakeOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    if (Result<void> valid = validateBakeConfig(config); !valid) {
        return valid.error();
    }
    Result<std::vector<VolumeDesc>> descs = resolveVolumes(scene, config);
    if (!descs) {
        return descs.error();
    }
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    if (!tracer) {
        return tracer.error();
    }

    BakeResult result;
    result.stats.threads =
        options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    // Grows as batches are queued: a bricked volume's probes are known only as it refines.
    std::atomic<uint64_t> total_probes{0};
    std::atomic<uint64_t> probes_done{0};
    std::vector<VolumeConfig> volume_configs = config.volumes;
    if (volume_configs.empty()) {
        volume_configs.push_back(VolumeConfig{});
    }
    std::atomic<uint64_t> rays{0};
    std::atomic<uint64_t> cut_total{0};

    // Method vpl: one VPL set for the whole bake, from the seed alone; each probe then gathers
    // it on top of the direct light the path integrator computes with no bounce.
    std::optional<VplConfig> vpl_config;
    std::optional<VplGatherer> vpl_gatherer;
    if (config.method == Method::Vpl) {
        vpl_config = resolveVplConfig(scene, descs.value(), config);
        VplSet set = traceVpls(
            scene, *tracer.value(),
            VplPathSettings{*vpl_config->count, vpl_config->bounces, vpl_config->sampling},
            config.seed);
        rays.fetch_add(set.rays);
        result.stats.vplLightPaths = set.lightPaths;
        vpl_gatherer.emplace(std::move(set.vpls), *tracer.value(),
                             VplGatherSettings{vpl_config->clamp, *vpl_config->clampDistance,
                                               *vpl_config->nearField, vpl_config->shadows,
                                               vpl_config->cutError},
                             config.seed);
        result.stats.vpls = vpl_gatherer->vpls().size();
    }
    // Method lpv: the lights the grids carry, once for the whole bake; each volume then
    // propagates its own cascades and every probe adds them to its direct light.
    std::optional<LpvLights> lpv_lights;
    if (config.method == Method::Lpv) {
        lpv_lights = prepareLpvLights(scene, *tracer.value(), config.lpv, descs.value(),
                                      config.seed, result.stats.threads);
        rays.fetch_add(lpv_lights->rays);
        result.stats.vpls = lpv_lights->vpls;
    }
    auto report = [&] {
        if (options.progress) {
            options.progress(BakeProgress{
                probes_done.load(), total_probes.load(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()});
        }
    };

    for (uint32_t vi = 0; vi < descs.value().size(); ++vi) {
        const VolumeDesc& desc = descs.value()[vi];
        PathSettings settings;
        settings.samples = config.path.samples;
        settings.maxBounces = config.path.maxBounces;
        std::optional<LpvCascades> lpv_cascades;
        if (lpv_lights) {
            settings.samples = config.lpv.direct == LpvDirect::Traced ? config.lpv.directSamples
                                                                      : kLpvValiditySamples;
            settings.maxBounces = 0;
            lpv_cascades.emplace(
                propagateLpv(scene, *lpv_lights, config.lpv, desc, result.stats.threads));
        }
        const PathIntegrator integrator(scene, *tracer.value(), settings, desc.shOrder);
        std::optional<VplProbeIntegrator> vpl_integrator;
        if (vpl_gatherer) {
            vpl_integrator.emplace(scene, *tracer.value(), *vpl_gatherer, *vpl_config,
                                   desc.shOrder);
        }

        // Bakes any set of positions on the pool. Each probe's result depends only on
        // (seed, volume, id), so scheduling never changes the output.
        ProbeBatchFn bake_batch = [&](std::span<const glm::vec3> positions,
                                      std::span<const uint64_t> ids, std::span<sh::ShRgb> out_sh,
                                      std::span<uint8_t> out_valid) {
            const size_t count = positions.size();
            total_probes.fetch_add(count);
            std::atomic<size_t> next{0};
            // Small chunks keep both threads busy to the end.
            constexpr size_t kChunk = 4;
            auto worker = [&] {
                uint64_t local_rays = 0;
                uint64_t local_cut = 0;
                for (;;) {
                    const size_t begin = next.fetch_add(kChunk);
                    if (begin >= count) {
                        break;
                    }
                    const size_t end = std::min(count, begin + kChunk);
                    for (size_t i = begin; i < end; ++i) {
                        const glm::vec3 p = positions[i];
                        ProbeSample s;
                        if (vpl_integrator) {
                            const VplProbeSample v =
                                vpl_integrator->bakeProbe(p, config.seed, vi, ids[i]);
                            s = v.probe;
                            local_cut += v.cutSize;
                        } else {
                            s = integrator.bakeProbe(p, config.seed, vi, ids[i]);
                        }
                        if (lpv_cascades) {
                            s.sh = lpvProbe(*lpv_cascades, config.lpv, p, s.sh);
                        }
                        out_sh[i] = s.sh;
                        out_valid[i] = probeValidity(s, config.backfaceThreshold);
                        local_rays += s.rays;
                    }
                    probes_done.fetch_add(end - begin);
                }
                rays.fetch_add(local_rays);
                cut_total.fetch_add(local_cut);
            };
            const uint64_t batch_end = probes_done.load() + count;
            std::vector<std::thread> pool;
            const uint32_t pool_size =
                options.progress ? result.stats.threads : result.stats.threads - 1;
            for (uint32_t t = 0; t < pool_size; ++t) {
                pool.emplace_back(worker);
            }
            if (options.progress) {
                // The calling thread only reports, so callbacks never run on a pool thread.
                while (probes_done.load() < batch_end) {
                    report();
                    std::this_thread::sleep_for(std::chrono::milliseconds(100));
                }
            } else {
                worker();
            }
            for (std::thread& t : pool) {
                t.join();
            }
        };

        if (desc.layout == VolumeLayout::Bricked) {
            const VolumeConfig& vc = volume_configs[vi];
            BrickedSettings bs;
            bs.maxLevel = vc.maxLevel;
            bs.refineError = vc.refineError;
            bs.budgetBytes = config.maxMemoryBytes;
            bs.dilate = config.dilate;
            bs.tracer = tracer.value().get();
            bs.nudge = config.nudge;
            bs.backfaceThreshold = config.backfaceThreshold;
            bs.visibility = config.visibility;
            bs.threads = result.stats.threads;
            Result<BrickedOutcome> bricked = bakeBricked(scene, desc, desc.shOrder, bs, bake_batch);
            if (!bricked) {
                return bricked.error();
            }
            BrickedOutcome& b = bricked.value();
            for (int l = 0; l < 4; ++l) {
                result.stats.bricksPerLevel[l] += b.bricksPerLevel[l];
            }
            result.stats.refineCandidates += b.refineCandidates;
            result.stats.budgetDropped += b.budgetDropped;
            result.stats.budgetError = std::max(result.stats.budgetError, b.budgetError);
            result.stats.predictedInterpolationError =
                std::max(result.stats.predictedInterpolationError, b.predictedError);
            result.stats.invalidProbes += b.invalidProbes;
            result.stats.nudgedProbes += b.nudgedProbes;
            result.warnings.insert(result.warnings.end(), b.warnings.begin(), b.warnings.end());
            if (!b.visibility.empty()) {
                rays.fetch_add(kVisibilityRaysPerProbe * b.desc.probeCount());
            }
            Result<Volume> volume = makeVolume(b.desc, b.probes, b.validity, b.visibility);
            if (!volume) {
                return volume.error();
            }
            result.file.volumes.push_back(std::move(volume).value());
            continue;
        }

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

        const uint64_t invalid = uint64_t(std::count(validity.begin(), validity.end(), 0));
        result.stats.invalidProbes += invalid;
        if (config.dilate && invalid > 0) {
            const uint64_t unreachable = dilate(desc.grid, probes, validity);
            if (unreachable > 0) {
                result.warnings.push_back("volume '" + desc.name +
                                          "': " + std::to_string(unreachable) +
                                          " invalid probes have no valid probe to dilate from");
            }
        }
        // Visibility from the validity before dilation: dilated probes stay hidden.
        std::vector<uint8_t> vis;
        if (config.visibility) {
            vis = traceVolumeVisibility(*tracer.value(), desc, validity, result.stats.threads);
            rays.fetch_add(kVisibilityRaysPerProbe * count);
        }
        Result<Volume> volume = makeVolume(desc, probes, validity, vis);
        if (!volume) {
            return volume.error();
        }
        result.file.volumes.push_back(std::move(volume).value());
    }
    report();

    result.stats.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.stats.probes = total_probes.load();
    result.stats.rays = rays.load();
    result.stats.mraysPerSecond =
        result.stats.seconds > 0 ? double(result.stats.rays) / result.stats.seconds * 1e-6 : 0;
    result.stats.peakMemoryBytes = peakResidentBytes();
    if (vpl_gatherer && total_probes.load() > 0) {
        result.stats.vplMeanCut = double(cut_total.load()) / double(total_probes.load());
    }

    BakeMetadata& m = result.file.metadata;
    m.toolVersion = "probekit " PROBEKIT_VERSION_STRING;
    m.method = std::string(toString(config.method));
    BakeConfig resolved = config;
    if (resolved.volumes.empty()) {
        resolved.volumes.push_back(VolumeConfig{});
    }
    // Record what was actually baked: the resolved resolution and bounds of every volume.
    for (size_t i = 0; i < resolved.volumes.size(); ++i) {
        const VolumeDesc& d = descs.value()[i];
        resolved.volumes[i].resolution = d.grid.resolution();
    }
    if (vpl_config) {
        resolved.vpl = *vpl_config; // the chosen count and clamp distance
    }
    if (lpv_lights) {
        resolved.lpv.iterations = resolveLpvSettings(config.lpv).iterations;
    }
    m.parametersJson = describeConfig(resolved);
    m.seed = config.seed;
    m.sceneHash = scene.sourceHash;
    m.bakeSeconds = result.stats.seconds;
    return result;
}

} // namespace probekit::baker
