#version 450
// The dynamic GI's shading pass (runtime/include/probekit/runtime/dynamic_gi.hpp), dispatched
// after shade.comp when FrameSettings::dynamicGi is set: per pixel it adds the cascades'
// irradiance and the directional lights' direct light, shadowed by marching the finest
// cascade's geometry volume, to what shade.comp wrote (albedo / pi x E in the shaded view, E in
// the irradiance view), or writes the GI debug views. A pass of its own because the volumes'
// descriptors and the G-buffer already fill lavapipe's 128 resources per stage. CPU twins
// (runtime/src/gi_twin.hpp): giSampleRadiance (with giZonal), giSunVisibility,
// giGeometryColour, giOcclusion.
#extension GL_GOOGLE_include_directive : require
#include "render_layout.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(std140, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};
layout(binding = 1, rgba32f) uniform readonly image2D g_position;
layout(binding = 2, rgba32f) uniform readonly image2D g_normal;
layout(binding = 3, rgba16f) uniform readonly image2D g_albedo;
layout(binding = 4, rgba32f) uniform image2D out_color;
layout(std140, binding = 5) uniform PkGiBlock {
    PkGiGpu pk_gi;
};
// The cascades' radiance (gi_twin.hpp's GiField: 12 planes of cells^3 floats) and the finest
// cascade's geometry volume. Four bindings rather than an array: indexing an array of buffers
// needs a device feature.
layout(std430, binding = 6) readonly buffer PkGiRadiance0 { float v[]; } pk_gi_r0;
layout(std430, binding = 7) readonly buffer PkGiRadiance1 { float v[]; } pk_gi_r1;
layout(std430, binding = 8) readonly buffer PkGiRadiance2 { float v[]; } pk_gi_r2;
layout(std430, binding = 9) readonly buffer PkGiRadiance3 { float v[]; } pk_gi_r3;
layout(std430, binding = 10) readonly buffer PkGiGeometry { int v[]; } pk_gi_geometry;
#define PK_GI_GEOMETRY(i) pk_gi_geometry.v[i]
#include "gi_common.glsl"

float pk_gi_load(uint cascade, int i) {
    if (cascade == 0u) {
        return pk_gi_r0.v[i];
    } else if (cascade == 1u) {
        return pk_gi_r1.v[i];
    } else if (cascade == 2u) {
        return pk_gi_r2.v[i];
    }
    return pk_gi_r3.v[i];
}

PkGiLayout pk_gi_cascade(uint j) {
    PkGiLayout l;
    l.origin = pk_gi.cascades[j].origin.xyz;
    l.cellSize = pk_gi.cascades[j].origin.w;
    l.cells = int(pk_gi.cascades[j].info.x);
    return l;
}

// Cascade j's L1 radiance at p, trilinear between cell centres, clamped at its border; rows
// r, g, b of (L00, L1-1, L10, L11). CPU twin: gi_twin.cpp sampleField.
mat3x4 pk_gi_sample_field(uint j, vec3 p) {
    const PkGiLayout l = pk_gi_cascade(j);
    const int n = l.cells;
    const vec3 g = clamp((p - l.origin) / l.cellSize - 0.5, vec3(0.0), vec3(float(n - 1)));
    const ivec3 i0 = min(ivec3(floor(g)), ivec3(n - 1));
    const ivec3 i1 = min(i0 + 1, ivec3(n - 1));
    const vec3 t = g - vec3(i0);
    const int count = n * n * n;
    mat3x4 out_sh = mat3x4(0.0);
    for (int corner = 0; corner < 8; ++corner) {
        const ivec3 pick = ivec3((corner & 1) != 0 ? i1.x : i0.x, (corner & 2) != 0 ? i1.y : i0.y,
                                 (corner & 4) != 0 ? i1.z : i0.z);
        const float w = ((corner & 1) != 0 ? t.x : 1.0 - t.x) *
                        ((corner & 2) != 0 ? t.y : 1.0 - t.y) *
                        ((corner & 4) != 0 ? t.z : 1.0 - t.z);
        const int cell = pk_gi_cell_index(pick, n);
        for (int k = 0; k < 4; ++k) {
            for (int ch = 0; ch < 3; ++ch) {
                out_sh[ch][k] += w * pk_gi_load(j, (3 * k + ch) * count + cell);
            }
        }
    }
    return out_sh;
}

