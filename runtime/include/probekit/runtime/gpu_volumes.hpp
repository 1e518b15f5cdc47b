// probekit::runtime::GpuVolumeSet — probe volumes as Vulkan 3D textures, sampled in GLSL by
// pk_irradiance (shaders/probe_volume.glsl), the GPU twin of VolumeSet::irradiance.
//
// Each volume is uploaded in its stored format (RGBA16F or RGBA32F texels, unconverted) as one
// 3D image per texel plane (3 for L1, 7 for L2; packing in formats/.../volume.hpp), through a
// host-visible staging buffer. A sampler with linear filtering, clamp-to-edge addressing and no
// mipmaps makes hardware trilinear filtering at texture coordinate (g + 0.5) / res the clamp +
// trilinear step of the CPU sampler (runtime/include/probekit/runtime/sampler.hpp).
//
// Bricked volumes (formats/.../brick.hpp) are uploaded as an indirection image (R32_UINT, one
// texel per finest cell: brick index * 4 + level) plus one brick atlas per texel plane: each
// brick's 4 x 4 x 4 probes in one slot of 4 x 4 x 4 texels, slots laid out by brickAtlasSlots
// (layout in shaders/probe_volume_layout.h). Hardware trilinear filtering inside a slot is the
// brick interpolation of the CPU sampler (sampleVolumeSh's bricked steps).
//
// Visibility (formats/.../visibility.hpp, leak-proof interpolation) of a volume that has it is
// uploaded as one RG32_UINT texel per probe (the probe's six bytes, then two zero bytes:
// probe_volume_layout.h's "Visibility") into the slot's integer image, which a bricked volume
// shares with its indirection (the set has no room for more images: PK_MAX_VOLUMES). Such a
// volume carries PK_VOLUME_FLAG_VISIBILITY, and pk_irradiance interpolates it tap by tap with
// visibility weights, the CPU sampler's step V. Visibility belongs to the volume's geometry:
// it comes with the primary state (create, replaceVolume, updateBox), both states are weighted
// by it, and a second state's own visibility bytes are ignored.
//
// The descriptor set (layout: probe_volume_layout.h, bindings PK_BINDING_*) holds one uniform
// buffer (gpu::PkVolumeSetGpu: frames, boxes, fades, blending order, flags) and the planes of
// up to PK_MAX_VOLUMES volumes in two states. Applications create their pipeline layouts with
// createVolumeSetLayout (or descriptorSetLayout()), bind descriptorSet() at the set index they
// #define as PK_VOLUME_SET before including probe_volume.glsl, and call pk_irradiance.
//
// Dynamic updates and synchronisation. All calls use the context's queue, from one thread.
//  * replaceVolume / updateBox upload texels and return when the copy has completed. Their
//    command buffer first waits (pipeline barrier) for every shader read submitted before it on
//    the queue, so earlier frames see the old texels and later frames the new ones: no frame
//    ever samples a half-copied volume. updateBox copies exactly the texels of the box.
//  * setFrame, setStateBlend and setNormalOffset only change CPU-side uniforms. They reach the
//    GPU through recordUniformUpdate(cmd), which the application records once per frame
//    (outside a render pass, before its commands that sample the set); the data is captured in
//    the command buffer at record time, so frames in flight keep the values they were
//    recorded with. No texel is re-uploaded; a moved volume samples its texels in its new frame.
//  * A primary replacement that changes a bricked volume's layout (or turns a dense volume
//    into a bricked one or back) reallocates the slot's images and rewrites the descriptor
//    set, with the same waiting and invalidation as allocating a second state.
//  * A volume's second state (replaceVolume(..., VolumeState::Secondary)) is mixed with the
//    first by setStateBlend's factor f on the GPU, a (1 - f) + b f per filtered texel, so
//    animating f costs no upload. Allocating the second state rewrites the descriptor set: it
//    waits for the queue to go idle and invalidates command buffers recorded earlier with the
//    set bound (record them again).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>
#include <vulkan/vulkan.h>

#include "probe_volume_layout.h"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"
#include "probekit/runtime/gpu_context.hpp"

