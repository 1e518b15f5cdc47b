// probekit probe volumes in GLSL. Conventions: formats/CONVENTIONS.md (radiance SH, real
// orthonormal Ramamoorthi-Hanrahan basis, no Condon-Shortley phase, glTF axes; irradiance E in
// W/m^2, not divided by pi).
//
// Texel planes (formats/include/probekit/formats/volume.hpp): plane c (0..2) holds
// (L00, L1-1, L10, L11) of channel c; planes 3..6 hold the 15 band-2 values, value j = 3k + c at
// plane 3 + j / 4, component j % 4.
//
// Two levels:
//  * Always: pk_sh_irradiance and pk_unpack_probe, pure functions on coefficients.
//  * With PK_VOLUME_SET defined (the descriptor set index the application binds
//    probekit::runtime::GpuVolumeSet::descriptorSet() to) before the include: the volume-set
//    bindings (layout in probe_volume_layout.h, shared with C++) and pk_irradiance(worldPos,
//    normal), the GPU twin of probekit::runtime::VolumeSet::irradiance. Usable in any stage
//    (it samples with explicit LOD 0).
//
// Visibility (leak-proof interpolation, sampler.hpp step V): volumes flagged
// PK_VOLUME_FLAG_VISIBILITY are interpolated tap by tap with visibility weights
// (pk_visible_texels) instead of by the hardware filter. The specialization constant
// pk_visibility_mode (id PK_CONSTANT_VISIBILITY; modes in probe_volume_layout.h) chooses how:
//  * PK_VISIBILITY_BRANCH (default, right for any set): a uniform branch per volume, tap by tap
//    with visibility, hardware-filtered without;
//  * PK_VISIBILITY_OFF: the visibility path compiled out, exactly the hardware-filtered code,
//    for pipelines that only sample sets without visibility (GpuVolumeSet::anyVisibility);
//  * PK_VISIBILITY_TAPS: every volume tap by tap (without visibility at weight 1: trilinear
//    interpolation), no hardware-filtered fetch at all.
// Implementations that execute both sides of every branch, uniform ones included (lavapipe in
// Mesa 22: all eight slot cases of pk_fetch_planes run, masked), pay for code they skip: for
// them OFF keeps sets without visibility at their old cost and TAPS saves the filtered fetches
// a BRANCH pipeline would run (masked) beside the taps. The renderer picks OFF, or TAPS on CPU
// devices and BRANCH on others.
#ifndef PROBEKIT_PROBE_VOLUME_GLSL
#define PROBEKIT_PROBE_VOLUME_GLSL

// texelFetch on the indirection's utexture3D without a sampler (an integer image has nothing
// to filter). Before the layout include: an #extension must precede every declaration.
#extension GL_EXT_samplerless_texture_functions : require

#include "probe_volume_layout.h"

const float PK_PI = 3.14159265358979323846;

// Irradiance from unpacked RGB coefficients sh[0..8] (sh[4..8] zero for L1) at unit normal n.
// Mirrors probekit::sh::irradiance (formats/src/sh.cpp) term for term:
// E(n) = sum_lm A_l L_lm Y_lm(n), A = (pi, 2pi/3, pi/4).
vec3 pk_sh_irradiance(vec3 sh[9], vec3 n) {
    const float a0 = PK_PI;
    const float a1 = 2.0 * PK_PI / 3.0;
    const float a2 = PK_PI / 4.0;
    vec3 e = a0 * 0.282095 * sh[0];
    e += a1 * 0.488603 * (sh[1] * n.y + sh[2] * n.z + sh[3] * n.x);
    e += a2 * (1.092548 * (sh[4] * (n.x * n.y) + sh[5] * (n.y * n.z) + sh[7] * (n.x * n.z)) +
               0.315392 * sh[6] * (3.0 * n.z * n.z - 1.0) +
               0.546274 * sh[8] * (n.x * n.x - n.y * n.y));
    return e;
}

