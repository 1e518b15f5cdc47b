// probekit::runtime::Renderer — a small headless deferred renderer for tools and tests.
//
// Pass 1 (G-buffer, rasterised): the environment behind everything (shaded and probes views),
// then triangle meshes -> world position, world normal (the vertex normals interpolated per pixel,
// turned to the side the camera sees: surfaces are two-sided, as the baker treats them), albedo
// (the vertex's base colour factor times the triangle's base-colour texture sampled per pixel at
// the interpolated uv), emission and an id; in the probes and validity views also one sphere per
// probe for a budget of probes (probeBudget). Pass 2 (shading, compute): per pixel,
// pk_irradiance (shaders/probe_volume.glsl) at the G-buffer position and normal, then the view's
// output; the result lands in an RGBA32F image that is read back to the caller. Each pass is
// timed with GPU timestamps.
//
// The renderer knows nothing of glTF: callers pass plain triangle arrays (the probekit tool
// loads scenes through probekit::baker and flattens them).
//
// Frame and units: glTF world (metres, +Y up). Outputs are linear (tone mapping for display is
// tonemap.hpp's, applied by the caller): radiance W/(sr m^2) in the shaded, probes and validity
// views (the environment's radiance where no geometry is), irradiance E W/m^2 in the irradiance
// view, a colour ramp of a dimensionless share in the leak view.
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

#include "probekit/formats/environment.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/runtime/gpu_context.hpp"
#include "probekit/runtime/gpu_volumes.hpp"

namespace probekit::runtime {

struct GiShadingInputs; // dynamic_gi.hpp

// One mesh vertex, world space. The normal is interpolated across the triangle per pixel
// (smooth shading; for flat shading give each triangle its own three vertices with the face
// normal); it need not be unit length, and which side it points to does not matter (the G-buffer
// turns it to the side the camera sees).
struct RenderVertex {
    glm::vec3 position{0.0f}; // metres
    glm::vec3 normal{0.0f, 1.0f, 0.0f};
    glm::vec3 albedo{0.8f};   // linear Lambertian albedo (factor) per channel, in [0, 1]
    glm::vec3 emission{0.0f}; // emitted radiance, W/(sr m^2) (added in the shaded views)
    glm::vec2 uv{0.0f};       // glTF texture coordinates of the triangle's base-colour texture
};
static_assert(sizeof(RenderVertex) == 56, "vertex buffers are tightly packed RenderVertex");

// Textures: at most this many (one descriptor set each, so no descriptor-indexing feature is
// needed), each at most maxImageDimension2D a side. Stored as RGBA16F (linear filtering of it is
// required of every Vulkan device), sampled with LINEAR filtering, REPEAT addressing and no
// mipmaps: RgbaImage::sampleBilinear (formats/environment.hpp) is the CPU twin.
constexpr size_t kMaxRenderTextures = 1024;

struct Camera {
    glm::vec3 eye{0.0f, 0.0f, 3.0f}; // metres, world
    glm::vec3 target{0.0f};          // the point at the image centre
    glm::vec3 up{0.0f, 1.0f, 0.0f};  // roughly up; need not be orthogonal to the view
    float verticalFovDeg = 45.0f;    // degrees, full vertical angle
    float nearPlane = 0.01f;         // metres, > 0
    float farPlane = 1000.0f;        // metres, > nearPlane
};

// The default view of a scene: from the box's `side` (a unit axis: +Z by default, since glTF
// assets face +Z, so a model's front and its text show unmirrored, +X to the right), looking
// back at the box's centre from far enough that the box's face on that side fits both
// field-of-view angles with a 10% margin. Up is +Y (for the +-Y sides, -Z and +Z: the image's
// top is then the far side). The bundled Cornell box is open towards -Z: side (0, 0, -1) gives
// its classic front view.
Camera frameBounds(const grid::Aabb& bounds, float vertical_fov_deg, float aspect,
                   glm::vec3 side = glm::vec3(0.0f, 0.0f, 1.0f));

// The unit world direction of the ray through image point `pixel` (pixel (x, y)'s centre is
// (x + 0.5, y + 0.5); row 0 is the top). CPU twin of pk_pixel_direction (shaders/
// background.frag), which reads the environment behind the geometry.
glm::vec3 pixelDirection(const Camera& camera, uint32_t width, uint32_t height, glm::vec2 pixel);

// The probes and validity views draw at most this many probe spheres: one per 8 x 8 pixels of
// the image, so that spheres never crowd into a moire and a 5 M-probe volume costs the G-buffer
// what a few thousand spheres do. How probes are chosen (Renderer::render): those whose sphere
// is in front of the camera and inside the image; if more than the budget, only those whose
// lattice coordinates (grid coordinates, or a bricked volume's finest-level lattice) are all
// multiples of the smallest power of two s that brings the count within it (a regular sub-grid
// every s-th probe, so the coarse bricks of a bricked volume outlast the fine ones; in the
// validity view invalid probes are always kept, as far as the budget allows); each drawn sphere
// has radius s x 0.15 x its probe spacing (or FrameSettings::probeRadius), and at least
// kMinProbeRadiusPixels on screen.
constexpr uint32_t kProbePixels = 64;
constexpr float kMinProbeRadiusPixels = 1.5f;
uint32_t probeBudget(uint32_t width, uint32_t height);

enum class RenderView : uint32_t {
    Shaded = 0,     // albedo / pi x (E + direct light when asked) + emission
    Irradiance = 1, // E itself
    Probes = 2,     // Shaded, plus probes (probeBudget) as spheres lit by their own SH
                    // (white albedo); bricked volumes' probes are flat spheres coloured by
                    // their brick's level: 0 blue, 1 green, 2 yellow, 3 magenta (radius 0.15 x
                    // that brick's probe spacing), so the adaptive refinement shows
    Validity = 3,   // probe spheres only (none hidden by walls; probeBudget): valid ones lit
                    // by their SH, invalid ones flat red
    Leak = 4,       // the visible share v of the trilinear weight (runtime::visibleWeight,
                    // blended over volumes as irradiance is: pk_visible_weight) as the ramp
                    // rgb = (1, v, v): white where no interpolation tap is hidden (v = 1, also
                    // everywhere for volumes without visibility), red where every tap is
                    // (v = 0, plain trilinear interpolation would leak light through a wall)
    // Dynamic GI debug views (FrameSettings::dynamicGi required):
    GiIrradiance = 5, // the cascades' irradiance alone, W/m^2
    GiGeometry = 6,   // the geometry volume at the surface: mean albedo x min(1, area / s^2)
    GiAo = 7,         // the geometry volume's openness half a cell in front of the surface:
                      // 1 - the blocking along the six axes, averaged (grey)
};

constexpr size_t kMaxRenderLights = 8;

struct FrameSettings {
    uint32_t width = 640;  // pixels, 1..maxImageDimension2D
    uint32_t height = 480; // pixels
    Camera camera;
    RenderView view = RenderView::Shaded;
    // Add direct light from `lights` (for volumes baked without it, e.g. lights in light mode
    // indirect): per pixel the sum of irradianceAt (formats/light.hpp) over the lights that
    // reach it, which the shading pass mirrors (pk_direct_irradiance, shaders/shade.comp).
    // Shaded and irradiance views; the light's name is not used.
    bool directLight = false;
    std::vector<PunctualLight> lights; // at most kMaxRenderLights
    // Shadows of `lights`: empty = every light reaches every pixel (unshadowed); else one mask
    // per pixel (x + width * y), bit i set where lights[i] reaches the pixel's surface point, as
    // a ray tracer finds it from a frame's G-buffer (viewer::lightVisibility).
    std::vector<uint32_t> lightVisibility;
    // Probe sphere radius in metres before decimation (probeBudget); 0 = 0.15 x each volume's
    // smallest probe spacing.
    float probeRadius = 0.0f;
    // Draw the environment set by Renderer::setEnvironment where no geometry is (shaded and
    // probes views; the others keep a black background).
    bool showEnvironment = true;
    // Benchmark variant: the shading pass performs only pk_irradiance's texture fetches
    // (pk_fetch_only); the image is meaningless, the timing is the floor of the real pass.
    bool fetchOnly = false;
    // Dynamic GI (dynamic_gi.hpp; the object must outlive the render call): its cascades'
    // irradiance is added to the volumes' (bakedLight true) or replaces it (false), and, with
    // directLight and giShadowSun, the directional lights' direct light is shadowed by marching
    // the finest cascade's geometry volume (gi_twin.hpp, giSunVisibility). The probes, validity
    // and leak views ignore it.
    const GiShadingInputs* dynamicGi = nullptr;
    bool bakedLight = true;
    bool giShadowSun = true;
    bool readbackColor = true;    // fill Frame::color
    bool readbackGBuffer = false; // fill Frame::position and Frame::normal
};

// What the probes and validity views drew (probeBudget's rule).
struct ProbeStats {
    uint64_t total = 0;  // probes in the volumes
    uint64_t inView = 0; // of those, in front of the camera and inside the image
    uint64_t drawn = 0;  // spheres drawn, at most the budget
    uint32_t budget = 0; // probeBudget(width, height)
    uint32_t stride = 1; // every stride-th probe along each lattice axis
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
                                     // (whose rgb is the environment's radiance, or 0)
    std::vector<glm::vec4> position; // world position (m), w = 1 on geometry, 0 background
    std::vector<glm::vec4> normal;   // unit world normal the shading used (facing the camera)
    FrameTimings timings;
    ProbeStats probes; // probes and validity views
};

class Renderer {
public:
    // Builds pipelines (lavapipe compiles shaders on first use: render a frame before timing).
    // The context must outlive the renderer.
    static Result<Renderer> create(GpuContext& context);