namespace probekit::runtime {

constexpr size_t kMaxGpuVolumes = PK_MAX_VOLUMES;

// Which of a volume's two texel states an upload writes.
enum class VolumeState : uint8_t {
    Primary = 0,   // what the volume shows at blend factor 0 (always present)
    Secondary = 1, // what it shows at blend factor 1 (allocated on first upload)
};

// ---- CPU-side packing (pure functions, no Vulkan; unit-tested without a GPU) ----

// Blending order: indices of `descs` by descending blendPriority, ties in index order. The same
// order VolumeSet::irradiance visits.
std::vector<uint32_t> blendOrder(std::span<const VolumeDesc> descs);

// Brick-atlas slots per axis (A in probe_volume_layout.h) for `brick_count` bricks on a device
// whose 3D images may be `max_image_dimension_3d` texels per axis: powers of two, the fewest
// slots that hold every brick (2^e slots, e = ceil(log2(brick_count)), so less than twice the
// bricks), e split as evenly as possible over the axes (x >= y >= z, each <= 2x the next), each
// axis at most max_image_dimension_3d / 4 slots. Powers of two make the atlas size 4 A one too,
// so the normalised coordinate (slot * 4 + 0.5 + local) / (4 A) and the filter's product with
// 4 A are exact: a coordinate on a slot's last probe cannot round into the next slot (with other
// sizes it can, by ~1e-6 of a texel, blending in an unrelated brick; measured 1.6e-4 of the
// irradiance on lavapipe). Fails with OutOfRange when brick_count is 0 or the bricks do not fit.
Result<glm::uvec3> brickAtlasSlots(size_t brick_count, uint32_t max_image_dimension_3d);

// The atlas slot of brick `index`: (index % A.x, (index / A.x) % A.y, index / (A.x * A.y)).
glm::uvec3 brickAtlasSlot(uint32_t index, glm::uvec3 atlas_slots);

// One volume's uniforms. `blend` in [0, 1] is the factor towards the second state; > 0 sets
// PK_VOLUME_FLAG_BLEND (the caller guarantees a second state is bound). `atlas_slots`: for a
// bricked volume the brickAtlasSlots its atlas was made with; ignored for dense volumes.
// `visibility` sets PK_VOLUME_FLAG_VISIBILITY (the caller guarantees the visibility texels are
// bound).
gpu::PkVolumeGpu packVolumeGpu(const VolumeDesc& desc, float blend,
                               glm::uvec3 atlas_slots = glm::uvec3(0u), bool visibility = false);

// The whole uniform buffer. Preconditions (checked in every build type; a failure prints the
// condition and aborts, ARCHITECTURE.md "Preconditions"): 1 <= descs.size() <= kMaxGpuVolumes,
// blends has one entry per volume, atlas_slots one per volume or (no bricked volumes) none,
// visibility one per volume (nonzero: the volume has visibility) or (none has) none.
gpu::PkVolumeSetGpu packVolumeSetGpu(std::span<const VolumeDesc> descs,
                                     std::span<const float> blends, float normal_offset,
                                     std::span<const glm::uvec3> atlas_slots = {},
                                     std::span<const uint8_t> visibility = {});

// Visibility texels (probe_volume_layout.h): 8 bytes per probe, the probe's six visibility
// bytes then two zero bytes, i.e. RG32_UINT (q0 | q1 << 8 | q2 << 16 | q3 << 24, q4 | q5 << 8)
// (and the same memory as RGBA16_UINT (q0 | q1 << 8, q2 | q3 << 8, q4 | q5 << 8, 0)).
constexpr size_t kVisibilityTexelBytes = 8;
// The visibility texels of the probes [first, first + count) of a dense volume with
// visibility, z, y, x (x fastest). Preconditions (checked as packTexelBox's): the box's, the
// volume's visibility is kBytesPerProbe per probe, and `out` holds visibilityBoxBytes(count)
// bytes.
size_t visibilityBoxBytes(glm::uvec3 count);
void packVisibilityBox(const Volume& volume, glm::uvec3 first, glm::uvec3 count,
                       std::span<uint8_t> out);
// The extent of a bricked volume's integer image with visibility: the indirection (`cells`)
// and, above it along z, the visibility atlas (`atlas_slots` * 4 texels per axis).
glm::uvec3 brickedIntegerExtent(glm::uvec3 cells, glm::uvec3 atlas_slots);

// The texels of the probes [first, first + count) of every plane, in staging order: plane by
// plane, then z, y, x (x fastest), in the volume's storage format (raw float or half bits).
// Dense volumes only. Preconditions (checked in every build type; a failure prints the
// condition and aborts, ARCHITECTURE.md "Preconditions"): the volume is dense and holds
// planes * probes * 4 texel components, count >= 1 per axis and first + count <= resolution,
// and `out` holds texelBoxBytes(volume, count) bytes.
size_t texelBoxBytes(const Volume& volume, glm::uvec3 count);
void packTexelBox(const Volume& volume, glm::uvec3 first, glm::uvec3 count, std::span<uint8_t> out);

// Creates the descriptor set layout probe_volume.glsl declares (all shader stages). Identically
// defined layouts are compatible, so pipelines made with it accept any GpuVolumeSet's set. The
// caller destroys it.
Result<VkDescriptorSetLayout> createVolumeSetLayout(const GpuContext& context);

class GpuVolumeSet {
public:
    // Uploads every volume (1..kMaxGpuVolumes of them; each must pass validateVolume) in its
    // primary state, blend factors 0, normal offset 0. The context must outlive the set.
    static Result<GpuVolumeSet> create(GpuContext& context, std::span<const Volume> volumes);