// Unpacks the 7 (or, for L1, the first 3) RGBA texels of one probe into RGB coefficients.
// Mirrors probekit::unpackProbe (formats/src/volume.cpp): band-2 value j = 3k + c at plane
// 3 + j / 4, component j % 4, written out with constant indices (loops with computed indices
// would keep the arrays in memory on CPU implementations such as lavapipe).
void pk_unpack_probe(vec4 t[7], bool l2, out vec3 sh[9]) {
    sh[0] = vec3(t[0].x, t[1].x, t[2].x);
    sh[1] = vec3(t[0].y, t[1].y, t[2].y);
    sh[2] = vec3(t[0].z, t[1].z, t[2].z);
    sh[3] = vec3(t[0].w, t[1].w, t[2].w);
    if (l2) {
        sh[4] = t[3].xyz;                    // j = 0, 1, 2
        sh[5] = vec3(t[3].w, t[4].xy);       // j = 3, 4, 5
        sh[6] = vec3(t[4].zw, t[5].x);       // j = 6, 7, 8
        sh[7] = t[5].yzw;                    // j = 9, 10, 11
        sh[8] = t[6].xyz;                    // j = 12, 13, 14
    } else {
        sh[4] = vec3(0.0);
        sh[5] = vec3(0.0);
        sh[6] = vec3(0.0);
        sh[7] = vec3(0.0);
        sh[8] = vec3(0.0);
    }
}

#ifdef PK_VOLUME_SET

layout(std140, set = PK_VOLUME_SET, binding = PK_BINDING_VOLUMES) uniform PkVolumeSetBlock {
    PkVolumeSetGpu pk_volume_set;
};
// Element PK_MAX_PLANES * slot + plane. Indexed with constants only (see pk_fetch_planes), so
// no dynamic-indexing feature is needed.
layout(set = PK_VOLUME_SET, binding = PK_BINDING_STATE_A) uniform texture3D
    pk_state_a[PK_MAX_VOLUMES * PK_MAX_PLANES];
layout(set = PK_VOLUME_SET, binding = PK_BINDING_STATE_B) uniform texture3D
    pk_state_b[PK_MAX_VOLUMES * PK_MAX_PLANES];
layout(set = PK_VOLUME_SET, binding = PK_BINDING_SAMPLER) uniform sampler pk_linear_clamp;
// The slots' integer images (probe_volume_layout.h), element = slot: bricked volumes'
// indirection and the visibility of volumes that have it (PK_BINDING_VISIBILITY is this binding).
layout(set = PK_VOLUME_SET, binding = PK_BINDING_INDIRECTION) uniform utexture3D
    pk_indirection[PK_MAX_VOLUMES];
// How volumes with visibility are sampled (see the top of this file).
layout(constant_id = PK_CONSTANT_VISIBILITY) const uint pk_visibility_mode = PK_VISIBILITY_BRANCH;

// Slot of the i-th volume in blending order (descending priority, ties in set order).
uint pk_blend_slot(uint i) {
    return pk_volume_set.order[i / 4u][i % 4u];
}

// World -> the volume's local frame. Mirrors grid::RigidFrame::toLocal:
// conjugate(rotation) * (world - translation).
vec3 pk_to_local(uint s, vec3 world) {
    const vec4 r0 = pk_volume_set.volumes[s].worldToLocal0;
    const vec4 r1 = pk_volume_set.volumes[s].worldToLocal1;
    const vec4 r2 = pk_volume_set.volumes[s].worldToLocal2;
    const vec3 d = world - vec3(r0.w, r1.w, r2.w);
    return vec3(dot(r0.xyz, d), dot(r1.xyz, d), dot(r2.xyz, d));
}

// Blend weight w(p) in [0, 1]. Mirrors runtime::volumeWeight (and depthInside) in
// runtime/src/sampler.cpp.
float pk_volume_weight(uint s, vec3 local) {
    const vec4 box_min = pk_volume_set.volumes[s].boxMin;
    const vec3 box_max = pk_volume_set.volumes[s].boxMax.xyz;
    const vec3 to_faces = min(local - box_min.xyz, box_max - local);
    const float depth = min(to_faces.x, min(to_faces.y, to_faces.z));
    if (!(depth >= 0.0)) {
        return 0.0;
    }
    const float fade = box_min.w;
    if (fade <= 0.0) {
        return 1.0; // hard border: the closed box counts in full
    }
    return min(depth / fade, 1.0);
}

// Distance from the box in metres (0 inside). Mirrors runtime::distanceToVolume.
float pk_distance_to_volume(uint s, vec3 local) {
    const vec3 box_min = pk_volume_set.volumes[s].boxMin.xyz;
    const vec3 box_max = pk_volume_set.volumes[s].boxMax.xyz;
    return length(max(max(box_min - local, local - box_max), 0.0));
}

#if PK_MAX_VOLUMES != 8
#error "pk_fetch_planes, pk_accumulate_tap and the integer-image fetches have one case per slot"
#endif

bool pk_is_bricked(uint s) {
    return (pk_volume_set.volumes[s].resolution.w & PK_VOLUME_FLAG_BRICKED) != 0u;
}

