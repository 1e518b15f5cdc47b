#include "memory_model.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "methods/lpv.hpp"
#include "methods/lpv_method.hpp"
#include "methods/vpl_gather.hpp"
#include "methods/vpl_paths.hpp"
#include "volume/bricked.hpp"

namespace probekit::baker {

namespace {

std::string count(uint64_t n) {
    return std::to_string(n);
}

// A LightSampler (light_sampler.hpp): per emissive triangle its geometry and CDF entry, a
// per-triangle pdf when the scene has emitters, and for a lat-long sky a float column CDF per
// pixel and a few doubles per row.
uint64_t lightSamplerBytes(const Scene& scene) {
    uint64_t emitters = 0;
    for (const uint32_t m : scene.triangleMaterial) {
        emitters += m < scene.materials.size() && scene.materials[m].isEmissive();
    }
    uint64_t bytes = 0;
    if (emitters > 0) {
        // Emitter: four vec3 and an index; the CDF in double.
        bytes += emitters * (4 * sizeof(glm::vec3) + sizeof(uint32_t) + sizeof(double)) +
                 uint64_t(scene.triangles.size()) * sizeof(float);
    }
    const Image& sky = scene.environment.image;
    if (scene.environment.type == Environment::Type::LatLong) {
        bytes += uint64_t(sky.height) * (sky.width + 1) * sizeof(float) +
                 uint64_t(sky.height + 1) * 3 * sizeof(double);
    }
    return bytes;
}

// Bytes makeVolume's result keeps per probe: texels, validity, visibility.
uint64_t outputBytesPerProbe(const VolumeDesc& d, bool visibility) {
    return uint64_t(planeCount(d.shOrder)) * 4 * bytesPerComponent(d.storage) + 1 +
           (visibility ? visibility::kBytesPerProbe : 0);
}

// A dense volume at its peak (bakeDenseVolume, at makeVolume): positions, ids, SH, validity and
// visibility of every probe, makeVolume's float staging, and its result.
uint64_t denseWorkingBytesPerProbe(const VolumeDesc& d, bool visibility) {
    const uint64_t staging = uint64_t(planeCount(d.shOrder)) * 4 * sizeof(float);
    const uint64_t kept = outputBytesPerProbe(d, visibility);
    const uint64_t inputs = sizeof(glm::vec3) + sizeof(uint64_t) + sizeof(sh::ShRgb) + 1 +
                            (visibility ? visibility::kBytesPerProbe : 0);
    // Float storage moves the staging into the volume.
    return inputs + kept + (d.storage == Storage::Float16 ? staging : 0);
}

// Lattice points of a bricked volume with every brick refined to `level`.
uint64_t latticeProbes(const VolumeDesc& d, uint32_t level) {
    const glm::uvec3 points = d.grid.resolution() * brick::kBrickCells * (1u << level) + 1u;
    return uint64_t(points.x) * points.y * points.z;
}

// Scene surface area inside `box`: each triangle's area times the share of its bounding box
// inside (exact for axis-aligned rectangles, an estimate otherwise).
double areaInside(const Scene& scene, const grid::Aabb& box) {
    double area = 0.0;
    for (const glm::uvec3& t : scene.triangles) {
        const auto [a, b, c, lo, hi] = triangleCorners(scene, t);
        double share = 1.0;
        for (int k = 0; k < 3; ++k) {
            const float inside = std::min(hi[k], box.max[k]) - std::max(lo[k], box.min[k]);
            if (inside < 0.0f) {
                share = 0.0;
                break;
            }
            if (hi[k] > lo[k]) {
                share *= double(inside) / double(hi[k] - lo[k]);
            }
        }
        if (share > 0.0) {
            area += share * 0.5 * double(glm::length(glm::cross(b - a, c - a)));
        }
    }
    return area;
}

// Transfers a surface blocks per cell-sized square of surface (buildLpvTransfer's corrections;
// never more than 6 per cell): measured 5.8 to 10.5 over the Cornell box, the courtyard and the
// engine at grids 16 to 64.
constexpr double kLpvCorrectionsPerCellArea = 12.0;

// One volume's LPV cascades (LpvCascades' constructor): the largest bytes held while they are
// propagated, and what they keep.
struct LpvVolumeBytes {
    uint64_t peak = 0;
    uint64_t kept = 0;
    uint64_t cells = 0;
};
LpvVolumeBytes lpvVolumeBytes(const Scene& scene, const LpvConfig& config, const VolumeDesc& v) {
    const LpvSettings settings = resolveLpvSettings(config);
    const grid::Aabb bounds = v.grid.worldBounds();
    const std::vector<LpvCascadeLayout> layouts =
        layoutLpvCascades(bounds, scene.hasGeometry() ? scene.bounds : bounds, settings);
    constexpr uint64_t kField = 12 * sizeof(float);    // LpvField per cell
    constexpr uint64_t kCrossing = 18 * sizeof(float); // CrossingPlanes per cell
    constexpr uint64_t kRadiance = sizeof(Sh1Rgb);     // the propagated result per cell
    constexpr uint64_t kBlocking = sizeof(sh::Coeffs); // geometry volume per corner
    // propagateToRadiance: the current field, the next one and the one replacing it during a
    // step, the crossings, and the result at the end.
    constexpr uint64_t kPropagation = 3 * kField + kCrossing;
    static_assert(kPropagation >= 2 * kField + kCrossing + kRadiance);
    LpvVolumeBytes out;
    for (size_t k = 0; k < layouts.size(); ++k) {
        const LpvCascadeLayout& layout = layouts[k];
        const uint64_t cells = layout.cellCount();
        out.cells += cells;
        const glm::uvec3 corners = glm::uvec3(layout.cells) + 1u;
        uint64_t corrections = 0;
        if (settings.occlusion) {
            const float s = layout.cellSize;
            const grid::Aabb box{layout.origin - 0.5f * s, layout.max() + 0.5f * s};
            const double blocked = kLpvCorrectionsPerCellArea * areaInside(scene, box) / (s * s);
            corrections = uint64_t(std::min(blocked, 6.0 * double(cells)));
        }
        const uint64_t transfer = corrections * sizeof(LpvTransfer::Correction);
        const uint64_t geometry =
            settings.occlusion ? uint64_t(corners.x) * corners.y * corners.z * kBlocking : 0;
        out.peak = std::max(out.peak, out.kept + transfer + geometry);
        out.peak = std::max(out.peak, out.kept + transfer + kPropagation * cells);
        out.kept += kRadiance * cells;
        if (k > 0) {
            // The lights outside the finer cascade, propagated once more.
            out.peak = std::max(out.peak, out.kept + transfer + kPropagation * cells);
            out.kept += kRadiance * cells;
        }
    }
    return out;
}

std::string volumeName(size_t index, const VolumeDesc& v) {
    return "volumes[" + std::to_string(index) + "] ('" + v.name + "')";
}

struct Fixed {
    MemoryTerm process, scene, tracer, threads;
};

} // namespace

uint64_t MemoryPhase::bytes() const {
    uint64_t total = 0;
    for (const MemoryTerm& t : terms) {
        total += t.bytes;
    }
    return total;
}

uint64_t MemoryPhase::ownBytes(bool with_adapting) const {
    uint64_t total = 0;
    for (const MemoryTerm& t : terms) {
        total += t.external || (t.adapts && !with_adapting) ? 0 : t.bytes;
    }
    return total;
}

uint64_t residentBytes() {
    std::ifstream statm("/proc/self/statm");
    uint64_t size = 0;
    uint64_t resident = 0;
    if (!(statm >> size >> resident)) {
        return 0;
    }
    const long page = sysconf(_SC_PAGESIZE);
    return resident * uint64_t(page > 0 ? page : 4096);
}

uint64_t processBytes(const Scene& scene) {
    const uint64_t resident = residentBytes();
    uint64_t held = sceneBytes(scene);
#if defined(__GLIBC__)
    // Heap the loader freed stays resident but is reused by the bake's next allocations.
    held += mallinfo2().fordblks;
#endif
    return resident > held ? resident - held : 0;
}

uint64_t brickedWorkingBytes(const BakeConfig& config, uint64_t other_bytes) {
    const uint64_t room =
        config.maxMemoryBytes > other_bytes ? config.maxMemoryBytes - other_bytes : 0;
    return std::max(room, kMinWorkingBytes);
}

namespace {

// Builds the phases of a prediction: every phase holds the process and the scene; a traced phase
// also holds the tracer and the threads' scratch buffers.
struct PhaseBuilder {
    MemoryTerm process;
    MemoryTerm scene;
    MemoryTerm tracer;
    MemoryTerm threads;

