// probekit GPU layout of a probe-volume set, shared by C++ (probekit/runtime/gpu_volumes.hpp) and
// GLSL (shaders/probe_volume.glsl). One definition, so the two can never drift: C++ checks every
// size and offset below with static_assert; GLSL reads the same structs as a std140 uniform
// block. Every member is a vec4/uvec4 (16-byte rows, marked with their byte offsets), so std140
// adds no padding and C++ needs no alignment attributes.
//
// Units: metres, glTF world frame (formats/CONVENTIONS.md).
#ifndef PROBEKIT_PROBE_VOLUME_LAYOUT_H
#define PROBEKIT_PROBE_VOLUME_LAYOUT_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>

#include <glm/vec4.hpp>

namespace probekit::gpu {
using vec4 = glm::vec4;
using uvec4 = glm::uvec4;
#endif

// Volumes one set can hold; pk_irradiance blends all of them. 8 volumes x 7 planes x 2 states
// + 8 integer images (indirection and visibility, below) = 120 sampled images, within lavapipe's
// 128 per shader stage (Vulkan's portable minimum is far lower; desktop drivers allow
// thousands). With its uniform buffer the set holds 121 of lavapipe's maxPerStageResources
// (128, which counts every descriptor but samplers), leaving 7 for the application's own (the
// renderer's shading pass uses exactly those: a uniform buffer and six storage images). So
// visibility has no images of its own: 8 more would make the set alone 129 (validation rejects
// the pipeline layout); it shares each slot's integer image with the indirection.
#define PK_MAX_VOLUMES 8
// Texel planes per volume state: 3 for L1, 7 for L2 (formats/.../volume.hpp).
#define PK_MAX_PLANES 7

// Descriptor bindings of the volume set (descriptor set PK_VOLUME_SET in GLSL).
#define PK_BINDING_VOLUMES 0 // uniform buffer: PkVolumeSetGpu
#define PK_BINDING_STATE_A 1 // texture3D[PK_MAX_VOLUMES * PK_MAX_PLANES]: element 7 slot + plane
#define PK_BINDING_STATE_B 2 // the same for the second state of each volume
#define PK_BINDING_SAMPLER 3 // sampler: linear filtering, clamp-to-edge, no mipmaps
// utexture3D[PK_MAX_VOLUMES]: element = slot, the slot's integer image (bricked indirection
// and/or visibility, below).
#define PK_BINDING_INDIRECTION 4
// Visibility (below) lives in the integer images of PK_BINDING_INDIRECTION: one binding, named
// twice so that readers looking for either find it.
#define PK_BINDING_VISIBILITY PK_BINDING_INDIRECTION
// Sampled images the set declares (per shader stage; see PK_MAX_VOLUMES).
#define PK_SAMPLED_IMAGES (2 * PK_MAX_VOLUMES * PK_MAX_PLANES + PK_MAX_VOLUMES)

// PkVolumeGpu.resolution.w flags.
#define PK_VOLUME_FLAG_L2 1u      // 7 planes (L2) rather than 3 (L1)
#define PK_VOLUME_FLAG_BLEND 2u   // mix state A and state B by boxMax.w
#define PK_VOLUME_FLAG_BRICKED 4u // bricked layout (formats/.../brick.hpp): indirection + atlas
// Visibility texels in the integer image (below): taps weighted by visibility (sampler.hpp V).
#define PK_VOLUME_FLAG_VISIBILITY 8u

// Bricked volumes (brick.hpp; sampled by pk_brick_uvw, the twin of runtime::sampleVolumeSh):
//  * The indirection image (R32_UINT, one texel per finest cell, extent = finest cells; with
//    visibility the lower part of an RG32_UINT integer image, below) holds
//    PK_BRICK_ENTRY(brick index, brick level) per cell in x: index * 4 + level.
//  * Each texel plane (and state) is one 3D brick atlas (the volume's storage format) of
//    bricks.xyz * PK_BRICK_SIZE texels: brick b's 4 x 4 x 4 probes (x fastest, as stored) fill
//    the slot (b % A.x, (b / A.x) % A.y, b / (A.x * A.y)), A = bricks.xyz
//    (runtime::brickAtlasSlots chooses A), texels slot * 4 .. slot * 4 + 3. Probe-local
//    coordinates in [0, 3] sample texel coordinate slot * 4 + 0.5 + local, so hardware
//    trilinear filtering never reaches a neighbouring slot.
#define PK_BRICK_SIZE 4u
#define PK_BRICK_ENTRY(index, level) ((index)*4u + (level))

// Visibility (formats/.../visibility.hpp; sampled by pk_volume_texels, the twin of step V of
// runtime::sampleVolumeSh), present when PK_VOLUME_FLAG_VISIBILITY is set:
//  * One R32G32_UINT texel per probe, read with texelFetch: x = q0 | q1 << 8 | q2 << 16 |
//    q3 << 24, y = q4 | q5 << 8, where q0..q5 are the probe's six bytes (q[2 axis + side]). Its
//    memory is the bytes q0..q5, 0, 0: the same as an RGBA16_UINT texel (q0 | q1 << 8,
//    q2 | q3 << 8, q4 | q5 << 8, 0); 32-bit components let a bricked volume's indirection share
//    the image (entries in x, as in the R32_UINT indirection).
//  * Dense: the slot's integer image is the visibility alone, extent = the grid, probe (x, y, z)
//    at texel (x, y, z).
//  * Bricked: the integer image holds the indirection at z in [0, C.z) (C = finest cells =
//    resolution.xyz; entries in x, y = 0) and the visibility atlas above it: brick b's probe
//    (x, y, z) at texel slot * 4 + (x, y, z) + (0, 0, C.z), the slot of the texel planes.
//    Extent (max(C.x, 4 A.x), max(C.y, 4 A.y), C.z + 4 A.z).
//  * Without visibility a dense slot binds a dummy and a bricked one its R32_UINT indirection.
// The visibility belongs to the volume's geometry: both states are weighted by the primary's.
// Tap weight (visibility.hpp): w_i = trilinear_i * (vis_i + PK_VISIBILITY_FLOOR), vis_i falling
// from 1 to 0 over PK_VISIBILITY_RAMP cells beyond the stored distance q / 255.
#define PK_VISIBILITY_RAMP (1.0 / 32.0) // visibility::kRamp, cells
#define PK_VISIBILITY_FLOOR 1.0e-3      // visibility::kFloor
// Specialization constant id of probe_volume.glsl's pk_visibility_mode (uint), and its values
// (how pk_irradiance samples volumes with visibility; probe_volume.glsl says when to use which).
#define PK_CONSTANT_VISIBILITY 1001
#define PK_VISIBILITY_OFF 0u    // compiled out: only for sets without visibility
#define PK_VISIBILITY_BRANCH 1u // default: a uniform branch per volume, taps or filter
#define PK_VISIBILITY_TAPS 2u   // every volume tap by tap, no hardware-filtered fetch

// One volume. World -> local is the inverse of the volume's rigid frame:
// local = R^T (world - t), with the rows of R^T in xyz and t in w.
struct PkVolumeGpu {
    vec4 worldToLocal0; // bytes   0..15: row 0 of R^T; w = t.x (m)
    vec4 worldToLocal1; // bytes  16..31: row 1 of R^T; w = t.y (m)
    vec4 worldToLocal2; // bytes  32..47: row 2 of R^T; w = t.z (m)
    vec4 boxMin;        // bytes  48..63: local box min (m); w = fade distance (m, 0 = hard)
    vec4 boxMax;        // bytes  64..79: local box max (m); w = state blend factor in [0, 1]
    vec4 spacing;       // bytes  80..95: dense: probe spacing per axis (m); w = grid offset
                        //                (0.5 center mode, 0 corner mode). Bricked: zero
    uvec4 resolution;   // bytes 96..111: dense: probes per axis; bricked: finest cells per
                        //                axis; w = PK_VOLUME_FLAG_* bits
    uvec4 bricks;       // bytes 112..127: bricked: xyz = atlas slots per axis (A), w = max
                        //                 level; dense: zero
};

// The whole set: one uniform buffer.
struct PkVolumeSetGpu {
    uvec4 header;                        // bytes  0..15: x = volume count; yzw zero
    vec4 params;                         // bytes 16..31: x = normal offset (m); yzw zero
    uvec4 order[PK_MAX_VOLUMES / 4];     // bytes 32..63: blending order, slot of the i-th
                                         //   volume at order[i / 4][i % 4] (descending
                                         //   priority, ties in set order)
    PkVolumeGpu volumes[PK_MAX_VOLUMES]; // bytes 64..1087: by slot (= index in the set)
};

#ifdef __cplusplus
static_assert(sizeof(vec4) == 16 && sizeof(uvec4) == 16, "GLM vectors must be tightly packed");
static_assert(offsetof(PkVolumeGpu, worldToLocal0) == 0);
static_assert(offsetof(PkVolumeGpu, worldToLocal1) == 16);
static_assert(offsetof(PkVolumeGpu, worldToLocal2) == 32);
static_assert(offsetof(PkVolumeGpu, boxMin) == 48);
static_assert(offsetof(PkVolumeGpu, boxMax) == 64);
static_assert(offsetof(PkVolumeGpu, spacing) == 80);
static_assert(offsetof(PkVolumeGpu, resolution) == 96);
static_assert(offsetof(PkVolumeGpu, bricks) == 112);
static_assert(sizeof(PkVolumeGpu) == 128, "std140 array stride of PkVolumeGpu");
static_assert(offsetof(PkVolumeSetGpu, header) == 0);
static_assert(offsetof(PkVolumeSetGpu, params) == 16);
static_assert(offsetof(PkVolumeSetGpu, order) == 32);
static_assert(offsetof(PkVolumeSetGpu, volumes) == 64);
static_assert(sizeof(PkVolumeSetGpu) == 64 + 128 * PK_MAX_VOLUMES);
static_assert(PK_MAX_VOLUMES % 4 == 0, "order[] packs four slots per uvec4");
static_assert(PK_SAMPLED_IMAGES == 120, "the budget PK_MAX_VOLUMES describes");
static_assert(PK_BINDING_VISIBILITY == PK_BINDING_INDIRECTION, "one integer image per slot");
static_assert((PK_VOLUME_FLAG_VISIBILITY &
               (PK_VOLUME_FLAG_L2 | PK_VOLUME_FLAG_BLEND | PK_VOLUME_FLAG_BRICKED)) == 0,
              "flags are distinct bits");
} // namespace probekit::gpu
#endif

#endif