// The texel at c of slot s's integer image (one case per slot: constant indices): x is the
// bricked indirection entry, xy a visibility texel (probe_volume_layout.h).
uvec2 pk_integer_texel(uint s, ivec3 c) {
    switch (s) {
    case 0: return texelFetch(pk_indirection[0], c, 0).xy;
    case 1: return texelFetch(pk_indirection[1], c, 0).xy;
    case 2: return texelFetch(pk_indirection[2], c, 0).xy;
    case 3: return texelFetch(pk_indirection[3], c, 0).xy;
    case 4: return texelFetch(pk_indirection[4], c, 0).xy;
    case 5: return texelFetch(pk_indirection[5], c, 0).xy;
    case 6: return texelFetch(pk_indirection[6], c, 0).xy;
    default: return texelFetch(pk_indirection[7], c, 0).xy;
    }
}

// The indirection entry of finest cell c of slot s.
uint pk_indirection_entry(uint s, ivec3 c) {
    return pk_integer_texel(s, c).x;
}

// Atlas texture coordinate of brick-local coordinates l (in [0, 3]) of brick `index`: texel
// slot * 4 + 0.5 + l (probe_volume_layout.h), where linear filtering interpolates exactly the
// brick's probes floor(l) and floor(l) + 1 with weights fract(l), never a neighbouring slot (the
// atlas size is a power of two, so this coordinate is exact: runtime::brickAtlasSlots). Mirrors
// runtime::brickAtlasSlot.
vec3 pk_atlas_uvw(uint s, uint index, vec3 l) {
    const uvec3 a = pk_volume_set.volumes[s].bricks.xyz;
    const uvec3 slot = uvec3(index % a.x, (index / a.x) % a.y, index / (a.x * a.y));
    return (vec3(slot * PK_BRICK_SIZE) + 0.5 + l) / vec3(a * PK_BRICK_SIZE);
}

// The bricked steps B1-B2 of the sampler.hpp specification (runtime::sampleVolumeSh's
// withTaps and brick::locate, term for term): the point in finest-cell units, its cell's brick
// from the indirection, and the brick-local coordinates l in [0, 3].
void pk_brick_locate(uint s, vec3 local, out uint index, out vec3 l) {
    const uvec3 cells = pk_volume_set.volumes[s].resolution.xyz;
    const vec3 box_min = pk_volume_set.volumes[s].boxMin.xyz;
    const vec3 box_max = pk_volume_set.volumes[s].boxMax.xyz;
    vec3 f = (local - box_min) / (box_max - box_min) * vec3(cells);
    f = mix(f, vec3(0.0), isnan(f));
    f = clamp(f, vec3(0.0), vec3(cells));
    const uvec3 c = min(uvec3(f), cells - 1u);
    const uint entry = pk_indirection_entry(s, ivec3(c));
    const uint level = entry & 3u;
    const uint span = 1u << (pk_volume_set.volumes[s].bricks.w - level);
    const uvec3 origin = (c / span) * span;
    index = entry >> 2u;
    l = clamp((f - vec3(origin)) * (3.0 / float(span)), vec3(0.0), vec3(3.0));
}

// Texture coordinate of the bricked steps B1-B3: pk_brick_locate, then the brick's atlas slot;
// the hardware filter does B3's trilinear interpolation.
vec3 pk_brick_uvw(uint s, vec3 local) {
    uint index;
    vec3 l;
    pk_brick_locate(s, local, index, l);
    return pk_atlas_uvw(s, index, l);
}

// Texture coordinate of steps 1-3 of the sampler.hpp specification: grid coordinates
// (grid::GridLayout::localToGrid), clamped to [0, res - 1] (runtime's axisTaps; NaN -> 0), at
// (g + 0.5) / res, where linear filtering with clamp-to-edge interpolates exactly the probes
// floor(g) and floor(g) + 1 with weights fract(g). Bricked volumes: pk_brick_uvw.
vec3 pk_volume_uvw(uint s, vec3 local) {
    if (pk_is_bricked(s)) {
        return pk_brick_uvw(s, local);
    }
    const vec4 spacing = pk_volume_set.volumes[s].spacing;
    const vec3 res = vec3(pk_volume_set.volumes[s].resolution.xyz);
    vec3 g = (local - pk_volume_set.volumes[s].boxMin.xyz) / spacing.xyz - spacing.w;
    g = mix(g, vec3(0.0), isnan(g));
    g = clamp(g, vec3(0.0), res - 1.0);
    return (g + 0.5) / res;
}

// ---- Visibility (sampler.hpp step V; probe_volume_layout.h's "Visibility") ----

