#version 450
// Dynamic GI stage 4: one propagation step as a gather, one invocation per LPV cell. CPU twin:
// giPropagateStep (runtime/src/gi_twin.cpp): every cell receives from each neighbour it lies
// along, through the five faces of the transfer, keep_f W_f Y(w_f) (Y(w_f) . I_source x scale),
// keep_f = weight (1 - clamp(face potential)); the cell's own crossing entries (18 planes,
// 3 d + ch) gain the flux each transfer carries (only this invocation touches them, so no
// atomics); channels whose band 0 ends negative are zeroed. Each workgroup writes the sums of
// kept and dropped flux per channel (two vec4 per workgroup: kept rgb, dropped rgb, summed in a
// fixed tree order) for gi_reduce.comp, which turns them into the scale the next step applies.
// The keep factors depend on the geometry alone, so they are computed once per geometry volume:
// compiled with PK_GI_KEEP (gi_keep.comp) this file instead writes, per source cell and transfer
// (d, f), keep_f = weight (1 - clamp(face potential, 0, 1)) to plane 5 d + f of the keep buffer
// (30 planes of n^3 floats; the twin's transferKeep holds the same numbers), which the steps
// read. extra.x: propagation weight.
#extension GL_GOOGLE_include_directive : require
#define PK_GI_STAGE
#define PK_GI_GEOMETRY(i) geometry[i]

layout(std430, set = 0, binding = 3) readonly buffer PkGiGeometryVolume {
    int geometry[];
};

#include "gi_common.glsl"

#define PK_GI_GROUP 64
layout(local_size_x = PK_GI_GROUP) in;

#ifdef PK_GI_KEEP
layout(std430, set = 0, binding = 12) writeonly buffer PkGiKeep {
    float keep_table[];
};

void main() {
    const PkGiLayout cascade = pk_gi_layout();
    const int n = cascade.cells;
    const int count = n * n * n;
    const int si = int(gl_GlobalInvocationID.x);
    if (si >= count) {
        return;
    }
    const ivec3 src = pk_gi_cell_of_index(si, n);
    const float weight = pk_gi_push.extra.x;
    for (int d = 0; d < 6; ++d) {
        const bool used = pk_gi_inside(src + pk_gi_direction(d), n);
        for (int f = 0; f < 5; ++f) {
            float keep = weight;
            if (used) {
                const float potential =
                    pk_gi_face_potential(cascade, src, d, pk_gi_face_direction(d, f));
                keep = weight * (1.0 - clamp(potential, 0.0, 1.0));
            }
            keep_table[(5 * d + f) * count + si] = keep;
        }
    }
}
#else
layout(std430, set = 0, binding = 12) readonly buffer PkGiKeep {
    float keep_table[];
};
layout(std430, set = 0, binding = 5) readonly buffer PkGiCurrent {
    float current[];
};
layout(std430, set = 0, binding = 6) writeonly buffer PkGiNext {
    float next[];
};
layout(std430, set = 0, binding = 7) buffer PkGiCrossing {
    float crossing[];
};
layout(std430, set = 0, binding = 8) writeonly buffer PkGiPartials {
    vec4 partials[];
};
layout(std430, set = 0, binding = 9) readonly buffer PkGiScale {
    vec4 scale;
};

shared vec3 s_kept[PK_GI_GROUP];
shared vec3 s_dropped[PK_GI_GROUP];

void main() {
    const PkGiLayout cascade = pk_gi_layout();
    const int n = cascade.cells;
    const int count = n * n * n;
    const int ci = int(gl_GlobalInvocationID.x);
    const uint lid = gl_LocalInvocationID.x;
    vec3 kept = vec3(0.0);
    vec3 dropped = vec3(0.0);
    if (ci < count) {
        const ivec3 c = pk_gi_cell_of_index(ci, n);
        const vec3 current_scale = scale.xyz;
        vec3 sum[4] = vec3[4](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
        for (int d = 0; d < 6; ++d) {
            const ivec3 src = c - pk_gi_direction(d);
            if (!pk_gi_inside(src, n)) {
                continue;
            }
            const int si = pk_gi_cell_index(src, n);
            vec3 source[4];
            for (int k = 0; k < 4; ++k) {
                for (int ch = 0; ch < 3; ++ch) {
                    source[k][ch] = current[(3 * k + ch) * count + si] * current_scale[ch];
                }
            }
            vec3 crossed = vec3(0.0);
            for (int f = 0; f < 5; ++f) {
                const vec4 yf = pk_gi_basis_l1(pk_gi_face_direction(d, f));
                const float keep = keep_table[(5 * d + f) * count + si];
                vec3 along = yf[0] * source[0];
                for (int k = 1; k < 4; ++k) {
                    along += yf[k] * source[k];
                }
                const vec3 flux = (keep * pk_gi_face_solid_angle(f)) * along;
                crossed += flux;
                for (int k = 0; k < 4; ++k) {
                    sum[k] += yf[k] * flux;
                }
            }
            for (int ch = 0; ch < 3; ++ch) {
                crossing[(3 * d + ch) * count + ci] += crossed[ch];
            }
        }
        for (int ch = 0; ch < 3; ++ch) {
            const bool drop = sum[0][ch] < 0.0;
            if (drop) {
                dropped[ch] = PK_GI_SQRT_FOUR_PI * sum[0][ch];
            } else {
                kept[ch] = PK_GI_SQRT_FOUR_PI * sum[0][ch];
            }
            for (int k = 0; k < 4; ++k) {
                next[(3 * k + ch) * count + ci] = drop ? 0.0 : sum[k][ch];
            }
        }
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
        partials[2u * gl_WorkGroupID.x] = vec4(s_kept[0], 0.0);
        partials[2u * gl_WorkGroupID.x + 1u] = vec4(s_dropped[0], 0.0);
    }
}
#endif // PK_GI_KEEP
