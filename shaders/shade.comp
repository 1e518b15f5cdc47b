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

// Irradiance from the frame's punctual lights on a surface at p with normal n, each light
// counted where the pixel's light mask (`mask`, PK_LIGHT_MASK_BINDING) says it arrives. CPU
// twin: the sum over the visible lights of probekit::irradianceAt (formats/include/probekit/
// formats/light.hpp), mirrored term for term: I / d^2, KHR_lights_punctual's range window
// (rangeWindow), the glTF spot cone ramp (normalIrradianceAt), times max(0, n . l). The baker's
// integrators use the same functions, so rendered direct light matches what a bake stores.
vec3 pk_direct_irradiance(vec3 p, vec3 n, uint mask) {
    vec3 e = vec3(0.0);
    for (uint i = 0u; i < pk_frame.info.y; ++i) {
        if (((mask >> i) & 1u) == 0u) {
            continue;
        }
        const PkLightGpu light = pk_frame.lights[i];
        if (light.info.x == PK_LIGHT_DIRECTIONAL) {
            // With the dynamic GI's pass, directional lights are shaded there, shadowed.
            if ((pk_frame.info.w & PK_FRAME_GI_DIRECTIONAL) == 0u) {
                e += light.intensity.rgb * max(dot(n, -light.direction.xyz), 0.0);
            }
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
    {
        // Without baked light (dynamic GI alone) the volumes' irradiance is left out; the
        // dynamic GI's pass (gi_shade.comp) adds its own after this one.
        vec3 e = (pk_frame.info.w & PK_FRAME_NO_BAKED) != 0u ? vec3(0.0)
                                                             : pk_irradiance(position, n);
        if (pk_frame.info.z != 0u) {
            e += pk_direct_irradiance(position, n, (id >> PK_LIGHT_MASK_SHIFT) & 0xffu);
        }
        if (view == PK_VIEW_IRRADIANCE) {
            color = e;
        } else {
            color = imageLoad(g_albedo, px).rgb / PK_PI * e + imageLoad(g_emission, px).rgb;
        }
    }
    imageStore(out_color, px, vec4(color, 1.0));
#endif
}