bool pk_has_visibility(uint s) {
    return pk_visibility_mode != PK_VISIBILITY_OFF &&
           (pk_volume_set.volumes[s].resolution.w & PK_VOLUME_FLAG_VISIBILITY) != 0u;
}

// The visibility texel at integer-image texel c of slot s: x = q0..q3, y = q4, q5.
uvec2 pk_visibility_texel(uint s, ivec3 c) {
    return pk_integer_texel(s, c);
}

// vis_i of one probe (its visibility texel q) at grid offset o. Mirrors
// visibility::probeVisibility (formats/.../visibility.hpp) term for term: per axis a, side
// (o_a > 0 ? 0 : 1), d_a = q[2 a + side] / 255 (decodeDistance), and the minimum over the axes
// of clamp(1 - (|o_a| - d_a) / kRamp, 0, 1). The CPU skips an axis with o_a = 0; here it gives
// 1 + d_a / kRamp >= 1, clamped to 1, which leaves the minimum as it is: the same value.
float pk_probe_visibility(uvec2 q, vec3 o) {
    // Byte h = 2 a + side of the six: x holds h = 0..3, y h = 4, 5 (lowest byte first).
    const uint qx = (q.x >> (o.x > 0.0 ? 0u : 8u)) & 255u;
    const uint qy = (q.x >> (o.y > 0.0 ? 16u : 24u)) & 255u;
    const uint qz = (q.y >> (o.z > 0.0 ? 0u : 8u)) & 255u;
    const vec3 d = vec3(uvec3(qx, qy, qz)) * (1.0 / 255.0);
    const vec3 v = clamp(1.0 - (abs(o) - d) / PK_VISIBILITY_RAMP, vec3(0.0), vec3(1.0));
    return min(1.0, min(v.x, min(v.y, v.z)));
}

// The (up to) 8 taps of one volume at a local position: runtime's withTaps and axisTaps (the
// dense coordinate is pk_volume_uvw's g, the bricked one pk_brick_locate's l).
struct PkTaps {
    vec3 coord;       // the clamped coordinate: dense g in [0, res - 1], bricked l in [0, 3]
    uvec3 lower;      // probes floor(coord) ...
    uvec3 upper;      // ... and floor(coord) + 1; on an axis at its last probe the lower one
                      // again, with weight fract(coord) = 0 (axisTaps' one-tap axis)
    ivec3 texel;      // texel of the probe (0, 0, 0) in the planes: 0, or the brick's slot * 4
    ivec3 visibility; // its texel in the integer image: 0, or slot * 4 + (0, 0, C.z)
};

PkTaps pk_volume_taps(uint s, vec3 local) {
    PkTaps taps;
    uvec3 last;
    if (pk_is_bricked(s)) {
        uint index;
        pk_brick_locate(s, local, index, taps.coord);
        last = uvec3(PK_BRICK_SIZE - 1u);
        const uvec3 a = pk_volume_set.volumes[s].bricks.xyz;
        const uvec3 slot = uvec3(index % a.x, (index / a.x) % a.y, index / (a.x * a.y));
        taps.texel = ivec3(slot * PK_BRICK_SIZE);
        taps.visibility = taps.texel + ivec3(0, 0, int(pk_volume_set.volumes[s].resolution.z));
    } else {
        const vec4 spacing = pk_volume_set.volumes[s].spacing;
        const uvec3 res = pk_volume_set.volumes[s].resolution.xyz;
        vec3 g = (local - pk_volume_set.volumes[s].boxMin.xyz) / spacing.xyz - spacing.w;
        g = mix(g, vec3(0.0), isnan(g));
        taps.coord = clamp(g, vec3(0.0), vec3(res) - 1.0);
        last = res - 1u;
        taps.texel = ivec3(0);
        taps.visibility = ivec3(0);
    }
    taps.lower = uvec3(taps.coord); // floor: coord >= 0
    taps.upper = min(taps.lower + 1u, last);
    return taps;
}

// Tap k (0..7, x fastest as the CPU's loops): its probe, its per-axis weights (the CPU's
// tx.weight[i], ty.weight[j], tz.weight[k]: 1 - fract, fract) and its visibility offset (the
// clamped coordinate minus the probe's).
void pk_tap(PkTaps taps, uint k, out uvec3 probe, out vec3 axis_weights, out vec3 offset) {
    const bvec3 up = notEqual(uvec3(k, k >> 1u, k >> 2u) & 1u, uvec3(0u));
    probe = mix(taps.lower, taps.upper, up);
    const vec3 t = taps.coord - vec3(taps.lower);
    axis_weights = mix(1.0 - t, t, up);
    offset = taps.coord - vec3(probe);
}

