#version 450
// G-buffer pass: world position, camera-facing unit normal, albedo, emission and id.
#extension GL_GOOGLE_include_directive : require
#include "render_layout.h"

layout(std140, set = 0, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};
// Per pixel, which lights reach it (render_layout.h, PK_LIGHT_MASK_BINDING).
layout(std430, set = 0, binding = PK_LIGHT_MASK_BINDING) readonly buffer PkLightMask {
    uint pk_light_mask[];
};
// The draw's base-colour texture (a 1 x 1 white one for untextured triangles and probe spheres).
// CPU twin: RgbaImage::sampleBilinear (formats/environment.hpp): LINEAR, REPEAT, no mipmaps.
layout(set = 1, binding = 0) uniform sampler2D pk_base_color;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec3 in_albedo;
layout(location = 3) in vec3 in_emission;
layout(location = 4) flat in uint in_id;
layout(location = 5) in vec2 in_uv;

layout(location = 0) out vec4 g_position;
layout(location = 1) out vec4 g_normal;
layout(location = 2) out vec4 g_albedo;
layout(location = 3) out vec4 g_emission;
layout(location = 4) out uint g_id;

void main() {
    vec3 n = normalize(in_normal);
    // Surfaces are two-sided (the baker's convention): shade the side the camera sees. Which
    // side that is comes from the triangle's own plane g (the screen derivatives of the position
    // lie in it): the interpolated normal is flipped when it and the viewer lie on opposite
    // sides of g. The sign of g cancels in the product, and near a silhouette a smooth normal
    // that leans slightly away from the viewer is kept, not turned into the surface.
    const vec3 to_eye = pk_frame.eye.xyz - in_position;
    const vec3 g = cross(dFdx(in_position), dFdy(in_position));
    const float side = dot(g, to_eye) * dot(g, n);
    if (side < 0.0 || (side == 0.0 && dot(n, to_eye) < 0.0)) {
        n = -n;
    }
    g_position = vec4(in_position, 1.0);
    g_normal = vec4(n, 0.0);
    g_albedo = vec4(in_albedo * textureLod(pk_base_color, in_uv, 0.0).rgb, 1.0);
    g_emission = vec4(in_emission, 1.0);
    g_id = in_id;
    if ((in_id & 3u) == PK_KIND_SURFACE) {
        const uvec2 px = uvec2(gl_FragCoord.xy);
        g_id |= (pk_light_mask[px.x + px.y * pk_frame.size.x] & 0xffu) << PK_LIGHT_MASK_SHIFT;
    }
}
