#version 450
// G-buffer pass, background (drawn first, without depth, so geometry covers it): the
// environment's radiance along each pixel's view direction goes to the emission target with id
// PK_KIND_NONE, which the shading pass passes through as the pixel's colour (alpha 0). Radiance
// units W/(sr m^2) (formats/CONVENTIONS.md); the lat-long mapping is formats/environment.hpp's.
#extension GL_GOOGLE_include_directive : require
#include "render_layout.h"

layout(std140, set = 0, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};
// The lat-long image (a 1 x 1 placeholder for a constant environment): LINEAR, REPEAT.
layout(set = 1, binding = 0) uniform sampler2D pk_environment_map;

layout(location = 0) out vec4 g_position;
layout(location = 1) out vec4 g_normal;
layout(location = 2) out vec4 g_albedo;
layout(location = 3) out vec4 g_emission;
layout(location = 4) out uint g_id;

const float PK_PI_F = 3.14159265358979;

// The unit direction through image point `pixel` (gl_FragCoord.xy: pixel centres at + 0.5).
// CPU twin: runtime::pixelDirection (runtime/include/probekit/runtime/renderer.hpp).
vec3 pk_pixel_direction(vec2 pixel) {
    const vec2 ndc = vec2(2.0 * pixel.x / float(pk_frame.size.x) - 1.0,
                          1.0 - 2.0 * pixel.y / float(pk_frame.size.y));
    return normalize(pk_frame.cameraForward.xyz + ndc.x * pk_frame.cameraRight.xyz +
                     ndc.y * pk_frame.cameraUp.xyz);
}

// The lat-long (u, v) of a unit direction, the map turned by `rotation` radians about +Y.
// CPU twin: probekit::latLongUv (formats/include/probekit/formats/environment.hpp).
vec2 pk_latlong_uv(vec3 dir, float rotation) {
    const float c = cos(rotation);
    const float s = sin(rotation);
    const vec3 d = vec3(c * dir.x - s * dir.z, dir.y, s * dir.x + c * dir.z);
    const float theta = acos(clamp(d.y, -1.0, 1.0));
    float phi = atan(d.x, -d.z);
    if (phi < 0.0) {
        phi += 2.0 * PK_PI_F;
    }
    return vec2(phi / (2.0 * PK_PI_F), theta / PK_PI_F);
}

void main() {
    vec3 radiance = pk_frame.environment.rgb;
    if (pk_frame.environmentInfo.x == PK_ENV_LATLONG) {
        const vec3 dir = pk_pixel_direction(gl_FragCoord.xy);
        const vec2 uv = pk_latlong_uv(dir, pk_frame.environment.w);
        radiance *= textureLod(pk_environment_map, uv, 0.0).rgb;
    }
    g_position = vec4(0.0);
    g_normal = vec4(0.0);
    g_albedo = vec4(0.0);
    g_emission = vec4(min(radiance, vec3(PK_HALF_MAX)), 0.0);
    g_id = PK_KIND_NONE;
}
