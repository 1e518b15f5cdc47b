#version 450
// G-buffer pass, meshes: world-space triangles (runtime::RenderVertex) to clip space.
#extension GL_GOOGLE_include_directive : require
#include "render_layout.h"

layout(std140, set = 0, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec3 in_albedo;
layout(location = 3) in vec3 in_emission;
layout(location = 4) in vec2 in_uv;

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;
layout(location = 2) out vec3 out_albedo;
layout(location = 3) out vec3 out_emission;
layout(location = 4) flat out uint out_id;
layout(location = 5) out vec2 out_uv;

void main() {
    out_position = in_position;
    out_normal = in_normal;
    out_albedo = in_albedo;
    out_emission = in_emission;
    out_id = PK_KIND_SURFACE;
    out_uv = in_uv;
    gl_Position = pk_frame.viewProjection * vec4(in_position, 1.0);
}
