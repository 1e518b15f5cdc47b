#version 450
// Dynamic GI stage 2: what each geometry cell's surface reflects, one invocation per geometry
// cell. CPU twin: giSurfaceLightsDirect (info.y == 0: the first bounce, lit by the frame's
// lights through the geometry volume) and giSurfaceLightsBounce (info.y == 1: lit by the
// previous bounce's radiance, the `pass` buffer), runtime/src/gi_twin.cpp.
//
// Output, std430, 64 bytes per geometry cell (gi_twin.hpp's GiSurfaceLight):
//   ivec4 target  x, y: the LPV cell side 0 (+normal) and side 1 (-normal) inject into, -1 none
//   vec4 flux[2]  rgb: W reflected into each side's hemisphere
//   vec4 normal   xyz: the surface's canonical normal (0 for an empty cell)
#extension GL_GOOGLE_include_directive : require
#define PK_GI_STAGE
#define PK_GI_GEOMETRY(i) geometry[i]

layout(std430, set = 0, binding = 3) readonly buffer PkGiGeometryVolume {
    int geometry[];
};

#include "gi_common.glsl"

layout(local_size_x = 64) in;

// DynamicGi's GiFrameGpu (runtime/src/dynamic_gi.cpp). Light type: 0 point, 1 spot,
// 2 directional (probekit::LightType).
struct PkGiLightGpu {
    vec4 position;  // xyz world, w range (0: infinite)
    vec4 direction; // xyz as given (spot, directional), w cos(inner cone)
    vec4 intensity; // rgb, w cos(outer cone)
    ivec4 info;     // x type
};
layout(std140, set = 0, binding = 0) uniform PkGiFrame {
    PkGiLightGpu lights[8];
    ivec4 counts;        // x light count
    vec4 borderSky[24];  // giBorderSky, [6 d][4 k], rgb
}
pk_gi_frame;

struct PkGiSurfaceLight {
    ivec4 target;
    vec4 flux[2];
    vec4 normal;
};
layout(std430, set = 0, binding = 4) writeonly buffer PkGiSurfaces {
    PkGiSurfaceLight surfaces[];
};
// The previous bounce's radiance (GiField layout), read on later bounces.
layout(std430, set = 0, binding = 10) readonly buffer PkGiPass {
    float pass[];
};

// normalIrradianceAt x max(0, m . l) (formats/src/light.cpp irradianceAt), with the direction
// towards the light and its distance as directionToLight gives them.
vec3 lightIrradiance(PkGiLightGpu light, vec3 point, vec3 m, out vec3 to_light,
                     out float distance) {
    const float inf = uintBitsToFloat(0x7f800000u);
    if (light.info.x == 2) {
        to_light = -normalize(light.direction.xyz);
        distance = inf;
    } else {
        const vec3 offset = light.position.xyz - point;
        distance = length(offset);
        if (!(distance > 0.0)) {
            to_light = vec3(0.0);
            return vec3(0.0);
        }
        to_light = offset / distance;
    }
    const float cos_theta = dot(m, to_light);
    if (!(cos_theta > 0.0)) {
        return vec3(0.0);
    }
    if (light.info.x == 2) {
        return light.intensity.rgb * cos_theta;
    }
    const vec3 to_point = point - light.position.xyz;
    const float d2 = dot(to_point, to_point);
    if (d2 <= 0.0) {
        return vec3(0.0);
    }
    float attenuation = 1.0 / d2;
    const float range = light.position.w;
    if (range > 0.0) {
        const float r = d2 / (range * range);
        const float window = clamp(1.0 - r * r, 0.0, 1.0);
        attenuation *= window * window;
    }
    if (light.info.x == 1) {
        const float cos_angle = dot(light.direction.xyz, to_point / sqrt(d2));
        const float scale = 1.0 / max(0.001, light.direction.w - light.intensity.w);
        const float t = clamp((cos_angle - light.intensity.w) * scale, 0.0, 1.0);
        attenuation *= t * t;
    }
    return light.intensity.rgb * attenuation * cos_theta;
}

