#version 450
// Dynamic GI stage 3: the injected intensity field, one invocation per LPV cell, gathering the
// surface sides whose target is this cell from the 27 geometry cells c + {-1, 0, 1}^3 (z, y, x
// ascending, side 0 before side 1) as the cosine lobe Phi (Y00, 2/3 Y1m(m)); with info.y == 1
// (the first bounce) it adds the sky entering through the cascade's border. CPU twin: giInject
// (runtime/src/gi_twin.cpp). Writes every cell of the field (GiField layout).
#extension GL_GOOGLE_include_directive : require
#define PK_GI_STAGE
#include "gi_common.glsl"

layout(local_size_x = 64) in;

struct PkGiLightGpu {
    vec4 position;
    vec4 direction;
    vec4 intensity;
    ivec4 info;
};
layout(std140, set = 0, binding = 0) uniform PkGiFrame {
    PkGiLightGpu lights[8];
    ivec4 counts;
    vec4 borderSky[24]; // giBorderSky [6 d][4 k], rgb: W/(sr m^2)
}
pk_gi_frame;

struct PkGiSurfaceLight {
    ivec4 target;
    vec4 flux[2];
    vec4 normal;
};
layout(std430, set = 0, binding = 4) readonly buffer PkGiSurfaces {
    PkGiSurfaceLight surfaces[];
};
layout(std430, set = 0, binding = 5) writeonly buffer PkGiField {
    float field[];
};

void main() {
    const PkGiLayout cascade = pk_gi_layout();
    const int n = cascade.cells;
    const int count = n * n * n;
    const int ci = int(gl_GlobalInvocationID.x);
    if (ci >= count) {
        return;
    }
    const ivec3 c = pk_gi_cell_of_index(ci, n);
    const int gv = n + 1;
    vec3 sum[4] = vec3[4](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
    for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
                const ivec3 g = c + ivec3(dx, dy, dz);
                if (!pk_gi_inside(g, gv)) {
                    continue;
                }
                const PkGiSurfaceLight s = surfaces[g.x + gv * (g.y + gv * g.z)];
                for (int side = 0; side < 2; ++side) {
                    if (s.target[side] != ci) {
                        continue;
                    }
                    const vec3 m = side == 0 ? s.normal.xyz : -s.normal.xyz;
                    const vec4 ym = pk_gi_basis_l1(m);
                    const vec3 flux = s.flux[side].rgb;
                    sum[0] += ym[0] * flux;
                    for (int k = 1; k < 4; ++k) {
                        sum[k] += (0.666666687 * ym[k]) * flux;
                    }
                }
            }
        }
    }
    if (pk_gi_push.info.y == 1) {
        const float face = cascade.cellSize * cascade.cellSize;
        for (int d = 0; d < 6; ++d) {
            // Light travelling along d enters through the low side for a positive d.
            const int axis = d / 2;
            const int layer = (d & 1) == 0 ? 0 : n - 1;
            if (c[axis] == layer) {
                for (int k = 0; k < 4; ++k) {
                    sum[k] += face * pk_gi_frame.borderSky[4 * d + k].rgb;
                }
            }
        }
    }
    for (int k = 0; k < 4; ++k) {
        for (int ch = 0; ch < 3; ++ch) {
            field[(3 * k + ch) * count + ci] = sum[k][ch];
        }
    }
}
