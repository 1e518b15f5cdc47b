// probekit headless renderer: GPU layout of its frame uniforms and G-buffer encoding, shared by
// C++ (runtime/src/renderer*.cpp) and GLSL (gbuffer.*, probe_sphere.vert, shade.comp). As in
// probe_volume_layout.h, every member is a 16-byte row so std140 adds no padding, and C++
// static_asserts every offset.
//
// Units: metres, glTF world frame; light intensities as formats/CONVENTIONS.md states (point
// and spot: W/sr, directional: W/m^2).
#ifndef PROBEKIT_RENDER_LAYOUT_H
#define PROBEKIT_RENDER_LAYOUT_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>

#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>

namespace probekit::gpu {
using mat4 = glm::mat4;
using vec4 = glm::vec4;
using uvec4 = glm::uvec4;
#endif

#define PK_MAX_LIGHTS 8

// PkFrameGpu.info.x: what the shading pass writes.
#define PK_VIEW_SHADED 0u      // albedo / pi x (E + direct) + emission, W/(sr m^2)
#define PK_VIEW_IRRADIANCE 1u  // E, W/m^2
#define PK_VIEW_PROBES 2u      // surfaces shaded, probe spheres lit by their own SH
#define PK_VIEW_VALIDITY 3u    // probe spheres only: valid ones lit by their SH, invalid ones red
#define PK_VIEW_LEAK 4u        // visible share v of the trilinear weight: rgb (1, v, v)
#define PK_VIEW_GI 5u          // the dynamic GI cascades' irradiance alone, W/m^2
#define PK_VIEW_GI_GEOMETRY 6u // the geometry volume: mean albedo x min(1, area / s^2)
#define PK_VIEW_GI_AO 7u       // the geometry volume's occlusion in front of the surface: grey

// PkFrameGpu.info.w: flags for the dynamic GI's second shading pass (gi_shade.comp).
#define PK_FRAME_NO_BAKED 1u        // leave the volumes' irradiance out (dynamic GI alone)
#define PK_FRAME_GI_DIRECTIONAL 2u  // directional lights' direct light is the GI pass's

// PkFrameGpu.environmentInfo.x: what the background pass draws where no geometry is.
#define PK_ENV_NONE 0u     // nothing (the G-buffer stays cleared: black)
#define PK_ENV_CONSTANT 1u // PkFrameGpu.environment.rgb
#define PK_ENV_LATLONG 2u  // the lat-long image times PkFrameGpu.environment.rgb (the intensity)

// Largest binary16 value: the G-buffer's emission target holds the background radiance.
#define PK_HALF_MAX 65504.0

// The light mask (G-buffer pass, set 0, binding 1; one uint per pixel, x + width * y): bit i set
// where lights[i] reaches the pixel's surface point. The renderer fills it with every bit set
// unless FrameSettings::lightVisibility gives the traced visibility (shadows). gbuffer.frag
// copies a surface pixel's mask into bits 8..15 of its id (PK_KIND_SURFACE carries no probe),
// which shade.comp reads: the shading pass's stage has no resource to spare on lavapipe
// (maxPerStageResources 128, nearly all the volume slots' textures).
#define PK_LIGHT_MASK_BINDING 1
#define PK_LIGHT_MASK_SHIFT 8u

// PkLightGpu.info.x.
#define PK_LIGHT_POINT 0u
#define PK_LIGHT_SPOT 1u
#define PK_LIGHT_DIRECTIONAL 2u

// The G-buffer id attachment (R32_UINT): bits 0..1 kind, bit 2 probe validity, bits 3..5 volume
// slot, bits 8..31 the probe: dense volumes grid coordinates x | y << 8 | z << 16 (each < 256);
// bricked volumes the probe index brick * 64 + k (< 2^24), with the brick's level in bits 6..7.
#define PK_KIND_NONE 0u
#define PK_KIND_SURFACE 1u
#define PK_KIND_PROBE 2u

struct PkLightGpu {
    vec4 position;  // bytes  0..15: xyz position (m); w = range (m, 0 = infinite)
    vec4 direction; // bytes 16..31: xyz unit direction the light travels; w = cos(inner cone)
    vec4 intensity; // bytes 32..47: rgb W/sr (point, spot) or W/m^2 (directional); w = cos(outer)
    uvec4 info;     // bytes 48..63: x = PK_LIGHT_*; yzw zero
};

struct PkFrameGpu {
    mat4 viewProjection;              // bytes   0..63: world -> clip (Vulkan clip space)
    vec4 eye;                         // bytes  64..79: camera position (m); w = 1
    uvec4 info;                       // bytes  80..95: x = PK_VIEW_*, y = light count,
                                      //   z = add direct light (0/1), w = 0
    uvec4 size;                       // bytes 96..111: x = width, y = height (pixels)
    PkLightGpu lights[PK_MAX_LIGHTS]; // bytes 112..623
    // The camera's basis scaled to the image plane at distance 1 (runtime::pixelDirection):
    vec4 cameraRight;      // bytes 624..639: xyz right x tan(fov / 2) x aspect
    vec4 cameraUp;         // bytes 640..655: xyz up x tan(fov / 2)
    vec4 cameraForward;    // bytes 656..671: xyz unit view direction
    vec4 environment;      // bytes 672..687: rgb constant radiance x intensity
                           //   (constant) or the intensity (lat-long), W/(sr m^2);
                           //   w = rotation about +Y, radians
    uvec4 environmentInfo; // bytes 688..703: x = PK_ENV_*; yzw zero
};

// The dynamic GI's shading inputs (gi_shade.comp, binding 5; runtime::GiShadingInputs).
#define PK_MAX_GI_CASCADES 4
struct PkGiCascadeGpu {
    vec4 origin; // xyz world min corner (m); w = cell size (m)
    uvec4 info;  // x = cells per axis; yzw zero
};
struct PkGiGpu {
    PkGiCascadeGpu cascades[PK_MAX_GI_CASCADES]; // bytes 0..127, finest first
    uvec4 info;  // bytes 128..143: x = cascades, y = quality (0 L1, 1 L1 + zonal),
                 //   z = 0, w = shade the directional lights' direct light, shadowed through
                 //   the finest cascade's geometry volume (0/1)
    vec4 params; // bytes 144..159: x = fade (cells); yzw zero
};

#ifdef __cplusplus
static_assert(offsetof(PkGiGpu, info) == 128);
static_assert(sizeof(PkGiGpu) == 160);
static_assert(sizeof(mat4) == 64, "GLM matrices must be tightly packed (column-major)");
static_assert(offsetof(PkLightGpu, position) == 0);
static_assert(offsetof(PkLightGpu, direction) == 16);
static_assert(offsetof(PkLightGpu, intensity) == 32);
static_assert(offsetof(PkLightGpu, info) == 48);
static_assert(sizeof(PkLightGpu) == 64);
static_assert(offsetof(PkFrameGpu, viewProjection) == 0);
static_assert(offsetof(PkFrameGpu, eye) == 64);
static_assert(offsetof(PkFrameGpu, info) == 80);
static_assert(offsetof(PkFrameGpu, size) == 96);
static_assert(offsetof(PkFrameGpu, lights) == 112);
static_assert(offsetof(PkFrameGpu, cameraRight) == 624);
static_assert(offsetof(PkFrameGpu, cameraUp) == 640);
static_assert(offsetof(PkFrameGpu, cameraForward) == 656);
static_assert(offsetof(PkFrameGpu, environment) == 672);
static_assert(offsetof(PkFrameGpu, environmentInfo) == 688);
static_assert(sizeof(PkFrameGpu) == 112 + 64 * PK_MAX_LIGHTS + 80);
} // namespace probekit::gpu
#endif

#endif