// L1 irradiance facing m of the previous bounce's radiance at p: trilinear between cell
// centres, clamped at the border, clamped at 0 (gi_twin.cpp sampleField, irradianceL1).
vec3 bounceIrradiance(PkGiLayout cascade, vec3 p, vec3 m) {
    const int n = cascade.cells;
    const int count = n * n * n;
    const vec3 g = clamp((p - cascade.origin) / cascade.cellSize - 0.5, vec3(0.0), vec3(float(n - 1)));
    const ivec3 i0 = min(ivec3(floor(g)), ivec3(n - 1));
    const ivec3 i1 = min(i0 + 1, ivec3(n - 1));
    const vec3 t = g - vec3(i0);
    vec3 radiance[4] = vec3[4](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
    for (int corner = 0; corner < 8; ++corner) {
        const ivec3 pick = ivec3((corner & 1) != 0 ? i1.x : i0.x, (corner & 2) != 0 ? i1.y : i0.y,
                                 (corner & 4) != 0 ? i1.z : i0.z);
        const float w = ((corner & 1) != 0 ? t.x : 1.0 - t.x) *
                        ((corner & 2) != 0 ? t.y : 1.0 - t.y) *
                        ((corner & 4) != 0 ? t.z : 1.0 - t.z);
        const int cell = pk_gi_cell_index(pick, n);
        for (int k = 0; k < 4; ++k) {
            for (int ch = 0; ch < 3; ++ch) {
                radiance[k][ch] += w * pass[(3 * k + ch) * count + cell];
            }
        }
    }
    const vec4 y = pk_gi_basis_l1(m);
    vec3 e = PK_GI_A0 * y[0] * radiance[0];
    for (int k = 1; k < 4; ++k) {
        e += PK_GI_A1 * y[k] * radiance[k];
    }
    return max(e, vec3(0.0));
}

void main() {
    const PkGiLayout cascade = pk_gi_layout();
    const int gv = cascade.cells + 1;
    const int gi = int(gl_GlobalInvocationID.x);
    if (gi >= gv * gv * gv) {
        return;
    }
    const ivec3 g = pk_gi_cell_of_index(gi, gv);
    PkGiSurfaceLight light;
    light.target = ivec4(-1, -1, 0, 0);
    light.flux[0] = vec4(0.0);
    light.flux[1] = vec4(0.0);
    light.normal = vec4(0.0);

    // giSurfaceOf.
    const int base = PK_GI_CELL_INTS * gi;
    const int area_fixed = geometry[base + 6];
    float surface_area = 0.0;
    vec3 albedo = vec3(0.0);
    vec3 normal = vec3(0.0);
    vec3 position = vec3(0.0);
    if (area_fixed > 0) {
        const float area = float(area_fixed) / PK_GI_FIXED_SCALE;
        const float inv_area = 1.0 / area;
        const float s = cascade.cellSize;
        // Each side reflects with the area facing it (max of front and back).
        const float front = float(geometry[base + 16]) / PK_GI_FIXED_SCALE;
        surface_area = max(front, area - front) * (s * s);
        vec3 normal_sum;
        vec3 offset;
        for (int ch = 0; ch < 3; ++ch) {
            albedo[ch] = float(geometry[base + 7 + ch]) / PK_GI_FIXED_SCALE * inv_area;
            normal_sum[ch] = float(geometry[base + 10 + ch]) / PK_GI_FIXED_SCALE;
            offset[ch] = float(geometry[base + 13 + ch]) / PK_GI_FIXED_SCALE * inv_area;
        }
        const float len = length(normal_sum);
        if (!(len > 1e-3 * area)) {
            surface_area = 0.0;
        } else {
            normal = normal_sum / len;
            position = cascade.origin + (vec3(g) + offset) * s;
        }
    }
    light.normal = vec4(normal, 0.0);
    if (surface_area > 0.0) {
        for (int side = 0; side < 2; ++side) {
            const vec3 m = side == 0 ? normal : -normal;
            const vec3 at = position + 0.5 * cascade.cellSize * m;
            const ivec3 c = ivec3(floor((at - cascade.origin) / cascade.cellSize));
            if (!pk_gi_inside(c, cascade.cells)) {
                continue;
            }
            light.target[side] = pk_gi_cell_index(c, cascade.cells);
            vec3 e = vec3(0.0);
            if (pk_gi_push.info.y == 0) {
                for (int l = 0; l < pk_gi_frame.counts.x; ++l) {
                    vec3 to_light;
                    float distance;
                    const vec3 facing =
                        lightIrradiance(pk_gi_frame.lights[l], position, m, to_light, distance);
                    if (facing == vec3(0.0)) {
                        continue;
                    }
                    e += facing * pk_gi_transmittance(cascade, position, to_light, distance, g);
                }
            } else {
                e = bounceIrradiance(cascade, at, m);
            }
            light.flux[side] = vec4(surface_area * albedo * e, 0.0);
        }
    }
    surfaces[gi] = light;
}
