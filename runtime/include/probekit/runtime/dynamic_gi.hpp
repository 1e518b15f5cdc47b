// probekit::runtime::DynamicGi — runtime dynamic GI: one to four camera-centred light
// propagation volumes (cascades) relit in Vulkan compute when lights, sky, geometry or the
// camera change, sampled per pixel by the Renderer beside (or instead of) baked volumes.
//
// What the cascades carry: the sky's light (entering through each cascade's border and
// propagated, blocked by the geometry) and the light the given lights and the sky reflect off
// the geometry, `bounces` times; not the lights' direct light, which the renderer shades itself
// (FrameSettings::directLight) with the sun's visibility marched through the geometry volume.
// Combining with a baked volume without counting light twice: a light is either baked or given
// to DynamicGi, never both; the renderer adds the two irradiances (docs/runtime.md#dynamic-gi).
//
// Every compute stage has a CPU twin in runtime/src/gi_twin.hpp (its specification and the
// GPU tests' oracle).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>
#include <vulkan/vulkan.h>

#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/runtime/gpu_context.hpp"
#include "probekit/runtime/renderer.hpp"

namespace probekit::runtime {

constexpr uint32_t kMaxGiCascades = 4;
constexpr uint32_t kMaxGiLights = 8;

enum class GiQuality : uint32_t {
    L1 = 0,      // the cascades' L1 radiance as it is
    L1Zonal = 1, // plus a zonal band 2 hallucinated from L1 (gi_twin.hpp, giZonal)
};

struct DynamicGiSettings {
    uint32_t cascades = 1;          // 1..4, cascade k has cellSize x 2^k
    uint32_t resolution = 32;       // cells per axis: 32 or 64
    float cellSize = 0.25f;         // metres, finest cascade (> 0)
    uint32_t iterations = 16;       // propagation steps per bounce (1..256)
    uint32_t bounces = 1;           // surface bounces (1..4)
    uint32_t updateInterval = 1;    // frames between updates (>= 1; 1 = whenever dirty)
    float fadeCells = 2.0f;         // fade at each cascade's border, cells (>= 0)
    float propagationWeight = 1.0f; // (0, 1]
    GiQuality quality = GiQuality::L1;
    // How far ahead of the camera each cascade's centre lies, as a fraction of its width.
    float aheadFraction = 0.25f;
    // Dirty thresholds: a light's direction (radians) or position (cells of the finest cascade),
    // its colour and the sky (largest relative change of any channel or coefficient).
    float angleThreshold = 0.01f;
    float positionThreshold = 0.25f;
    float colourThreshold = 0.01f;
};

// What one recordUpdate call recorded.
struct GiUpdateStats {
    uint32_t dispatches = 0;      // compute dispatches recorded (0 on a frame with nothing to do)
    uint32_t cascadesUpdated = 0; // cascades relit
    bool geometryRebuilt = false; // at least one cascade's geometry volume was rebuilt
};

// GPU milliseconds of the last update's stages, summed over cascades; NaN when none ran or the
// queue has no timestamps.
struct GiTimings {
    double occupancyMs = std::numeric_limits<double>::quiet_NaN(); // geometry volume
    double injectMs = std::numeric_limits<double>::quiet_NaN();    // surfaces + inject
    double propagateMs = std::numeric_limits<double>::quiet_NaN(); // propagate + reduce
    double resolveMs = std::numeric_limits<double>::quiet_NaN();
};

// One cascade's placement (world min corner, cell size, cells per axis).
struct GiCascadePlacement {
    glm::vec3 origin{0.0f};
    float cellSize = 0.25f;
    uint32_t cells = 32;
};

// The cascades' placement for a camera: cascade k's cell size is cellSize x 2^k; its centre is
// the camera position plus aheadFraction x its width along `forward` (unit), and its origin is
// that centre minus half its width snapped down to its own cell lattice (multiples of its cell
// size from the world origin), so that static geometry does not shimmer as the camera moves.
std::vector<GiCascadePlacement> placeGiCascades(const DynamicGiSettings& settings, glm::vec3 camera,
                                                glm::vec3 forward);

// What the shading pass needs (Renderer::render's dynamicGi): per cascade the device buffer of
// its radiance (12 planes of resolution^3 floats, gi_twin.hpp's GiField layout) and placement.
struct GiShadingInputs {
    std::array<VkBuffer, kMaxGiCascades> radiance{};
    std::array<GiCascadePlacement, kMaxGiCascades> placement{};
    uint32_t cascades = 0;
    float fadeCells = 2.0f;
    GiQuality quality = GiQuality::L1;
    // The geometry volume of the finest cascade, for the sun's visibility in the shading pass
    // (17 int32 per cell, gi_geometry.hpp's GiGeometryCell, (resolution + 1)^3 cells).
    VkBuffer geometry = VK_NULL_HANDLE;
};

class DynamicGi {
public:
    // Fails with InvalidArgument on settings outside their ranges. The context must outlive
    // the object.
    static Result<DynamicGi> create(GpuContext& context, const DynamicGiSettings& settings);

