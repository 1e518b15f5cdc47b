#version 450
// Compile check for shaders/probe_volume.glsl: includes it and uses every function once.
#extension GL_GOOGLE_include_directive : require
#include "probe_volume.glsl"

layout(local_size_x = 1) in;
layout(std430, binding = 0) buffer Io {
    vec4 texels[7];
    vec4 normal;
    vec4 result;
};

void main() {
    vec4 t[7] = texels;
    vec3 sh[9];
    pk_unpack_probe(t, true, sh);
    result = vec4(pk_sh_irradiance(sh, normalize(normal.xyz)), 1.0);
}