#define PK_TAP_L1(STATE, S, C, W, A)                                                           \
    A[0] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 0], C, 0);                                \
    A[1] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 1], C, 0);                                \
    A[2] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 2], C, 0);
#define PK_TAP_L2(STATE, S, C, W, A)                                                           \
    A[3] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 3], C, 0);                                \
    A[4] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 4], C, 0);                                \
    A[5] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 5], C, 0);                                \
    A[6] += W * texelFetch(STATE[(S)*PK_MAX_PLANES + 6], C, 0);
#define PK_TAP_SLOT(S)                                                                         \
    case S:                                                                                    \
        PK_TAP_L1(pk_state_a, S, c, w, a)                                                      \
        if (l2) {                                                                              \
            PK_TAP_L2(pk_state_a, S, c, w, a)                                                  \
        }                                                                                      \
        if (blend) {                                                                           \
            PK_TAP_L1(pk_state_b, S, c, w, b)                                                  \
            if (l2) {                                                                          \
                PK_TAP_L2(pk_state_b, S, c, w, b)                                              \
            }                                                                                  \
        }                                                                                      \
        break;

// One tap of interpolateTexels' loop: w times the stored texels of every plane at texel c
// (texelFetch: the texel alone, decoded to float as Volume::texel does), added to a (state a)
// and b (state b). One case per slot, so every array index is a constant.
void pk_accumulate_tap(uint s, ivec3 c, float w, bool l2, bool blend, inout vec4 a[PK_MAX_PLANES],
                       inout vec4 b[PK_MAX_PLANES]) {
    switch (s) {
        PK_TAP_SLOT(0)
        PK_TAP_SLOT(1)
        PK_TAP_SLOT(2)
        PK_TAP_SLOT(3)
        PK_TAP_SLOT(4)
        PK_TAP_SLOT(5)
        PK_TAP_SLOT(6)
        PK_TAP_SLOT(7)
    }
}

// Step 3 (B3) with visibility, step V: runtime's interpolateTexels with visible_weights, term
// for term: each tap's trilinear weight times (vis + kFloor), the weighted texels summed and
// divided by the sum of the weights. Both states take the primary's visibility weights, and
// a (1 - f) + b f mixes them as pk_fetch_planes does. Planes a volume does not have are zero.
// A volume without visibility (PK_VISIBILITY_TAPS) weighs each tap by its trilinear weight
// alone: step 3 itself, normalised by a weight sum that is 1 to within rounding.
void pk_visible_texels(uint s, PkTaps taps, out vec4 t[PK_MAX_PLANES]) {
    const uint flags = pk_volume_set.volumes[s].resolution.w;
    const bool l2 = (flags & PK_VOLUME_FLAG_L2) != 0u;
    const bool blend = (flags & PK_VOLUME_FLAG_BLEND) != 0u;
    const bool visible = pk_has_visibility(s);
    const vec4 zero = vec4(0.0);
    vec4 a[PK_MAX_PLANES] = vec4[PK_MAX_PLANES](zero, zero, zero, zero, zero, zero, zero);
    vec4 b[PK_MAX_PLANES] = a;
    float weight_sum = 0.0;
    for (uint k = 0u; k < 8u; ++k) {
        uvec3 probe;
        vec3 axis;
        vec3 offset;
        pk_tap(taps, k, probe, axis, offset);
        // The CPU's tx.weight[i] * wyz, wyz = ty.weight[j] * tz.weight[k], times vis + kFloor.
        // Without visibility the fetch reads texel 0, which every integer image (or the dummy
        // bound in its place) has, and is not used.
        const uvec2 q =
            pk_visibility_texel(s, visible ? taps.visibility + ivec3(probe) : ivec3(0));
        float w = axis.x * (axis.y * axis.z);
        w *= visible ? pk_probe_visibility(q, offset) + PK_VISIBILITY_FLOOR : 1.0;
        weight_sum += w;
        pk_accumulate_tap(s, taps.texel + ivec3(probe), w, l2, blend, a, b);
    }
    const float f = blend ? pk_volume_set.volumes[s].boxMax.w : 0.0;
    t[0] = a[0] / weight_sum * (1.0 - f) + b[0] / weight_sum * f;
    t[1] = a[1] / weight_sum * (1.0 - f) + b[1] / weight_sum * f;
    t[2] = a[2] / weight_sum * (1.0 - f) + b[2] / weight_sum * f;
    t[3] = a[3] / weight_sum * (1.0 - f) + b[3] / weight_sum * f;
    t[4] = a[4] / weight_sum * (1.0 - f) + b[4] / weight_sum * f;
    t[5] = a[5] / weight_sum * (1.0 - f) + b[5] / weight_sum * f;
    t[6] = a[6] / weight_sum * (1.0 - f) + b[6] / weight_sum * f;
}