    GpuVolumeSet(GpuVolumeSet&&) noexcept;
    GpuVolumeSet& operator=(GpuVolumeSet&&) noexcept;
    ~GpuVolumeSet();

    size_t size() const;
    // Index = slot = position in the `volumes` given to create. The accessors below check
    // index < size() in every build type (a failure prints the condition and aborts,
    // ARCHITECTURE.md "Preconditions"); the update calls (replaceVolume, updateBox, setFrame,
    // setStateBlend) fail with OutOfRange instead.
    // The volume as the GPU sees it (after setFrame and replaceVolume).
    const VolumeDesc& desc(size_t index) const;
    // Validity bytes of the primary state (one per probe).
    const std::vector<uint8_t>& validity(size_t index) const;
    // Whether the volume has visibility (its primary state's Volume::visibility was not empty).
    bool hasVisibility(size_t index) const;
    // Whether any volume of the set has: pipelines that specialise pk_visibility_mode
    // PK_VISIBILITY_OFF (shaders/probe_volume.glsl) must not sample a set for which this is
    // true.
    bool anyVisibility() const;
    bool hasSecondState(size_t index) const;
    float stateBlend(size_t index) const;
    float normalOffset() const;
    // Bytes of texel data held on the GPU (both states; for bricked volumes the whole atlas,
    // unused slots included, plus the u32 indirection) and of the integer images (indirection
    // and visibility: for a bricked volume with visibility its whole image, 8 bytes a texel).
    size_t texelBytes() const;
    // Bytes copied to the GPU since creation (initial uploads included): texels, and for the
    // primary state the integer images' data (indirection entries, visibility texels); moving a
    // volume or changing a blend factor leaves it unchanged.
    size_t uploadedBytes() const;

    VkDescriptorSetLayout descriptorSetLayout() const;
    VkDescriptorSet descriptorSet() const;

    // Replaces a state's texels (and, for the primary state, validity, visibility and desc:
    // bounds, frame, fade, priority, name) with `volume`'s. A primary replacement may switch
    // visibility on or off (the slot's integer image is reallocated, and the descriptor set
    // rewritten, with the waiting and invalidation of a relayout below); a secondary one
    // ignores `volume`'s visibility. SH order and storage must match the slot's. A
    // dense slot replaced by a dense volume keeps its images: resolution and position mode
    // must match. A primary replacement where the slot or `volume` is bricked may change the
    // layout (top bricks, brick list, dense <-> bricked): the images are reallocated when their
    // shapes change, unless the slot has a second state (then the layout must stay). A
    // secondary state must have the primary's bounds and layout (for bricked volumes the same
    // top bricks and brick list). Fails with InvalidArgument naming the mismatch.
    Result<void> replaceVolume(size_t index, const Volume& volume,
                               VolumeState state = VolumeState::Primary);

    // Copies the texels of probes [first, first + count) from `source` (same layout as the
    // slot) into a state, and nothing else; for the primary state the validity and visibility
    // of the box too (`source` must then have visibility exactly when the slot has; a
    // secondary update ignores it). Dense volumes only. Fails with OutOfRange when the box is
    // empty or leaves the grid, and with InvalidArgument for a bricked slot or source (a box
    // of probes means nothing in the atlas: replace the whole volume) or a visibility
    // mismatch.
    Result<void> updateBox(size_t index, const Volume& source, glm::uvec3 first, glm::uvec3 count,
                           VolumeState state = VolumeState::Primary);

    // Moves a volume (new local -> world frame); texels stay where they are. Fails on a
    // non-unit or non-finite rotation or translation.
    Result<void> setFrame(size_t index, const grid::RigidFrame& frame);

    // Mix factor towards the second state, clamped to [0, 1] (NaN counts as 0). Fails with
    // InvalidArgument, changing nothing, when the clamped factor is not 0 and the volume has no
    // second state.
    Result<void> setStateBlend(size_t index, float blend);

    // Metres along the receiver normal that pk_irradiance moves its sample point (against
    // self-leaking; VolumeSet::irradiance's normal_offset). 0 reproduces the CPU sampler.
    void setNormalOffset(float metres);

    // Records the uniform update of the changes above (nothing when there are none) with the
    // barriers that order it after earlier shader reads and before later ones. Outside a
    // render pass.
    void recordUniformUpdate(VkCommandBuffer cmd);

private:
    struct Impl;
    explicit GpuVolumeSet(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> m_impl;
};

} // namespace probekit::runtime
