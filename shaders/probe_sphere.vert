#version 450
// G-buffer pass, probe spheres: one instance per probe (probes and validity views).
#extension GL_GOOGLE_include_directive : require
#include "render_layout.h"

layout(std140, set = 0, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};

layout(location = 0) in vec3 in_direction;     // unit-sphere vertex (and its normal)
layout(location = 1) in vec4 in_center_radius; // per instance: probe world position (m), radius
layout(location = 2) in uint in_id;            // per instance: G-buffer id (render_layout.h)

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;
layout(location = 2) out vec3 out_albedo;
layout(location = 3) out vec3 out_emission;
layout(location = 4) flat out uint out_id;
layout(location = 5) out vec2 out_uv; // the white texture: albedo 1

void main() {
    const vec3 position = in_center_radius.xyz + in_center_radius.w * in_direction;
    out_position = position;
    out_normal = in_direction;
    out_albedo = vec3(1.0);
    out_emission = vec3(0.0);
    out_id = in_id;
    out_uv = vec2(0.5);
    gl_Position = pk_frame.viewProjection * vec4(position, 1.0);
}