    DynamicGi(DynamicGi&&) noexcept;
    DynamicGi& operator=(DynamicGi&&) noexcept;
    ~DynamicGi();

    // The triangles (three indices each) whose geometry blocks and reflects light, in the
    // Renderer's vertex format; replaces earlier ones and marks every cascade dirty. Fails with
    // OutOfRange on an index past the vertices or a count not a multiple of three.
    Result<void> setGeometry(std::span<const RenderVertex> vertices,
                             std::span<const uint32_t> indices);
    // The dynamic lights (at most kMaxGiLights; OutOfRange beyond). Dirty when a light was added
    // or removed or one changed beyond the thresholds.
    Result<void> setLights(std::span<const PunctualLight> lights);
    // The sky's radiance SH (L2; the direction light comes from), or black for none.
    void setSky(const sh::ShRgb& radiance);
    // New tuning: everything but cascades, resolution and cellSize (InvalidArgument when those
    // differ, or on a setting outside its range). A change of iterations, bounces or
    // propagationWeight marks every cascade dirty (the weight also rebuilds the geometry
    // volume's keep factors); the others take effect without a relight (fade and quality in the
    // next frame's shading, thresholds, interval and aheadFraction at the next recordUpdate).
    Result<void> setTuning(const DynamicGiSettings& settings);
    // Camera position and unit forward direction: where the cascades are placed.
    void setCamera(glm::vec3 position, glm::vec3 forward);

    // Records into `cmd` the updates that are due: a cascade is due when it is dirty (its
    // placement moved, geometry, lights, sky or the transport's tuning changed) and at least
    // updateInterval frames have passed since the last update (the first update is always due). The
    // buffers the shading pass reads are written by the end of the recorded commands (a barrier to
    // the compute shader stage is recorded after them). The command buffer must be submitted before
    // the next recordUpdate; timings() then reads that submission's timestamps.
    Result<GiUpdateStats> recordUpdate(VkCommandBuffer cmd, uint64_t frame);
    // recordUpdate in a one-time command buffer, submitted and waited for.
    Result<GiUpdateStats> update(uint64_t frame);

    GiTimings timings() const;
    // Bytes of GPU memory the cascades' buffers hold (all float32 and int32: the twin's layouts;
    // docs/runtime.md#dynamic-gi).
    uint64_t gpuBytes() const;
    GiShadingInputs shadingInputs() const;
    const DynamicGiSettings& settings() const;
    std::vector<GiCascadePlacement> placements() const;

    // Test and debug access: reads back a cascade's radiance (GiField layout) and geometry
    // volume (GiGeometryCell layout, as 17 int32 per cell).
    Result<std::vector<float>> readRadiance(uint32_t cascade) const;
    Result<std::vector<int32_t>> readGeometry(uint32_t cascade) const;

private:
    struct Impl;
    explicit DynamicGi(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> m_impl;
};

} // namespace probekit::runtime
