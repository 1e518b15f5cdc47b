#version 450
// pk_irradiance at a list of points: probekit::runtime::GpuPointSampler, the GPU path the gpu
// tests compare against VolumeSet::irradiance.
#extension GL_GOOGLE_include_directive : require
#define PK_VOLUME_SET 0
#include "probe_volume.glsl"

layout(local_size_x = 64) in;

// Point i: position at 2i, normal at 2i + 1 (xyz; w unused).
layout(std430, set = 1, binding = 0) readonly buffer PkPoints {
    vec4 pk_points[];
};
layout(std430, set = 1, binding = 1) writeonly buffer PkResults {
    vec4 pk_results[];
};
layout(push_constant) uniform PkPush {
    uint count;
} pk_push;

void main() {
    const uint i = gl_GlobalInvocationID.x;
    if (i >= pk_push.count) {
        return;
    }
    const vec3 position = pk_points[2u * i].xyz;
    const vec3 normal = pk_points[2u * i + 1u].xyz;
    pk_results[i] = vec4(pk_irradiance(position, normal), 0.0);
}
