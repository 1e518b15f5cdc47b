#version 450
// Dynamic GI stage 5: accumulated face crossings -> L1 radiance SH, one invocation per LPV cell.
// CPU twin: giResolve (runtime/src/gi_twin.cpp). Writes this bounce's radiance to `pass` (the
// next bounce's surfaces read it alone) and adds it to the cascade's `radiance` (bounces
// accumulate; DynamicGi clears it at the start of an update). Both GiField layout.
#extension GL_GOOGLE_include_directive : require
#define PK_GI_STAGE
#include "gi_common.glsl"

layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 7) readonly buffer PkGiCrossing {
    float crossing[];
};
layout(std430, set = 0, binding = 10) writeonly buffer PkGiPass {
    float pass[];
};
layout(std430, set = 0, binding = 11) buffer PkGiRadiance {
    float radiance[];
};

void main() {
    const PkGiLayout cascade = pk_gi_layout();
    const int n = cascade.cells;
    const int count = n * n * n;
    const int i = int(gl_GlobalInvocationID.x);
    if (i >= count) {
        return;
    }
    const ivec3 c = pk_gi_cell_of_index(i, n);
    const float inv_area = 1.0 / (cascade.cellSize * cascade.cellSize);
    vec3 e[6];
    for (int d = 0; d < 6; ++d) {
        const int travel = d ^ 1;
        const bool from_inside = pk_gi_inside(c + pk_gi_direction(d), n);
        const ivec3 onward = c - pk_gi_direction(d);
        const int oi = pk_gi_cell_index(onward, n);
        vec3 here;
        vec3 there;
        for (int ch = 0; ch < 3; ++ch) {
            here[ch] = crossing[(3 * travel + ch) * count + i];
        }
        if (!pk_gi_inside(onward, n)) {
            e[d] = inv_area * here;
            continue;
        }
        for (int ch = 0; ch < 3; ++ch) {
            there[ch] = crossing[(3 * travel + ch) * count + oi];
        }
        e[d] = from_inside ? 0.5 * inv_area * (here + there) : inv_area * there;
    }
    const vec3 l0 = PK_GI_RESOLVE_BAND0 * (e[0] + e[1] + e[2] + e[3] + e[4] + e[5]);
    // SH index of the band-1 function along each axis: Y11 = x, Y1-1 = y, Y10 = z.
    const int band_one[3] = int[3](3, 1, 2);
    vec3 values[4];
    values[0] = l0;
    for (int axis = 0; axis < 3; ++axis) {
        values[band_one[axis]] = PK_GI_RESOLVE_BAND1 * (e[2 * axis] - e[2 * axis + 1]);
    }
    for (int k = 0; k < 4; ++k) {
        for (int ch = 0; ch < 3; ++ch) {
            const int at = (3 * k + ch) * count + i;
            pass[at] = values[k][ch];
            radiance[at] += values[k][ch];
        }
    }
}
