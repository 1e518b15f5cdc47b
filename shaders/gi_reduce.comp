#version 450
// Dynamic GI stage 4b: one workgroup sums gi_propagate.comp's per-workgroup kept and dropped
// flux (info.z partials, each invocation a strided run in index order, then a fixed tree) and
// writes the per-channel scale the next propagation step multiplies its source by: (kept +
// dropped) / kept where something was dropped and something kept, else 1 (giPropagateStep's
// return value; the twin sums in double, this in float).
#extension GL_GOOGLE_include_directive : require
#define PK_GI_STAGE
#include "gi_common.glsl"

#define PK_GI_GROUP 64
layout(local_size_x = PK_GI_GROUP) in;

layout(std430, set = 0, binding = 8) readonly buffer PkGiPartials {
    vec4 partials[];
};
layout(std430, set = 0, binding = 9) writeonly buffer PkGiScale {
    vec4 scale;
};

shared vec3 s_kept[PK_GI_GROUP];
shared vec3 s_dropped[PK_GI_GROUP];

void main() {
    const uint lid = gl_LocalInvocationID.x;
    const uint groups = uint(pk_gi_push.info.z);
    vec3 kept = vec3(0.0);
    vec3 dropped = vec3(0.0);
    for (uint i = lid; i < groups; i += PK_GI_GROUP) {
        kept += partials[2u * i].xyz;
        dropped += partials[2u * i + 1u].xyz;
    }
    s_kept[lid] = kept;
    s_dropped[lid] = dropped;
    barrier();
    for (uint stride = PK_GI_GROUP / 2; stride > 0u; stride /= 2u) {
        if (lid < stride) {
            s_kept[lid] += s_kept[lid + stride];
            s_dropped[lid] += s_dropped[lid + stride];
        }
        barrier();
    }
    if (lid == 0u) {
        vec3 result = vec3(1.0);
        for (int ch = 0; ch < 3; ++ch) {
            if (s_kept[0][ch] > 0.0 && s_dropped[0][ch] < 0.0) {
                result[ch] = (s_kept[0][ch] + s_dropped[0][ch]) / s_kept[0][ch];
            }
        }
        scale = vec4(result, 1.0);
    }
}