    explicit PhaseBuilder(const MemoryInputs& in) {
        const uint64_t triangles = in.scene.triangles.size();
        const uint64_t vertices = in.scene.positions.size();
        process = {"the process's libraries and other data", "", in.processBytes, false, true};
        scene = {"the scene's arrays (" + count(triangles) + " triangles, " +
                     count(in.scene.images.size()) + " images)",
                 "", sceneBytes(in.scene)};
        threads = {count(in.threads) + " threads' scratch buffers", "lower --threads",
                   in.threads * kThreadBytes};
        // RayTracer's own vertices (one padding), indices (one padding) and normals.
        tracer = {"the BVH and the tracer's arrays over " + count(triangles) + " triangles", "",
                  (vertices + 1) * sizeof(glm::vec3) + (triangles + 1) * sizeof(glm::uvec3) +
                      triangles * (sizeof(glm::vec3) + kBvhBytesPerTriangle)};
    }

    MemoryPhase phase(std::string name, std::vector<MemoryTerm> terms, bool traced) const {
        MemoryPhase p{std::move(name), {process, scene}};
        if (traced) {
            p.terms.push_back(tracer);
            p.terms.push_back(threads);
        }
        for (MemoryTerm& t : terms) {
            if (t.bytes > 0) {
                p.terms.push_back(std::move(t));
            }
        }
        return p;
    }
};

// What the method keeps for every volume, and how many light samplers it holds.
struct MethodMemory {
    MemoryTerm held;
    uint64_t samplers = 1;
};

// The method's own phase (tracing the VPLs, injecting the LPV lights), added to `out`, and what
// it keeps while the volumes bake.
MethodMemory addMethodPhase(const MemoryInputs& in, const PhaseBuilder& phases,
                            MemoryPrediction& out) {
    const BakeConfig& config = in.config;
    MethodMemory method;
    if (config.method == Method::Vpl) {
        const uint64_t n = in.vplCount;
        out.phases.push_back(phases.phase("tracing the VPLs",
                                          {{"vpl.count " + count(n) + " VPLs and their light tree",
                                            "lower --vpl-count", VplGatherer::buildBytes(n)}},
                                          true));
        method.held = {"vpl.count " + count(n) + " VPLs and their light tree", "lower --vpl-count",
                       VplGatherer::heldBytes(n)};
        method.samplers =
            3; // the probe's path integrator, and the VPL integrator's direct and near
    }
    if (config.method == Method::Lpv) {
        uint64_t lights = config.lpv.vplCount;
        if (config.lpv.direct == LpvDirect::Propagated) {
            lights += 2 * uint64_t(config.lpv.vplCount); // emitter samples, both sides
        }
        constexpr uint64_t kInjected = sizeof(LpvSurfaceLight) +
                                       sizeof(std::array<glm::vec3, kEscapeRays>) +
                                       sizeof(std::array<float, kEscapeRays>);
        // prepareLpvLights: the VPL set while its lights are injected and their escape rays
        // traced.
        out.phases.push_back(
            phases.phase("injecting the LPV lights",
                         {{"lpv.vpl_count " + count(config.lpv.vplCount) + " injected lights",
                           "lower --lpv-vpl-count",
                           uint64_t(config.lpv.vplCount) * sizeof(Vpl) + lights * kInjected}},
                         true));
        method.held = {"lpv.vpl_count " + count(config.lpv.vplCount) + " injected lights",
                       "lower --lpv-vpl-count", lights * kInjected};
    }
    return method;
}

// Adds volume `i`'s probe terms to its probe phase; `done` grows by what the volume keeps.
void addProbeTerms(const MemoryInputs& in, size_t i, MemoryPhase& probes, MemoryTerm& done,
                   MemoryPrediction& out) {
    const BakeConfig& config = in.config;
    const VolumeDesc& v = in.volumes[i];
    const std::string name = volumeName(i, v);
    if (v.layout == VolumeLayout::Bricked) {
        const uint64_t level0 = latticeProbes(v, 0);
        const uint64_t working = brickedWorkingBytes(config, probes.ownBytes());
        const uint64_t every = latticeProbes(v, v.bricks.maxLevel);
        const uint64_t bound = std::min(every, std::max(level0, working / kBakedProbeBytes));
        probes.terms.push_back({name + ": " + count(level0) + " level-0 lattice probes",
                                "lower the density or resolution", level0 * kBakedProbeBytes,
                                false});
        probes.terms.push_back({name + ": refinement's probes (at most)", "",
                                (bound - level0) * kBakedProbeBytes, true});
        out.refinementBoundBytes += probes.terms.back().bytes;
        out.brickedWorkingBytes.push_back(working);
        // What the volume keeps: its level-0 bricks' probes at least.
        done.bytes += uint64_t(brick::kBrickProbeCount) * v.grid.probeCount() *
                      outputBytesPerProbe(v, config.visibility);
    } else {
        const uint64_t n = v.grid.probeCount();
        probes.terms.push_back({name + ": " + count(n) + " probes",
                                "lower the resolution or density",
                                n * denseWorkingBytesPerProbe(v, config.visibility), false});
        out.brickedWorkingBytes.push_back(0);
        done.bytes += n * outputBytesPerProbe(v, config.visibility);
    }
}

// Each volume's phases (its LPV cascades, then its probes), in bake order; `done` ends holding
// every volume's output.
void addVolumePhases(const MemoryInputs& in, const PhaseBuilder& phases, const MethodMemory& method,
                     MemoryTerm& done, MemoryPrediction& out) {
    const BakeConfig& config = in.config;
    const MemoryTerm sampler{"light sampling tables", "",
                             method.samplers * lightSamplerBytes(in.scene)};
    for (size_t i = 0; i < in.volumes.size(); ++i) {
        const VolumeDesc& v = in.volumes[i];
        const std::string label = "volumes[" + std::to_string(i) + "]";
        MemoryTerm cascades;
        if (config.method == Method::Lpv) {
            const LpvVolumeBytes lpv = lpvVolumeBytes(in.scene, config.lpv, v);
            const std::string what = count(lpv.cells) + " cells of lpv.grid " +
                                     count(config.lpv.grid) + " x lpv.cascades " +
                                     count(config.lpv.cascades);
            const std::string advice = "lower --lpv-grid or --lpv-cascades";
            out.phases.push_back(phases.phase("propagating " + label + "'s cascades",
                                              {method.held, done, {what, advice, lpv.peak}}, true));
            cascades = {what, advice, lpv.kept};
        }
        MemoryPhase probes = phases.phase("baking " + label + "'s probes",
                                          {method.held, done, cascades, sampler}, true);
        addProbeTerms(in, i, probes, done, out);
        out.phases.push_back(std::move(probes));
    }
}

} // namespace

MemoryPrediction predictBakeMemory(const MemoryInputs& in) {
    const PhaseBuilder phases(in);
    MemoryPrediction out;
    MemoryTerm build_term = phases.tracer;
    const uint64_t triangles = in.scene.triangles.size();
    build_term.what = "the BVH build over " + count(triangles) + " triangles";
    build_term.bytes += triangles * (kBvhBuildBytesPerTriangle - kBvhBytesPerTriangle);
    out.phases.push_back(phases.phase("building the BVH", {build_term}, false));

    const MethodMemory method = addMethodPhase(in, phases, out);
    MemoryTerm done{"the volumes baked before", "", 0};
    addVolumePhases(in, phases, method, done, out);
    // probekit bake encodes the file after bake() has freed the tracer and the method.
    MemoryTerm encoded = done;
    encoded.what = "the encoded file's bytes";
    done.what = "the baked volumes";
    out.phases.push_back(phases.phase("writing the file", {done, encoded}, false));

    for (size_t i = 0; i < out.phases.size(); ++i) {
        const uint64_t bytes = out.phases[i].bytes();
        if (bytes > out.peakBytes) {
            out.peakBytes = bytes;
            out.peakPhase = i;
        }
    }
    return out;
}

std::string formatBytes(uint64_t bytes) {
    char text[32];
    if (bytes >= (1ull << 30)) {
        std::snprintf(text, sizeof text, "%.1f GiB", double(bytes) / double(1ull << 30));
    } else {
        std::snprintf(text, sizeof text, "%.0f MiB", double(bytes) / double(1ull << 20));
    }
    return text;
}

Result<void> checkBakeMemory(const MemoryPrediction& prediction, const BakeConfig& config) {
    const uint64_t limit = std::max(config.maxMemoryBytes, kMinWorkingBytes);
    // Bricked refinement shrinks to the room left, so it never makes a bake fail.
    const MemoryPhase* worst = nullptr;
    uint64_t worst_bytes = 0;
    for (const MemoryPhase& p : prediction.phases) {
        const uint64_t bytes = p.ownBytes(false);
        if (bytes > worst_bytes) {
            worst_bytes = bytes;
            worst = &p;
        }
    }
    if (worst == nullptr || worst_bytes <= limit) {
        return {};
    }
    std::vector<MemoryTerm> terms;
    for (const MemoryTerm& t : worst->terms) {
        if (!t.external) {
            terms.push_back(t);
        }
    }
    std::stable_sort(terms.begin(), terms.end(),
                     [](const MemoryTerm& a, const MemoryTerm& b) { return a.bytes > b.bytes; });
    std::string message =
        "the bake's predicted peak memory " + formatBytes(worst_bytes) + " (" + worst->name +
        ") exceeds max_memory_mb = " + std::to_string(config.maxMemoryBytes >> 20) + ":";
    std::string advice;
    // The largest term, and the next ones while they hold a quarter of the peak.
    for (size_t i = 0; i < terms.size() && (i == 0 || terms[i].bytes * 4 >= worst_bytes); ++i) {
        message += (i == 0 ? " " : "; ") + terms[i].what + " need " + formatBytes(terms[i].bytes);
        if (!terms[i].advice.empty() && advice.find(terms[i].advice) == std::string::npos) {
            advice += terms[i].advice + ", or ";
        }
    }
    return makeError(ErrorCode::OutOfRange, message + " (" + advice + "raise --max-memory)");
}

} // namespace probekit::baker