    Renderer(Renderer&&) noexcept;
    Renderer& operator=(Renderer&&) noexcept;
    ~Renderer();

    // Uploads the base-colour textures (linear RGBA, e.g. the baker Scene's decoded images) that
    // setMeshes's triangles refer to, replacing earlier ones and dropping the meshes (call
    // setMeshes after it). Fails with OutOfRange beyond kMaxRenderTextures textures or on an
    // empty or oversized image.
    Result<void> setTextures(std::span<const RgbaImage> images);

    // Uploads the triangle list drawn by later frames (indices into vertices, three per
    // triangle), replacing earlier meshes. `triangle_textures` is empty (no textures) or holds
    // per triangle an index into setTextures's images or -1 (none: the albedo is the vertices'
    // factor alone). Fails with OutOfRange on an index past the vertices or the textures, or a
    // count not a multiple of three or not one texture per triangle.
    Result<void> setMeshes(std::span<const RenderVertex> vertices,
                           std::span<const uint32_t> indices,
                           std::span<const int32_t> triangle_textures = {});

    // The environment drawn behind the geometry (FrameSettings::showEnvironment): a constant or
    // a lat-long image (uploaded as RGBA16F, so radiance above 65504 is clamped), radiance
    // W/(sr m^2) as Environment::radiance gives it, its CPU twin. A black one draws nothing.
    Result<void> setEnvironment(const Environment& environment);

    // Renders one frame with the volumes as they are now (records their pending uniform
    // update), waits for it and reads back what `settings` asks for.
    Result<Frame> render(GpuVolumeSet& volumes, const FrameSettings& settings);

private:
    struct Impl;
    explicit Renderer(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> m_impl;
};

} // namespace probekit::runtime
