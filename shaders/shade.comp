#version 450
// Shading pass: per pixel, pk_irradiance at the G-buffer position and normal, then the view's
// output (render_layout.h). Compiled three times: as is (shaded and irradiance views), with
// PK_PROBE_VIEWS (the debug views: also shades probe spheres by their own SH for the probes and
// validity views, and the leak view's visible share), and with PK_FETCH_ONLY (the benchmark
// floor: pk_irradiance's texture fetches alone). Keeping the debug paths out of the common
// variant matters on SIMD CPUs such as lavapipe, which run both sides of a divergent branch,
// texture fetches included (and, in Mesa 22, of uniform branches too).
#extension GL_GOOGLE_include_directive : require
#define PK_VOLUME_SET 0
#include "probe_volume.glsl"
#include "render_layout.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(std140, set = 1, binding = 0) uniform PkFrameBlock {
    PkFrameGpu pk_frame;
};
layout(set = 1, binding = 1, rgba32f) uniform readonly image2D g_position;
layout(set = 1, binding = 2, rgba32f) uniform readonly image2D g_normal;
layout(set = 1, binding = 3, rgba16f) uniform readonly image2D g_albedo;
layout(set = 1, binding = 4, rgba16f) uniform readonly image2D g_emission;
layout(set = 1, binding = 5, r32ui) uniform readonly uimage2D g_id;
layout(set = 1, binding = 6, rgba32f) uniform writeonly image2D out_color;

#ifdef PK_DYNAMIC_GI
// The dynamic GI (runtime/include/probekit/runtime/dynamic_gi.hpp): its cascades' radiance
// (gi_twin.hpp's GiField: 12 planes of cells^3 floats) and the finest cascade's geometry volume.
// Four bindings rather than an array: indexing an array of buffers needs a device feature.
layout(std140, set = 2, binding = 0) uniform PkGiBlock {
    PkGiGpu pk_gi;
};
layout(std430, set = 2, binding = 1) readonly buffer PkGiRadiance0 { float v[]; } pk_gi_r0;
layout(std430, set = 2, binding = 2) readonly buffer PkGiRadiance1 { float v[]; } pk_gi_r1;
layout(std430, set = 2, binding = 3) readonly buffer PkGiRadiance2 { float v[]; } pk_gi_r2;
layout(std430, set = 2, binding = 4) readonly buffer PkGiRadiance3 { float v[]; } pk_gi_r3;
layout(std430, set = 2, binding = 5) readonly buffer PkGiGeometry { int v[]; } pk_gi_geometry;
#define PK_GI_GEOMETRY(i) pk_gi_geometry.v[i]
#include "gi_common.glsl"
#ifndef PK_GI_GEOMETRY_INTS
#define PK_GI_GEOMETRY_INTS 17 // gi_geometry.hpp GiGeometryCell
#endif

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
#endif

// Unshadowed irradiance from the frame's punctual lights on a surface at p with normal n. CPU
// twin: the sum over the lights of probekit::irradianceAt (formats/include/probekit/formats/
// light.hpp), mirrored term for term: I / d^2, KHR_lights_punctual's range window (rangeWindow),
// the glTF spot cone ramp (normalIrradianceAt), times max(0, n . l). The baker's integrators use
// the same functions, so rendered direct light matches what a bake with direct light stores.
vec3 pk_direct_irradiance(vec3 p, vec3 n) {
    vec3 e = vec3(0.0);
    for (uint i = 0u; i < pk_frame.info.y; ++i) {
        const PkLightGpu light = pk_frame.lights[i];
        if (light.info.x == PK_LIGHT_DIRECTIONAL) {
            float visible = 1.0;
#ifdef PK_DYNAMIC_GI
            // The sun's shadow marched through the geometry volume (giTransmittance), from the
            // surface moved half a cell along its normal.
            if (pk_gi.info.w != 0u && dot(n, -light.direction.xyz) > 0.0) {
                const PkGiLayout l = pk_gi_cascade(0u);
                const vec3 from = p + 0.5 * l.cellSize * n;
                visible = pk_gi_transmittance(l, from, -light.direction.xyz, 1e30, ivec3(-1));
            }
#endif
            e += light.intensity.rgb * max(dot(n, -light.direction.xyz), 0.0) * visible;
            continue;
        }
        const vec3 to_point = p - light.position.xyz;
        const float d2 = dot(to_point, to_point);
        if (d2 <= 0.0) {
            continue;
        }
        float attenuation = 1.0 / d2;
        const float range = light.position.w;
        if (range > 0.0) {
            const float r = d2 / (range * range);
            const float window = clamp(1.0 - r * r, 0.0, 1.0);
            attenuation *= window * window;
        }
        const vec3 l = -to_point / sqrt(d2);
        if (light.info.x == PK_LIGHT_SPOT) {
            const float cos_angle = dot(light.direction.xyz, -l);
            const float scale = 1.0 / max(0.001, light.direction.w - light.intensity.w);
            const float t = clamp((cos_angle - light.intensity.w) * scale, 0.0, 1.0);
            attenuation *= t * t;
        }
        e += light.intensity.rgb * attenuation * max(dot(n, l), 0.0);
    }
    return e;
}