// The visible share of the trilinear weight of one volume at a local position, sum
// trilinear_i * vis_i in [0, 1]: runtime::visibleWeight (visibleShare) term for term; 1 for a
// volume without visibility.
float pk_volume_visible_weight(uint s, vec3 local) {
    if (!pk_has_visibility(s)) {
        return 1.0;
    }
    float share = 0.0;
    const PkTaps taps = pk_volume_taps(s, local);
    // Per tap, the CPU's tx.weight[i] * ty.weight[j] * tz.weight[k] * vis, left to right.
    for (uint k = 0u; k < 8u; ++k) {
        uvec3 probe;
        vec3 axis;
        vec3 offset;
        pk_tap(taps, k, probe, axis, offset);
        share += axis.x * axis.y * axis.z *
                 pk_probe_visibility(pk_visibility_texel(s, taps.visibility + ivec3(probe)),
                                     offset);
    }
    return share;
}

#define PK_FETCH_L1(STATE, S, UVW, T)                                                          \
    T[0] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 0], pk_linear_clamp), UVW, 0.0);     \
    T[1] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 1], pk_linear_clamp), UVW, 0.0);     \
    T[2] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 2], pk_linear_clamp), UVW, 0.0);
#define PK_FETCH_L2(STATE, S, UVW, T)                                                          \
    T[3] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 3], pk_linear_clamp), UVW, 0.0);     \
    T[4] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 4], pk_linear_clamp), UVW, 0.0);     \
    T[5] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 5], pk_linear_clamp), UVW, 0.0);     \
    T[6] = textureLod(sampler3D(STATE[(S)*PK_MAX_PLANES + 6], pk_linear_clamp), UVW, 0.0);
#define PK_FETCH_SLOT(S)                                                                       \
    case S:                                                                                    \
        PK_FETCH_L1(pk_state_a, S, uvw, t)                                                     \
        if (l2) {                                                                              \
            PK_FETCH_L2(pk_state_a, S, uvw, t)                                                 \
        }                                                                                      \
        if (blend) {                                                                           \
            PK_FETCH_L1(pk_state_b, S, uvw, tb)                                                \
            if (l2) {                                                                          \
                PK_FETCH_L2(pk_state_b, S, uvw, tb)                                            \
            }                                                                                  \
        }                                                                                      \
        break;

// The hardware-filtered texels of slot s at texture coordinate uvw: step 3 of the
// specification, i.e. the accumulation loop of runtime::sampleVolumeSh. A volume with a second
// state mixes the two filtered states, a (1 - f) + b f, which equals filtering the mixed texels
// (filtering is linear); f = 1 gives state b exactly. Planes a volume does not have are zero.
void pk_fetch_planes(uint s, vec3 uvw, out vec4 t[PK_MAX_PLANES]) {
    const uint flags = pk_volume_set.volumes[s].resolution.w;
    const bool l2 = (flags & PK_VOLUME_FLAG_L2) != 0u;
    const bool blend = (flags & PK_VOLUME_FLAG_BLEND) != 0u;
    const vec4 zero = vec4(0.0);
    t = vec4[PK_MAX_PLANES](zero, zero, zero, zero, zero, zero, zero);
    vec4 tb[PK_MAX_PLANES] = t;
    // One case per slot, so every array index is a constant (s is uniform in every caller).
    switch (s) {
        PK_FETCH_SLOT(0)
        PK_FETCH_SLOT(1)
        PK_FETCH_SLOT(2)
        PK_FETCH_SLOT(3)
        PK_FETCH_SLOT(4)
        PK_FETCH_SLOT(5)
        PK_FETCH_SLOT(6)
        PK_FETCH_SLOT(7)
    }
    if (blend) {
        const float f = pk_volume_set.volumes[s].boxMax.w;
        t[0] = t[0] * (1.0 - f) + tb[0] * f;
        t[1] = t[1] * (1.0 - f) + tb[1] * f;
        t[2] = t[2] * (1.0 - f) + tb[2] * f;
        t[3] = t[3] * (1.0 - f) + tb[3] * f;
        t[4] = t[4] * (1.0 - f) + tb[4] * f;
        t[5] = t[5] * (1.0 - f) + tb[5] * f;
        t[6] = t[6] * (1.0 - f) + tb[6] * f;
    }
}

