#version 450
// G-buffer pass: world position, camera-facing unit normal, albedo, emission and id.
#extension GL_GOOGLE_include_directive : require
#include "render_layout.h"

layout(std140, set = 0, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec3 in_albedo;
layout(location = 3) in vec3 in_emission;
layout(location = 4) flat in uint in_id;

layout(location = 0) out vec4 g_position;
layout(location = 1) out vec4 g_normal;
layout(location = 2) out vec4 g_albedo;
layout(location = 3) out vec4 g_emission;
layout(location = 4) out uint g_id;

void main() {
    vec3 n = normalize(in_normal);
    // Surfaces are two-sided (the baker's convention): shade the side the camera sees.
    if (dot(n, pk_frame.eye.xyz - in_position) < 0.0) {
        n = -n;
    }
    g_position = vec4(in_position, 1.0);
    g_normal = vec4(n, 0.0);
    g_albedo = vec4(in_albedo, 1.0);
    g_emission = vec4(in_emission, 1.0);
    g_id = in_id;
}