void main() {
    const ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(px), pk_frame.size.xy))) {
        return;
    }
    const uint id = imageLoad(g_id, px).x;
    const uint kind = id & 3u;
    if (kind == PK_KIND_NONE) {
        // The background: what the G-buffer's background pass left in the emission target (the
        // environment's radiance in the shaded and probes views, else the cleared 0), alpha 0.
        imageStore(out_color, px, vec4(imageLoad(g_emission, px).rgb, 0.0));
        return;
    }
    const vec3 position = imageLoad(g_position, px).xyz;
    const vec3 n = normalize(imageLoad(g_normal, px).xyz);
#ifdef PK_FETCH_ONLY
    imageStore(out_color, px, pk_fetch_only(position, n));
#else
    const uint view = pk_frame.info.x;
    vec3 color;
#ifdef PK_PROBE_VIEWS
    if (kind == PK_KIND_PROBE) {
        const bool valid = ((id >> 2u) & 1u) != 0u;
        const uint slot = (id >> 3u) & 7u;
        const bool bricked = pk_is_bricked(slot);
        // Bricked: (brick, probe in the brick, 0), as pk_probe_irradiance takes it.
        const uvec3 probe = bricked ? uvec3(id >> 14u, (id >> 8u) & 63u, 0u)
                                    : uvec3((id >> 8u) & 255u, (id >> 16u) & 255u, id >> 24u);
        // Flat colours get a little view-dependent shading so spheres still read as spheres.
        const float facing = max(dot(n, normalize(pk_frame.eye.xyz - position)), 0.0);
        if (view == PK_VIEW_PROBES && bricked) {
            // The brick's level (legend in renderer.hpp): 0 blue, 1 green, 2 yellow, 3 magenta.
            const vec3 level_colors[4] = vec3[4](vec3(0.15, 0.35, 1.0), vec3(0.15, 0.85, 0.25),
                                                 vec3(1.0, 0.85, 0.1), vec3(0.95, 0.2, 0.9));
            color = level_colors[(id >> 6u) & 3u] * (0.3 + 0.7 * facing);
        } else if (view == PK_VIEW_VALIDITY && !valid) {
            color = vec3(1.0, 0.05, 0.05) * (0.3 + 0.7 * facing);
        } else {
            // A white Lambertian sphere lit by the probe's own SH: radiance E / pi.
            color = pk_probe_irradiance(slot, probe, n) / PK_PI;
        }
    } else
#endif
#ifdef PK_PROBE_VIEWS
    if (view == PK_VIEW_LEAK) {
        // White (v = 1) to red (v = 0): renderer.hpp's RenderView::Leak.
        const float v = pk_visible_weight(position, n);
        color = vec3(1.0, v, v);
    } else
#endif
#ifdef PK_DYNAMIC_GI
    if (view == PK_VIEW_GI) {
        color = pk_gi_irradiance(position, n);
    } else if (view == PK_VIEW_GI_GEOMETRY) {
        color = pk_gi_geometry_colour(position);
    } else if (view == PK_VIEW_GI_AO) {
        color = vec3(pk_gi_occlusion(position, n));
    } else
#endif
    {
#ifdef PK_DYNAMIC_GI
        vec3 e = pk_gi_irradiance(position, n);
        if (pk_gi.info.z != 0u) {
            e += pk_irradiance(position, n);
        }
#else
        vec3 e = pk_irradiance(position, n);
#endif
        if (view == PK_VIEW_IRRADIANCE) {
            color = e;
        } else {
            if (pk_frame.info.z != 0u) {
                e += pk_direct_irradiance(position, n);
            }
            color = imageLoad(g_albedo, px).rgb / PK_PI * e + imageLoad(g_emission, px).rgb;
        }
    }
    imageStore(out_color, px, vec4(color, 1.0));
#endif
}