// The interpolated texels of one volume at a local position: steps 1-3 (B1-B3) of
// runtime::sampleVolumeSh. Without visibility the hardware filter at pk_volume_uvw; with it
// (step V) the taps one by one, pk_visible_texels (and in PK_VISIBILITY_TAPS mode every volume
// so).
void pk_volume_texels(uint s, vec3 local, out vec4 t[PK_MAX_PLANES]) {
    if (pk_visibility_mode == PK_VISIBILITY_TAPS ||
        (pk_visibility_mode == PK_VISIBILITY_BRANCH && pk_has_visibility(s))) {
        pk_visible_texels(s, pk_volume_taps(s, local), t);
    } else {
        pk_fetch_planes(s, pk_volume_uvw(s, local), t);
    }
}

// Irradiance of one volume at a local position. Mirrors
// sh::irradiance(runtime::sampleVolumeSh(volume, p), order, n).
vec3 pk_volume_irradiance(uint s, vec3 local, vec3 n) {
    vec4 t[PK_MAX_PLANES];
    pk_volume_texels(s, local, t);
    vec3 sh[9];
    pk_unpack_probe(t, (pk_volume_set.volumes[s].resolution.w & PK_VOLUME_FLAG_L2) != 0u, sh);
    return pk_sh_irradiance(sh, n);
}

// Where no volume covers p, VolumeSet::irradiance samples the nearest box alone. Passing over
// the volumes once without fetching anything finds out which case applies, so that the
// blending pass below has one fetch site: SIMD implementations (GPUs, lavapipe) then fetch
// each volume once for a group of pixels, not once per case.
void pk_coverage(vec3 p, out bool covered, out uint nearest) {
    const uint count = pk_volume_set.header.x;
    covered = false;
    nearest = pk_blend_slot(0u);
    float nearest_distance = 0.0;
    for (uint i = 0u; i < count; ++i) {
        const uint s = pk_blend_slot(i);
        const vec3 local = pk_to_local(s, p);
        covered = covered || pk_volume_weight(s, local) > 0.0;
        // Ties go to the earlier volume in blending order, as on the CPU.
        const float d = pk_distance_to_volume(s, local);
        if (i == 0u || d < nearest_distance) {
            nearest = s;
            nearest_distance = d;
        }
    }
}

// The share a = w * remaining of the i-th volume in blending order at p, with its slot s and
// p in its local frame: w is its blend weight (pk_volume_weight) when some volume covers p,
// else 1 for the nearest volume alone. The one blending rule of pk_irradiance,
// pk_fetch_only and pk_visible_weight (runtime::VolumeSet::irradiance on the CPU).
float pk_blend_share(uint i, vec3 p, bool covered, uint nearest, float remaining, out uint s,
                     out vec3 local) {
    s = pk_blend_slot(i);
    local = pk_to_local(s, p);
    const float w = covered ? pk_volume_weight(s, local) : (s == nearest ? 1.0 : 0.0);
    return w * remaining;
}

// One blending pass over the volumes, as pk_blended and pk_fetch_only make it: the sample point
// p (moved params.x metres along the normal; the CPU's normal_offset), the coverage pass's
// result, the CPU loop's running sums (`remaining`, the weight not yet given out, and
// `weight_sum`, the shares given), and the current volume: its slot s, p in its local frame
// and its share a.
struct PkBlend {
    vec3 p;
    bool covered;
    uint nearest;
    float remaining;
    float weight_sum;
    uint s;
    vec3 local;
    float a;
};

PkBlend pk_blend_begin(vec3 world_position, vec3 normal) {
    PkBlend blend;
    blend.p = world_position + pk_volume_set.params.x * normal;
    pk_coverage(blend.p, blend.covered, blend.nearest);
    blend.remaining = 1.0;
    blend.weight_sum = 0.0;
    return blend;
}

// Step i of the pass: the i-th volume's share a (pk_blend_share), slot s and local sample
// point. True, with a added to weight_sum and taken from remaining (the CPU's weight_sum += a;
// remaining -= a), when the volume is sampled: a > 0.
bool pk_blend_step(inout PkBlend blend, uint i) {
    blend.a = pk_blend_share(i, blend.p, blend.covered, blend.nearest, blend.remaining, blend.s,
                             blend.local);
    if (blend.a > 0.0) {
        blend.weight_sum += blend.a;
        blend.remaining -= blend.a;
    }
    return blend.a > 0.0;
}