// Irradiance of the cascades at p facing n, clamped at 0. CPU twin: sh::irradiance of
// giSampleRadiance (gi_twin.hpp; the zonal band per channel as giZonal adds it), then max(0, .).
vec3 pk_gi_irradiance(vec3 p, vec3 n) {
    mat3x4 sh = mat3x4(0.0);
    for (uint j = pk_gi.info.x; j-- > 0u;) {
        const PkGiLayout l = pk_gi_cascade(j);
        const vec3 lo = p - l.origin;
        const vec3 hi = l.origin + float(l.cells) * l.cellSize - p;
        const float inside = min(min(min(lo.x, lo.y), min(lo.z, hi.x)), min(hi.y, hi.z));
        const float band = pk_gi.params.x * l.cellSize;
        const float w = band > 0.0 ? clamp(inside / band, 0.0, 1.0) : (inside >= 0.0 ? 1.0 : 0.0);
        if (w <= 0.0) {
            continue;
        }
        sh = (1.0 - w) * sh + w * pk_gi_sample_field(j, p);
    }
    const vec4 y = pk_gi_basis_l1(n);
    const vec4 lobe = vec4(PK_GI_A0, PK_GI_A1, PK_GI_A1, PK_GI_A1);
    vec3 e = vec3(dot(sh[0], lobe * y), dot(sh[1], lobe * y), dot(sh[2], lobe * y));
    if (pk_gi.info.y == 1u) {
        // The zonal band hallucinated from L1 (giZonal): z P2 along the L1 direction, whose
        // irradiance is A2 z sqrt(5 / (4 pi)) P2(n . d).
        for (int ch = 0; ch < 3; ++ch) {
            const float l00 = sh[ch].x;
            const vec3 l1 = vec3(sh[ch].w, sh[ch].y, sh[ch].z);
            const float len = length(l1);
            if (l00 > 0.0 && len > 0.0) {
                const float r = min(1.0, len / (1.7320508 * l00));
                const float z = 2.2360680 * l00 * r * r;
                const float c = dot(n, l1 / len);
                e[ch] += (PK_GI_PI / 4.0) * z * 0.63078313 * 0.5 * (3.0 * c * c - 1.0);
            }
        }
    }
    return max(e, vec3(0.0));
}

// The geometry cell of the finest cascade nearest p (clamped into its volume).
int pk_gi_geometry_cell(vec3 p) {
    const PkGiLayout l = pk_gi_cascade(0u);
    const int gv = l.cells + 1;
    const ivec3 g = clamp(ivec3(floor((p - l.origin) / l.cellSize + 0.5)), ivec3(0), ivec3(gv - 1));
    return pk_gi_geometry_index(g, gv);
}

// The debug views. CPU twins: giGeometryColour and giOcclusion (gi_twin.hpp).
vec3 pk_gi_geometry_colour(vec3 p) {
    const int base = pk_gi_geometry_cell(p) * PK_GI_GEOMETRY_INTS;
    const float area = float(PK_GI_GEOMETRY(base + 6)) / PK_GI_FIXED_SCALE;
    if (!(area > 0.0)) {
        return vec3(0.0);
    }
    const vec3 albedo_area = vec3(PK_GI_GEOMETRY(base + 7), PK_GI_GEOMETRY(base + 8),
                                  PK_GI_GEOMETRY(base + 9)) / PK_GI_FIXED_SCALE;
    return albedo_area / area * min(1.0, area);
}
float pk_gi_occlusion(vec3 p, vec3 n) {
    const PkGiLayout l = pk_gi_cascade(0u);
    const int cell = pk_gi_geometry_cell(p + 0.5 * l.cellSize * n);
    float blocked = 0.0;
    for (int d = 0; d < 6; ++d) {
        blocked += clamp(pk_gi_cell_potential(cell, vec3(pk_gi_direction(d))), 0.0, 1.0);
    }
    return 1.0 - blocked / 6.0;
}

// The directional lights' direct light at p facing n, each shadowed by the geometry volume
// (giSunVisibility: marched from p + n s / 2).
vec3 pk_gi_directional(vec3 p, vec3 n) {
    vec3 e = vec3(0.0);
    const PkGiLayout l = pk_gi_cascade(0u);
    for (uint i = 0u; i < pk_frame.info.y; ++i) {
        const PkLightGpu light = pk_frame.lights[i];
        if (light.info.x != PK_LIGHT_DIRECTIONAL) {
            continue;
        }
        const float facing = max(dot(n, -light.direction.xyz), 0.0);
        if (facing > 0.0) {
            const vec3 from = p + 0.5 * l.cellSize * n;
            e += light.intensity.rgb * facing *
                 pk_gi_transmittance(l, from, -light.direction.xyz, 1e30, ivec3(-1));
        }
    }
    return e;
}

void main() {
    const ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(px), pk_frame.size.xy))) {
        return;
    }
    const vec4 position = imageLoad(g_position, px);
    if (position.w <= 0.0) {
        return; // the background, as shade.comp left it
    }
    const vec3 p = position.xyz;
    const vec3 n = normalize(imageLoad(g_normal, px).xyz);
    const uint view = pk_frame.info.x;
    vec3 color = imageLoad(out_color, px).rgb;
    if (view == PK_VIEW_GI) {
        color = pk_gi_irradiance(p, n);
    } else if (view == PK_VIEW_GI_GEOMETRY) {
        color = pk_gi_geometry_colour(p);
    } else if (view == PK_VIEW_GI_AO) {
        color = vec3(pk_gi_occlusion(p, n));
    } else if (view == PK_VIEW_IRRADIANCE) {
        color += pk_gi_irradiance(p, n);
    } else if (view == PK_VIEW_SHADED) {
        vec3 e = pk_gi_irradiance(p, n);
        if (pk_gi.info.w != 0u) {
            e += pk_gi_directional(p, n);
        }
        color += imageLoad(g_albedo, px).rgb / PK_GI_PI * e;
    }
    imageStore(out_color, px, vec4(color, 1.0));
}
