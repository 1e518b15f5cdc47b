#version 450
// Compile check for shaders/probe_volume.glsl: includes it with the volume-set bindings and uses
// every function once.
#extension GL_GOOGLE_include_directive : require
#define PK_VOLUME_SET 1
#include "probe_volume.glsl"

layout(local_size_x = 1) in;
layout(std430, set = 0, binding = 0) buffer Io {
    vec4 texels[7];
    vec4 normal;
    vec4 position;
    vec4 result;
    vec4 blended;
    vec4 own;
    vec4 fetched;
    vec4 visible;
};

void main() {
    vec4 t[7] = texels;
    vec3 sh[9];
    pk_unpack_probe(t, true, sh);
    const vec3 n = normalize(normal.xyz);
    result = vec4(pk_sh_irradiance(sh, n), 1.0);
    blended = vec4(pk_irradiance(position.xyz, n), 1.0);
    own = vec4(pk_probe_irradiance(0u, uvec3(0u), n), 1.0);
    fetched = pk_fetch_only(position.xyz, n);
    visible = vec4(pk_visible_weight(position.xyz, n));
}
