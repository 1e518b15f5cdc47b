// probekit::runtime::Renderer — a small headless deferred renderer for tools and tests.
//
// Pass 1 (G-buffer, rasterised): triangle meshes -> world position, world normal (turned to face
// the camera: surfaces are two-sided, as the baker treats them), albedo, emission and an id; in the
// probes and validity views also one small sphere per probe. Pass 2 (shading, compute): per pixel,
// pk_irradiance (shaders/probe_volume.glsl) at the G-buffer position and normal, then the view's
// output; the result lands in an RGBA32F image that is read back to the caller. Each pass is
// timed with GPU timestamps.
//
// The renderer knows nothing of glTF: callers pass plain triangle arrays (the probekit tool
// loads scenes through probekit::baker and flattens them).
//
// Frame and units: glTF world (metres, +Y up). Outputs are linear: radiance W/(sr m^2) in the
// shaded, probes and validity views, irradiance E W/m^2 in the irradiance view, a colour ramp
// of a dimensionless share in the leak view.
//
// Sets whose volumes have no visibility (GpuVolumeSet::anyVisibility false) are shaded by
// pipelines with the visibility path specialised out (pk_visibility_mode PK_VISIBILITY_OFF,
// shaders/probe_volume.glsl), so they cost what they did before visibility existed; sets with
// visibility by PK_VISIBILITY_TAPS pipelines on CPU devices (lavapipe, which runs both sides of
// uniform branches: every volume tap by tap, no filtered fetch) and PK_VISIBILITY_BRANCH ones
// elsewhere (volumes without visibility keep the hardware filter).
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "probekit/formats/grid.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/runtime/gpu_context.hpp"
#include "probekit/runtime/gpu_volumes.hpp"

namespace probekit::runtime {

// One mesh vertex, world space. Flat shading: give each triangle its own three vertices with
// the face normal.
struct RenderVertex {
    glm::vec3 position{0.0f}; // metres
    glm::vec3 normal{0.0f, 1.0f, 0.0f};
    glm::vec3 albedo{0.8f};   // linear Lambertian albedo per channel, in [0, 1]
    glm::vec3 emission{0.0f}; // emitted radiance, W/(sr m^2) (added in the shaded views)
};
static_assert(sizeof(RenderVertex) == 48, "vertex buffers are tightly packed RenderVertex");

struct Camera {
    glm::vec3 eye{0.0f, 0.0f, 3.0f}; // metres, world
    glm::vec3 target{0.0f};          // the point at the image centre
    glm::vec3 up{0.0f, 1.0f, 0.0f};  // roughly up; need not be orthogonal to the view
    float verticalFovDeg = 45.0f;    // degrees, full vertical angle
    float nearPlane = 0.01f;         // metres, > 0
    float farPlane = 1000.0f;        // metres, > nearPlane
};

// The default view of a scene: looking along +Z at the box's centre, from far enough on its
// -Z side that the whole box fits both field-of-view angles with a 10% margin (for the bundled
// Cornell box, which is open at z = 0, that is the classic front view).
Camera frameBounds(const grid::Aabb& bounds, float vertical_fov_deg, float aspect);

enum class RenderView : uint32_t {
    Shaded = 0,     // albedo / pi x (E + direct light when asked) + emission
    Irradiance = 1, // E itself
    Probes = 2,     // Shaded, plus each probe as a sphere lit by its own SH (white albedo);
                    // bricked volumes' probes are flat spheres coloured by their brick's
                    // level: 0 blue, 1 green, 2 yellow, 3 magenta (radius 0.15 x that
                    // brick's probe spacing), so the adaptive refinement shows
    Validity = 3,   // probe spheres only (none hidden by walls): valid ones lit by their SH,
                    // invalid ones flat red
    Leak = 4,       // the visible share v of the trilinear weight (runtime::visibleWeight,
                    // blended over volumes as irradiance is: pk_visible_weight) as the ramp
                    // rgb = (1, v, v): white where no interpolation tap is hidden (v = 1, also
                    // everywhere for volumes without visibility), red where every tap is
                    // (v = 0, plain trilinear interpolation would leak light through a wall)
};

constexpr size_t kMaxRenderLights = 8;

struct FrameSettings {
    uint32_t width = 640;  // pixels, 1..maxImageDimension2D
    uint32_t height = 480; // pixels
    Camera camera;
    RenderView view = RenderView::Shaded;
    // Add unshadowed direct light from `lights` (for volumes baked without it): per pixel the
    // sum of irradianceAt (formats/light.hpp) over the lights, which the shading pass mirrors
    // (pk_direct_irradiance, shaders/shade.comp). Shaded and probes views only; the light's
    // name is not used.
    bool directLight = false;
    std::vector<PunctualLight> lights; // at most kMaxRenderLights
    // Probe sphere radius in metres; 0 = 0.15 x each volume's smallest probe spacing.
    float probeRadius = 0.0f;
    // Benchmark variant: the shading pass performs only pk_irradiance's texture fetches
    // (pk_fetch_only); the image is meaningless, the timing is the floor of the real pass.
    bool fetchOnly = false;
    bool readbackColor = true;    // fill Frame::color
    bool readbackGBuffer = false; // fill Frame::position and Frame::normal
};

struct FrameTimings {
    // GPU time of each pass in milliseconds; NaN when the queue has no timestamps.
    double gbufferMs = std::numeric_limits<double>::quiet_NaN();
    double shadeMs = std::numeric_limits<double>::quiet_NaN();
};

// Pixel (x, y) at index x + width * y; row 0 is the top of the image.
struct Frame {
    uint32_t width = 0;
    uint32_t height = 0;
    std::vector<glm::vec4> color;    // rgb as the view says; alpha 1 on geometry, 0 background
    std::vector<glm::vec4> position; // world position (m), w = 1 on geometry, 0 background
    std::vector<glm::vec4> normal;   // unit world normal the shading used (facing the camera)
    FrameTimings timings;
};

class Renderer {
public:
    // Builds pipelines (lavapipe compiles shaders on first use: render a frame before timing).
    // The context must outlive the renderer.
    static Result<Renderer> create(GpuContext& context);

    Renderer(Renderer&&) noexcept;
    Renderer& operator=(Renderer&&) noexcept;
    ~Renderer();

    // Uploads the triangle list drawn by later frames (indices into vertices, three per
    // triangle), replacing earlier meshes. Fails with OutOfRange on an index past the vertices
    // or a count not a multiple of three.
    Result<void> setMeshes(std::span<const RenderVertex> vertices,
                           std::span<const uint32_t> indices);

    // Renders one frame with the volumes as they are now (records their pending uniform
    // update), waits for it and reads back what `settings` asks for.
    Result<Frame> render(GpuVolumeSet& volumes, const FrameSettings& settings);

private:
    struct Impl;
    explicit Renderer(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> m_impl;
};

} // namespace probekit::runtime