// The blend over every volume of the set of one per-volume value, sum a_v value_v / sum a_v with
// pk_blend_step's shares: E (pk_volume_irradiance) in xyz, or, when `visible_share`, the visible
// share (pk_volume_visible_weight) in every component. The one loop of pk_irradiance and
// pk_visible_weight.
//
// The CPU loop skips volumes of weight 0 and stops once `remaining` reaches 0; here every
// volume is visited (a loop without divergent exits keeps the slot uniform, so
// pk_fetch_planes' switch stays a real branch) and a volume is sampled only when its share
// a = w * remaining is positive, which selects exactly the volumes the CPU samples. Outside
// every volume the nearest one takes weight 1, giving the value of that volume alone.
vec4 pk_blended(vec3 world_position, vec3 normal, bool visible_share) {
    PkBlend blend = pk_blend_begin(world_position, normal);
    vec4 weighted_sum = vec4(0.0);
    for (uint i = 0u; i < pk_volume_set.header.x; ++i) {
        if (pk_blend_step(blend, i)) {
            const uint s = blend.s;
            const vec3 local = blend.local;
            weighted_sum +=
                blend.a * (visible_share ? vec4(pk_volume_visible_weight(s, local))
                                         : vec4(pk_volume_irradiance(s, local, normal), 0.0));
        }
    }
    // Normalising keeps the last volume's fade band from fading to black.
    return weighted_sum / blend.weight_sum;
}

// Irradiance E (W/m^2, not divided by pi) at world position p for a receiver with unit world
// normal n, blended over every volume of the set (pk_blended). Mirrors, term for term,
// probekit::runtime::VolumeSet::irradiance(p, n, normal_offset) (runtime/src/sampler.cpp), with
// normal_offset = params.x: the sample point moves that many metres along n, away from the
// surface whose probes may sit behind it (self-leaking); 0 samples p itself.
vec3 pk_irradiance(vec3 world_position, vec3 normal) {
    return pk_blended(world_position, normal, false).xyz;
}

// Irradiance from one probe's own coefficients, no interpolation: sh::irradiance of
// Volume::probe. `probe`: grid coordinates (dense) or, for a bricked volume, (brick index,
// probe index in the brick 0..63, 0). At a texel centre ((probe + 0.5) / res, exact for
// power-of-two resolutions; the atlas texel of the brick probe, whose size A * 4 need not be a
// power of two, so the centre is within a float rounding of exact), linear filtering weighs that
// texel alone.
vec3 pk_probe_irradiance(uint s, uvec3 probe, vec3 n) {
    vec4 t[PK_MAX_PLANES];
    if (pk_is_bricked(s)) {
        const uint k = probe.y;
        pk_fetch_planes(s, pk_atlas_uvw(s, probe.x, vec3(k & 3u, (k >> 2u) & 3u, k >> 4u)), t);
    } else {
        pk_fetch_planes(s, (vec3(probe) + 0.5) / vec3(pk_volume_set.volumes[s].resolution.xyz),
                        t);
    }
    vec3 sh[9];
    pk_unpack_probe(t, (pk_volume_set.volumes[s].resolution.w & PK_VOLUME_FLAG_L2) != 0u, sh);
    return pk_sh_irradiance(sh, n);
}

// The texture fetches of pk_irradiance and nothing else: the same volumes (the same coverage
// pass and shares, so the same fetches) at the same coordinates, but no SH unpacking,
// evaluation or weighted sums; the fetched texels are added up so none is optimised away. The
// cost floor of pk_irradiance, for benchmarks.
vec4 pk_fetch_only(vec3 world_position, vec3 normal) {
    PkBlend blend = pk_blend_begin(world_position, normal);
    vec4 sum = vec4(0.0);
    for (uint i = 0u; i < pk_volume_set.header.x; ++i) {
        if (pk_blend_step(blend, i)) {
            vec4 t[PK_MAX_PLANES];
            pk_volume_texels(blend.s, blend.local, t);
            sum += t[0] + t[1] + t[2] + t[3] + t[4] + t[5] + t[6];
        }
    }
    return sum;
}

// The visible share of the trilinear weight at world position p (the leak view,
// `probekit render --view leak`): pk_volume_visible_weight (runtime::visibleWeight) blended
// over the volumes with pk_irradiance's shares, sum a_v share_v / sum a_v, at the same sample
// point (normal offset) and with the same nearest-volume rule outside every box. 1 where no
// tap is hidden, near 0 where plain trilinear interpolation would pull light through a wall.
float pk_visible_weight(vec3 world_position, vec3 normal) {
    return pk_blended(world_position, normal, true).x;
}

#endif // PK_VOLUME_SET

#endif
