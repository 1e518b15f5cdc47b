#include "probekit/runtime/gpu_volumes.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstring>
#include <numeric>
#include <string>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

#include "probekit/formats/check.hpp"
#include "vk_util.hpp"

namespace probekit::runtime {

using detail::Buffer;
using detail::Image;

namespace {

constexpr uint32_t kPlaneElements = PK_MAX_VOLUMES * PK_MAX_PLANES;
// The shader's visibility constants are the CPU sampler's.
static_assert(float(PK_VISIBILITY_RAMP) == visibility::kRamp);
static_assert(float(PK_VISIBILITY_FLOOR) == visibility::kFloor);
static_assert(kVisibilityTexelBytes >= visibility::kBytesPerProbe);
// The integer images: the indirection alone, or the indirection and visibility (bricked) or
// the visibility alone (dense) in 32-bit components.
constexpr VkFormat kIndirectionFormat = VK_FORMAT_R32_UINT;
constexpr VkFormat kVisibilityFormat = VK_FORMAT_R32G32_UINT;
// Shader reads of the set may happen in any stage the application uses.
constexpr VkPipelineStageFlags kAnyStage = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;

// The barriers around every upload: waits for every shader read submitted earlier
// (write-after-read) and makes the image a transfer destination; `old_layout` UNDEFINED
// discards its contents.
void beginImageUpload(VkCommandBuffer cmd, VkImage image, VkImageLayout old_layout) {
    detail::imageBarrier(cmd, image, VK_IMAGE_ASPECT_COLOR_BIT, old_layout,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, kAnyStage, 0,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
}

// Copies staging-buffer regions into an image begun with beginImageUpload and hands it back
// to shader reads.
void finishImageUpload(VkCommandBuffer cmd, VkBuffer staging, VkImage image,
                       std::span<const VkBufferImageCopy> regions) {
    vkCmdCopyBufferToImage(cmd, staging, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           uint32_t(regions.size()), regions.data());
    detail::imageBarrier(cmd, image, VK_IMAGE_ASPECT_COLOR_BIT,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_ACCESS_TRANSFER_WRITE_BIT, kAnyStage, VK_ACCESS_SHADER_READ_BIT);
}

VkFormat texelFormat(Storage storage) {
    return storage == Storage::Float32 ? VK_FORMAT_R32G32B32A32_SFLOAT
                                       : VK_FORMAT_R16G16B16A16_SFLOAT;
}

size_t texelSize(Storage storage) {
    return 4 * bytesPerComponent(storage);
}

std::string slotName(size_t index, const VolumeDesc& desc) {
    return "volume " + std::to_string(index) + " (\"" + desc.name + "\")";
}

std::string extentText(glm::uvec3 e) {
    return std::to_string(e.x) + "x" + std::to_string(e.y) + "x" + std::to_string(e.z);
}

bool isBricked(const VolumeDesc& desc) {
    return desc.layout == VolumeLayout::Bricked;
}

// Whether the box [first, first + count) is non-empty and inside `resolution` on one axis,
// written so that first + count cannot overflow.
bool axisInside(uint32_t first, uint32_t count, uint32_t resolution) {
    return count != 0 && first < resolution && count <= resolution - first;
}

bool boxInside(glm::uvec3 first, glm::uvec3 count, glm::uvec3 resolution) {
    return axisInside(first.x, count.x, resolution.x) &&
           axisInside(first.y, count.y, resolution.y) && axisInside(first.z, count.z, resolution.z);
}

// Whether a volume's stored texels are as many as its planes and probes need (validateVolume's
// size rule, without its linear passes).
bool holdsTexels(const Volume& volume) {
    const size_t have =
        volume.desc.storage == Storage::Float32 ? volume.texelsF32.size() : volume.texelsF16.size();
    return have == size_t(volume.planes()) * volume.probeCount() * 4;
}

// Whether `incoming` has `current`'s texel format; the reason when not.
std::string formatMismatch(const VolumeDesc& current, const VolumeDesc& incoming) {
    if (current.shOrder != incoming.shOrder) {
        return "SH order differs";
    }
    if (current.storage != incoming.storage) {
        return std::string("storage ") + std::string(toString(incoming.storage)) +
               " differs from the uploaded " + std::string(toString(current.storage));
    }
    return {};
}

// Whether `incoming` can be written into images made for `current`; the reason when not.
std::string layoutMismatch(const VolumeDesc& current, const VolumeDesc& incoming) {
    if (isBricked(current) != isBricked(incoming)) {
        return std::string("layout ") + std::string(toString(incoming.layout)) +
               " differs from the uploaded " + std::string(toString(current.layout));
    }
    if (isBricked(current)) {
        if (current.grid.resolution() != incoming.grid.resolution()) {
            return "top bricks " + extentText(incoming.grid.resolution()) +
                   " differ from the uploaded " + extentText(current.grid.resolution());
        }
        if (current.bricks != incoming.bricks) {
            return "brick layout differs from the uploaded one";
        }
        return formatMismatch(current, incoming);
    }
    const glm::uvec3 a = current.grid.resolution();
    const glm::uvec3 b = incoming.grid.resolution();
    if (a != b) {
        return "resolution " + extentText(b) + " differs from the uploaded " + extentText(a);
    }
    if (current.grid.mode() != incoming.grid.mode()) {
        return "position mode differs";
    }
    return formatMismatch(current, incoming);
}

} // namespace

std::vector<uint32_t> blendOrder(std::span<const VolumeDesc> descs) {
    std::vector<uint32_t> order(descs.size());
    std::iota(order.begin(), order.end(), 0u);
    // Stable, as VolumeSet's m_byPriority: equal priorities keep set order.
    std::stable_sort(order.begin(), order.end(), [descs](uint32_t a, uint32_t b) {
        return descs[a].blendPriority > descs[b].blendPriority;
    });
    return order;
}

Result<glm::uvec3> brickAtlasSlots(size_t brick_count, uint32_t max_image_dimension_3d) {
    // Slots per axis: powers of two up to the largest that fits the device, 2^limit_log2.
    uint32_t limit_log2 = 0;
    while ((uint64_t(PK_BRICK_SIZE) << (limit_log2 + 1)) <= max_image_dimension_3d) {
        ++limit_log2;
    }
    uint32_t total_log2 = 0;
    while ((uint64_t(1) << total_log2) < brick_count) {
        ++total_log2;
    }
    if (brick_count == 0 || PK_BRICK_SIZE > max_image_dimension_3d || total_log2 > 3 * limit_log2) {
        return makeError(ErrorCode::OutOfRange, std::to_string(brick_count) +
                                                    " bricks do not fit a brick atlas of at most " +
                                                    std::to_string(1u << limit_log2) +
                                                    " slots per axis (maxImageDimension3D " +
                                                    std::to_string(max_image_dimension_3d) + ")");
    }
    // The exponent split as evenly as possible, x taking the remainder first.
    const uint32_t z = total_log2 / 3;
    const uint32_t y = (total_log2 - z) / 2;
    const uint32_t x = total_log2 - z - y;
    return glm::uvec3(1u << x, 1u << y, 1u << z);
}

glm::uvec3 brickAtlasSlot(uint32_t index, glm::uvec3 atlas_slots) {
    return {index % atlas_slots.x, (index / atlas_slots.x) % atlas_slots.y,
            index / (atlas_slots.x * atlas_slots.y)};
}

gpu::PkVolumeGpu packVolumeGpu(const VolumeDesc& desc, float blend, glm::uvec3 atlas_slots,
                               bool visibility) {
    const grid::GridLayout& layout = desc.grid;
    // Columns of R^T; row i of R^T is (m[0][i], m[1][i], m[2][i]).
    const glm::mat3 m = glm::mat3_cast(glm::conjugate(layout.frame().rotation));
    const glm::vec3 t = layout.frame().translation;
    gpu::PkVolumeGpu v{};
    v.worldToLocal0 = glm::vec4(m[0][0], m[1][0], m[2][0], t.x);
    v.worldToLocal1 = glm::vec4(m[0][1], m[1][1], m[2][1], t.y);
    v.worldToLocal2 = glm::vec4(m[0][2], m[1][2], m[2][2], t.z);
    v.boxMin = glm::vec4(layout.bounds().min, desc.fadeDistance);
    v.boxMax = glm::vec4(layout.bounds().max, blend);
    uint32_t flags = 0;
    if (desc.shOrder == sh::Order::L2) {
        flags |= PK_VOLUME_FLAG_L2;
    }
    if (blend > 0.0f) {
        flags |= PK_VOLUME_FLAG_BLEND;
    }
    if (visibility) {
        flags |= PK_VOLUME_FLAG_VISIBILITY;
    }
    if (isBricked(desc)) {
        flags |= PK_VOLUME_FLAG_BRICKED;
        v.resolution =
            glm::uvec4(brick::finestCells(layout.resolution(), desc.bricks.maxLevel), flags);
        v.bricks = glm::uvec4(atlas_slots, desc.bricks.maxLevel);
    } else {
        v.spacing =
            glm::vec4(layout.spacing(), layout.mode() == grid::PositionMode::Center ? 0.5f : 0.0f);
        v.resolution = glm::uvec4(layout.resolution(), flags);
    }
    return v;
}

gpu::PkVolumeSetGpu packVolumeSetGpu(std::span<const VolumeDesc> descs,
                                     std::span<const float> blends, float normal_offset,
                                     std::span<const glm::uvec3> atlas_slots,
                                     std::span<const uint8_t> visibility) {
    // Always on (ARCHITECTURE.md, "Preconditions"): set.volumes and set.order have room for
    // kMaxGpuVolumes, and the loop reads one blend, atlas shape and flag per volume.
    PK_CHECK(!descs.empty() && descs.size() <= kMaxGpuVolumes);
    PK_CHECK(blends.size() == descs.size());
    PK_CHECK(atlas_slots.empty() || atlas_slots.size() == descs.size());
    PK_CHECK(visibility.empty() || visibility.size() == descs.size());
    gpu::PkVolumeSetGpu set{};
    set.header = glm::uvec4(uint32_t(descs.size()), 0u, 0u, 0u);
    set.params = glm::vec4(normal_offset, 0.0f, 0.0f, 0.0f);
    const std::vector<uint32_t> order = blendOrder(descs);
    for (size_t i = 0; i < order.size(); ++i) {
        set.order[i / 4][int(i % 4)] = order[i];
    }
    for (size_t i = 0; i < descs.size(); ++i) {
        set.volumes[i] = packVolumeGpu(descs[i], blends[i],
                                       atlas_slots.empty() ? glm::uvec3(0u) : atlas_slots[i],
                                       !visibility.empty() && visibility[i] != 0);
    }
    return set;
}

size_t texelBoxBytes(const Volume& volume, glm::uvec3 count) {
    return size_t(volume.planes()) * count.x * count.y * count.z * texelSize(volume.desc.storage);
}

void packTexelBox(const Volume& volume, glm::uvec3 first, glm::uvec3 count,
                  std::span<uint8_t> bytes) {
    const grid::GridLayout& layout = volume.desc.grid;
    // Always on (ARCHITECTURE.md, "Preconditions"): the copies below read the box's rows from
    // the volume's texels and write them to `bytes` unchecked. Once per upload, not per probe.
    PK_CHECK(!isBricked(volume.desc));
    PK_CHECK(boxInside(first, count, layout.resolution()));
    PK_CHECK(holdsTexels(volume));
    PK_CHECK(bytes.size() == texelBoxBytes(volume, count));
    const size_t texel_bytes = texelSize(volume.desc.storage);
    const auto* source = volume.desc.storage == Storage::Float32
                             ? reinterpret_cast<const uint8_t*>(volume.texelsF32.data())
                             : reinterpret_cast<const uint8_t*>(volume.texelsF16.data());
    const size_t probes = volume.probeCount();
    const size_t row_bytes = count.x * texel_bytes;
    uint8_t* out = bytes.data();
    for (uint32_t p = 0; p < volume.planes(); ++p) {
        for (uint32_t z = first.z; z < first.z + count.z; ++z) {
            for (uint32_t y = first.y; y < first.y + count.y; ++y) {
                // A row of the box is contiguous in the plane (x fastest).
                const size_t probe = layout.linearIndex(glm::uvec3(first.x, y, z));
                std::memcpy(out, source + (p * probes + probe) * texel_bytes, row_bytes);
                out += row_bytes;
            }
        }
    }
}

size_t visibilityBoxBytes(glm::uvec3 count) {
    return size_t(count.x) * count.y * count.z * kVisibilityTexelBytes;
}

void packVisibilityBox(const Volume& volume, glm::uvec3 first, glm::uvec3 count,
                       std::span<uint8_t> bytes) {
    const grid::GridLayout& layout = volume.desc.grid;
    // Always on, as packTexelBox's.
    PK_CHECK(!isBricked(volume.desc));
    PK_CHECK(volume.visibility.size() == volume.probeCount() * visibility::kBytesPerProbe);
    PK_CHECK(boxInside(first, count, layout.resolution()));
    PK_CHECK(bytes.size() == visibilityBoxBytes(count));
    uint8_t* out = bytes.data();
    for (uint32_t z = first.z; z < first.z + count.z; ++z) {
        for (uint32_t y = first.y; y < first.y + count.y; ++y) {
            for (uint32_t x = first.x; x < first.x + count.x; ++x) {
                const size_t probe = layout.linearIndex(glm::uvec3(x, y, z));
                std::memcpy(out, &volume.visibility[probe * visibility::kBytesPerProbe],
                            visibility::kBytesPerProbe);
                std::memset(out + visibility::kBytesPerProbe, 0,
                            kVisibilityTexelBytes - visibility::kBytesPerProbe);
                out += kVisibilityTexelBytes;
            }
        }
    }
}

glm::uvec3 brickedIntegerExtent(glm::uvec3 cells, glm::uvec3 atlas_slots) {
    const glm::uvec3 atlas = atlas_slots * PK_BRICK_SIZE;
    return {std::max(cells.x, atlas.x), std::max(cells.y, atlas.y), cells.z + atlas.z};
}

Result<VkDescriptorSetLayout> createVolumeSetLayout(const GpuContext& context) {
    std::array<VkDescriptorSetLayoutBinding, 5> bindings{};
    bindings[0] = {PK_BINDING_VOLUMES, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_ALL,
                   nullptr};
    bindings[1] = {PK_BINDING_STATE_A, VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, kPlaneElements,
                   VK_SHADER_STAGE_ALL, nullptr};
    bindings[2] = {PK_BINDING_STATE_B, VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, kPlaneElements,
                   VK_SHADER_STAGE_ALL, nullptr};
    bindings[3] = {PK_BINDING_SAMPLER, VK_DESCRIPTOR_TYPE_SAMPLER, 1, VK_SHADER_STAGE_ALL, nullptr};
    bindings[4] = {PK_BINDING_INDIRECTION, VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, PK_MAX_VOLUMES,
                   VK_SHADER_STAGE_ALL, nullptr};
    VkDescriptorSetLayoutCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    info.bindingCount = uint32_t(bindings.size());
    info.pBindings = bindings.data();
    VkDescriptorSetLayout layout = VK_NULL_HANDLE;
    PK_VK_TRY(vkCreateDescriptorSetLayout(context.device(), &info, nullptr, &layout));
    return layout;
}

struct StateImages {
    std::array<Image, PK_MAX_PLANES> planes{};
    bool allocated = false;
    bool initialised = false; // holds data (layout SHADER_READ_ONLY_OPTIMAL)
};

struct Slot {
    VolumeDesc desc;
    std::vector<uint8_t> validity;
    bool visibility = false; // the primary state brought visibility data
    StateImages states[2];
    float blend = 0.0f;
    // Bricked only: the atlas shape (brickAtlasSlots), shared by both states (a second state
    // has the primary's layout).
    glm::uvec3 atlasSlots{0u};
    // The slot's integer image (PK_BINDING_INDIRECTION element, probe_volume_layout.h): bricked,
    // the indirection (R32_UINT) or the indirection and visibility (RG32_UINT); dense, the
    // visibility (RG32_UINT) or nothing (the dummy is bound).
    Image integer;
};

// Extent of one texel-plane image: the grid (dense) or the brick atlas (bricked).
VkExtent3D planeExtent(const Slot& slot) {
    const glm::uvec3 e =
        isBricked(slot.desc) ? slot.atlasSlots * PK_BRICK_SIZE : slot.desc.grid.resolution();
    return {e.x, e.y, e.z};
}

struct GpuVolumeSet::Impl {
    GpuContext* context = nullptr;
    VkDescriptorSetLayout layout = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet set = VK_NULL_HANDLE;
    VkSampler sampler = VK_NULL_HANDLE;
    Image dummy;            // bound to every element no plane uses
    Image dummyIndirection; // bound to every integer-image element no volume uses
    Buffer uniforms;
    Buffer staging; // reused and grown across uploads
    std::vector<Slot> slots;
    float normalOffset = 0.0f;
    bool dirty = true;
    size_t uploaded = 0;

    ~Impl();
    VkDevice device() const { return context->device(); }
    gpu::PkVolumeSetGpu packUniforms() const;
    Result<void> allocateState(const Slot& slot, StateImages& state);
    // The images of a slot's primary state (and, bricked, its atlas shape) and its integer
    // image.
    Result<void> allocateLayout(Slot& slot);
    // The slot's integer image for its desc, atlas shape and visibility (none for a dense slot
    // without visibility).
    Result<void> allocateIntegerImage(Slot& slot);
    void releaseImages(Slot& slot);
    Result<void> initDummy();
    Result<void> writeDescriptors();
    Result<void> ensureStaging(size_t bytes);
    Result<void> upload(size_t index, VolumeState which, const Volume& source, glm::uvec3 first,
                        glm::uvec3 count);
    Result<void> uploadBricked(size_t index, VolumeState which, const Volume& source);
    // The whole of `source` into a state: upload or uploadBricked.
    Result<void> uploadWhole(size_t index, VolumeState which, const Volume& source);
    void recordUniforms(VkCommandBuffer cmd);
};

GpuVolumeSet::Impl::~Impl() {
    if (context == nullptr) {
        return;
    }
    const VkDevice d = device();
    // Earlier submissions may still read the images.
    vkQueueWaitIdle(context->queue());
    for (Slot& slot : slots) {
        releaseImages(slot);
    }
    detail::destroy(d, dummy);
    detail::destroy(d, dummyIndirection);
    detail::destroy(d, uniforms);
    detail::destroy(d, staging);
    if (sampler != VK_NULL_HANDLE) {
        vkDestroySampler(d, sampler, nullptr);
    }
    if (pool != VK_NULL_HANDLE) {
        vkDestroyDescriptorPool(d, pool, nullptr);
    }
    if (layout != VK_NULL_HANDLE) {
        vkDestroyDescriptorSetLayout(d, layout, nullptr);
    }
}

gpu::PkVolumeSetGpu GpuVolumeSet::Impl::packUniforms() const {
    std::vector<VolumeDesc> descs;
    std::vector<float> blends;
    std::vector<glm::uvec3> atlas_slots;
    std::vector<uint8_t> visibility;
    for (const Slot& slot : slots) {
        descs.push_back(slot.desc);
        // A second state counts once it holds data (an upload that failed leaves none).
        blends.push_back(slot.states[1].initialised ? slot.blend : 0.0f);
        atlas_slots.push_back(slot.atlasSlots);
        visibility.push_back(slot.visibility && slot.integer.view != VK_NULL_HANDLE ? 1 : 0);
    }
    return packVolumeSetGpu(descs, blends, normalOffset, atlas_slots, visibility);
}

Result<void> GpuVolumeSet::Impl::allocateState(const Slot& slot, StateImages& state) {
    for (uint32_t p = 0; p < planeCount(slot.desc.shOrder); ++p) {
        Result<Image> image = detail::createImage(
            *context, VK_IMAGE_TYPE_3D, texelFormat(slot.desc.storage), planeExtent(slot),
            VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
            VK_IMAGE_ASPECT_COLOR_BIT);
        if (!image) {
            return image.error();
        }
        state.planes[p] = image.value();
    }
    state.allocated = true;
    return {};
}

Result<void> GpuVolumeSet::Impl::allocateLayout(Slot& slot) {
    if (isBricked(slot.desc)) {
        const uint32_t max_dimension = context->limits().maxImageDimension3D;
        Result<glm::uvec3> atlas = brickAtlasSlots(slot.desc.bricks.bricks.size(), max_dimension);
        if (!atlas) {
            return atlas.error();
        }
        slot.atlasSlots = atlas.value();
    } else {
        slot.atlasSlots = glm::uvec3(0u);
    }
    PK_TRY(allocateIntegerImage(slot));
    return allocateState(slot, slot.states[0]);
}

Result<void> GpuVolumeSet::Impl::allocateIntegerImage(Slot& slot) {
    detail::destroy(device(), slot.integer);
    glm::uvec3 extent;
    VkFormat format = kVisibilityFormat;
    if (isBricked(slot.desc)) {
        const uint32_t max_dimension = context->limits().maxImageDimension3D;
        const glm::uvec3 cells =
            brick::finestCells(slot.desc.grid.resolution(), slot.desc.bricks.maxLevel);
        if (glm::any(glm::greaterThan(cells, glm::uvec3(max_dimension)))) {
            return makeError(ErrorCode::OutOfRange,
                             "indirection of " + extentText(cells) +
                                 " finest cells exceeds the device's maxImageDimension3D " +
                                 std::to_string(max_dimension));
        }
        extent = cells;
        format = kIndirectionFormat;
        if (slot.visibility) {
            extent = brickedIntegerExtent(cells, slot.atlasSlots);
            format = kVisibilityFormat;
            if (glm::any(glm::greaterThan(extent, glm::uvec3(max_dimension)))) {
                return makeError(ErrorCode::OutOfRange,
                                 "indirection and visibility atlas (" + extentText(extent) +
                                     " texels) exceed the device's maxImageDimension3D " +
                                     std::to_string(max_dimension));
            }
        }
    } else if (slot.visibility) {
        extent = slot.desc.grid.resolution();
    } else {
        return {};
    }
    Result<Image> image = detail::createImage(
        *context, VK_IMAGE_TYPE_3D, format, {extent.x, extent.y, extent.z},
        VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
    if (!image) {
        return image.error();
    }
    slot.integer = image.value();
    return {};
}

void GpuVolumeSet::Impl::releaseImages(Slot& slot) {
    for (StateImages& state : slot.states) {
        for (Image& image : state.planes) {
            detail::destroy(device(), image);
        }
        state = StateImages{};
    }
    detail::destroy(device(), slot.integer);
}

namespace {

// A 1 x 1 x 1 image cleared to zero, ready to be sampled.
Result<Image> createZeroImage(GpuContext& context, VkFormat format) {
    Result<Image> image = detail::createImage(
        context, VK_IMAGE_TYPE_3D, format, {1, 1, 1},
        VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
    if (!image) {
        return image.error();
    }
    const VkImage handle = image.value().image;
    Result<void> cleared = context.submitAndWait([handle](VkCommandBuffer cmd) {
        const VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
        detail::imageBarrier(cmd, handle, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                             VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_ACCESS_TRANSFER_WRITE_BIT);
        const VkClearColorValue zero{};
        vkCmdClearColorImage(cmd, handle, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &zero, 1, &range);
        detail::imageBarrier(
            cmd, handle, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
            VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT,
            VK_ACCESS_TRANSFER_WRITE_BIT, kAnyStage, VK_ACCESS_SHADER_READ_BIT);
    });
    if (!cleared) {
        detail::destroy(context.device(), image.value());
        return cleared.error();
    }
    return image;
}

// A write of `count` descriptors of `type` at `binding` of `set`; what they point at is set by
// the caller.
VkWriteDescriptorSet descriptorWrite(VkDescriptorSet set, uint32_t binding, uint32_t count,
                                     VkDescriptorType type) {
    VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    write.dstSet = set;
    write.dstBinding = binding;
    write.descriptorCount = count;
    write.descriptorType = type;
    return write;
}

} // namespace

Result<void> GpuVolumeSet::Impl::initDummy() {
    Result<Image> plane = createZeroImage(*context, VK_FORMAT_R16G16B16A16_SFLOAT);
    if (!plane) {
        return plane.error();
    }
    dummy = plane.value();
    Result<Image> indirection = createZeroImage(*context, VK_FORMAT_R32_UINT);
    if (!indirection) {
        return indirection.error();
    }
    dummyIndirection = indirection.value();
    return {};
}

Result<void> GpuVolumeSet::Impl::writeDescriptors() {
    std::vector<VkDescriptorImageInfo> images(2 * kPlaneElements);
    for (uint32_t state = 0; state < 2; ++state) {
        for (uint32_t s = 0; s < PK_MAX_VOLUMES; ++s) {
            for (uint32_t p = 0; p < PK_MAX_PLANES; ++p) {
                VkImageView view = dummy.view;
                if (s < slots.size() && slots[s].states[state].allocated &&
                    slots[s].states[state].planes[p].view != VK_NULL_HANDLE) {
                    view = slots[s].states[state].planes[p].view;
                }
                images[state * kPlaneElements + s * PK_MAX_PLANES + p] = {
                    VK_NULL_HANDLE, view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
            }
        }
    }
    std::array<VkDescriptorImageInfo, PK_MAX_VOLUMES> indirections{};
    for (uint32_t s = 0; s < PK_MAX_VOLUMES; ++s) {
        const bool used = s < slots.size() && slots[s].integer.view != VK_NULL_HANDLE;
        indirections[s] = {VK_NULL_HANDLE, used ? slots[s].integer.view : dummyIndirection.view,
                           VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    }
    const VkDescriptorBufferInfo buffer{uniforms.buffer, 0, sizeof(gpu::PkVolumeSetGpu)};
    const VkDescriptorImageInfo sampler_info{sampler, VK_NULL_HANDLE, VK_IMAGE_LAYOUT_UNDEFINED};
    std::array<VkWriteDescriptorSet, 5> writes = {
        descriptorWrite(set, PK_BINDING_VOLUMES, 1, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER),
        descriptorWrite(set, PK_BINDING_STATE_A, kPlaneElements, VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE),
        descriptorWrite(set, PK_BINDING_STATE_B, kPlaneElements, VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE),
        descriptorWrite(set, PK_BINDING_SAMPLER, 1, VK_DESCRIPTOR_TYPE_SAMPLER),
        descriptorWrite(set, PK_BINDING_INDIRECTION, PK_MAX_VOLUMES,
                        VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE)};
    writes[0].pBufferInfo = &buffer;
    writes[1].pImageInfo = images.data();
    writes[2].pImageInfo = images.data() + kPlaneElements;
    writes[3].pImageInfo = &sampler_info;
    writes[4].pImageInfo = indirections.data();
    vkUpdateDescriptorSets(device(), uint32_t(writes.size()), writes.data(), 0, nullptr);
    return {};
}

void GpuVolumeSet::Impl::recordUniforms(VkCommandBuffer cmd) {
    const gpu::PkVolumeSetGpu data = packUniforms();
    VkBufferMemoryBarrier barrier{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
    barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.buffer = uniforms.buffer;
    barrier.offset = 0;
    barrier.size = VK_WHOLE_SIZE;
    // Earlier reads finish before the write (write-after-read).
    barrier.srcAccessMask = VK_ACCESS_UNIFORM_READ_BIT;
    barrier.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    vkCmdPipelineBarrier(cmd, kAnyStage, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 1, &barrier,
                         0, nullptr);
    // The data is copied into the command buffer now: frames recorded later cannot change it.
    vkCmdUpdateBuffer(cmd, uniforms.buffer, 0, sizeof(data), &data);
    barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_UNIFORM_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, kAnyStage, 0, 0, nullptr, 1, &barrier,
                         0, nullptr);
    dirty = false;
}

Result<void> GpuVolumeSet::Impl::upload(size_t index, VolumeState which, const Volume& source,
                                        glm::uvec3 first, glm::uvec3 count) {
    Slot& slot = slots[index];
    StateImages& state = slot.states[size_t(which)];
    const bool whole = first == glm::uvec3(0u) && count == slot.desc.grid.resolution();
    assert(state.initialised || whole);

    const size_t texel_bytes = texelBoxBytes(source, count);
    // The primary state brings the box's visibility too (the slot's integer image).
    const bool visible = which == VolumeState::Primary && slot.visibility;
    assert(!visible || source.hasVisibility());
    const size_t visibility_bytes = visible ? visibilityBoxBytes(count) : 0;
    const size_t bytes = texel_bytes + visibility_bytes;
    PK_TRY(ensureStaging(bytes));
    // The previous upload waited for its copy, so the staging memory is free to overwrite.
    auto* out = static_cast<uint8_t*>(staging.mapped);
    packTexelBox(source, first, count, {out, texel_bytes});
    if (visible) {
        packVisibilityBox(source, first, count, {out + texel_bytes, visibility_bytes});
    }

    const size_t plane_bytes = texel_bytes / source.planes();
    // A whole replacement discards the old texels (UNDEFINED); a box keeps the rest of them.
    const VkImageLayout old_layout =
        whole ? VK_IMAGE_LAYOUT_UNDEFINED : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
    PK_TRY(context->submitAndWait([&](VkCommandBuffer cmd) {
        for (uint32_t p = 0; p < source.planes(); ++p) {
            const Image& image = state.planes[p];
            beginImageUpload(cmd, image.image, old_layout);
            VkBufferImageCopy region{};
            region.bufferOffset = p * plane_bytes;
            region.bufferRowLength = 0; // tightly packed box
            region.bufferImageHeight = 0;
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageOffset = {int32_t(first.x), int32_t(first.y), int32_t(first.z)};
            region.imageExtent = {count.x, count.y, count.z};
            finishImageUpload(cmd, staging.buffer, image.image, std::span(&region, 1));
        }
        if (visible) {
            beginImageUpload(cmd, slot.integer.image, old_layout);
            VkBufferImageCopy region{};
            region.bufferOffset = texel_bytes;
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageOffset = {int32_t(first.x), int32_t(first.y), int32_t(first.z)};
            region.imageExtent = {count.x, count.y, count.z};
            finishImageUpload(cmd, staging.buffer, slot.integer.image, std::span(&region, 1));
        }
        // A replaced primary state may bring a new box, frame, fade or priority.
        if (dirty) {
            recordUniforms(cmd);
        }
    }));
    state.initialised = true;
    uploaded += bytes;
    return {};
}

Result<void> GpuVolumeSet::Impl::ensureStaging(size_t bytes) {
    if (staging.size < bytes) {
        detail::destroy(device(), staging);
        Result<Buffer> buffer =
            detail::createBuffer(*context, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
        if (!buffer) {
            return buffer.error();
        }
        staging = buffer.value();
    }
    return {};
}

namespace {

// Where a bricked upload's parts sit in the staging buffer: the texels as stored, then (primary
// state) the indirection and, with visibility, the visibility atlas.
struct BrickedStaging {
    bool primary = false;
    bool visible = false;
    size_t texelBytes = 0;
    size_t entryBytes = 0; // per indirection entry: 4 (R32_UINT) or 8 (RG32_UINT, y = 0)
    size_t indirectionBytes = 0;
    size_t visibilityBytes = 0;

    size_t total() const { return texelBytes + indirectionBytes + visibilityBytes; }
};

// The staging layout of `source` for a state (primary: the indirection comes along; visible:
// the visibility too).
BrickedStaging brickedStaging(const Volume& source, bool primary, bool visible) {
    BrickedStaging s;
    s.primary = primary;
    s.visible = visible;
    // The stored planes are already brick after brick, each brick's 64 texels a 4 x 4 x 4 box
    // (x fastest): they are staged as they are, one copy region per brick.
    s.texelBytes = source.texelBytes();
    // The primary state brings the indirection and, with visibility, the visibility atlas,
    // both in the slot's integer image: entries of 4 bytes (R32_UINT) or 8 (RG32_UINT, y = 0).
    s.entryBytes = visible ? kVisibilityTexelBytes : sizeof(uint32_t);
    s.indirectionBytes = primary ? source.indirection.size() * s.entryBytes : 0;
    s.visibilityBytes = visible ? source.probeCount() * kVisibilityTexelBytes : 0;
    return s;
}

// Writes the parts of `layout` from `source` into the staging memory at `out`.
void packBrickedStaging(const Volume& source, const BrickedStaging& layout, uint8_t* out) {
    std::memcpy(out,
                source.desc.storage == Storage::Float32
                    ? static_cast<const void*>(source.texelsF32.data())
                    : static_cast<const void*>(source.texelsF16.data()),
                layout.texelBytes);
    if (layout.primary) {
        const std::vector<brick::Brick>& bricks = source.desc.bricks.bricks;
        const size_t stride = layout.entryBytes / sizeof(uint32_t);
        auto* entries = reinterpret_cast<uint32_t*>(out + layout.texelBytes);
        for (size_t c = 0; c < source.indirection.size(); ++c) {
            const uint32_t b = source.indirection[c];
            entries[c * stride] = PK_BRICK_ENTRY(b, uint32_t(bricks[b].level));
            if (stride == 2) {
                entries[c * stride + 1] = 0;
            }
        }
    }
    if (layout.visible) {
        // Probe by probe in stored order: each brick's 64 probes are a 4 x 4 x 4 box (x fastest).
        uint8_t* texel = out + layout.texelBytes + layout.indirectionBytes;
        for (size_t probe = 0; probe < source.probeCount(); ++probe) {
            std::memcpy(texel, &source.visibility[probe * visibility::kBytesPerProbe],
                        visibility::kBytesPerProbe);
            std::memset(texel + visibility::kBytesPerProbe, 0,
                        kVisibilityTexelBytes - visibility::kBytesPerProbe);
            texel += kVisibilityTexelBytes;
        }
    }
}

// Clears an image being uploaded (in TRANSFER_DST_OPTIMAL) to zero before its copies.
void clearForUpload(VkCommandBuffer cmd, VkImage image) {
    const VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    const VkClearColorValue zero{};
    vkCmdClearColorImage(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &zero, 1, &range);
    detail::imageBarrier(cmd, image, VK_IMAGE_ASPECT_COLOR_BIT,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
}

// The copy of brick b's 4 x 4 x 4 box from `buffer_offset` to its atlas slot, raised by `lift`.
VkBufferImageCopy brickRegion(uint32_t b, glm::uvec3 atlas_slots, VkDeviceSize buffer_offset,
                              glm::uvec3 lift) {
    const glm::uvec3 origin = brickAtlasSlot(b, atlas_slots) * PK_BRICK_SIZE + lift;
    VkBufferImageCopy region{};
    region.bufferOffset = buffer_offset;
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageOffset = {int32_t(origin.x), int32_t(origin.y), int32_t(origin.z)};
    region.imageExtent = {PK_BRICK_SIZE, PK_BRICK_SIZE, PK_BRICK_SIZE};
    return region;
}

// Records the copies of every plane's bricks from the staging buffer into the state's atlas.
void recordBrickPlanes(VkCommandBuffer cmd, VkBuffer staging, const Slot& slot,
                       const StateImages& state, const Volume& source) {
    const size_t brick_count = source.desc.bricks.bricks.size();
    const size_t texel_size = texelSize(source.desc.storage);
    std::vector<VkBufferImageCopy> regions(brick_count);
    for (uint32_t p = 0; p < source.planes(); ++p) {
        const Image& image = state.planes[p];
        // Unused slots are cleared: a filter tap of weight 0 next to a slot must not read
        // a NaN.
        beginImageUpload(cmd, image.image, VK_IMAGE_LAYOUT_UNDEFINED);
        clearForUpload(cmd, image.image);
        for (size_t b = 0; b < brick_count; ++b) {
            regions[b] =
                brickRegion(uint32_t(b), slot.atlasSlots,
                            (p * source.probeCount() + b * brick::kBrickProbeCount) * texel_size,
                            glm::uvec3(0u));
        }
        finishImageUpload(cmd, staging, image.image, regions);
    }
}

// Records the copies of the indirection (and the visibility atlas) into the slot's integer image.
void recordBrickIntegerImage(VkCommandBuffer cmd, VkBuffer staging, const Slot& slot,
                             const Volume& source, const BrickedStaging& layout) {
    const size_t brick_count = source.desc.bricks.bricks.size();
    const Image& image = slot.integer;
    const glm::uvec3 cells =
        brick::finestCells(source.desc.grid.resolution(), source.desc.bricks.maxLevel);
    beginImageUpload(cmd, image.image, VK_IMAGE_LAYOUT_UNDEFINED);
    if (layout.visible) {
        // Texels outside both regions are never read; cleared for determinism.
        clearForUpload(cmd, image.image);
    }
    std::vector<VkBufferImageCopy> integer_regions(1 + (layout.visible ? brick_count : 0));
    VkBufferImageCopy& indirection_region = integer_regions[0];
    indirection_region = {};
    indirection_region.bufferOffset = layout.texelBytes;
    indirection_region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    indirection_region.imageExtent = {cells.x, cells.y, cells.z};
    for (size_t b = 0; layout.visible && b < brick_count; ++b) {
        // The visibility atlas sits above the indirection: z offset C.z.
        integer_regions[1 + b] =
            brickRegion(uint32_t(b), slot.atlasSlots,
                        layout.texelBytes + layout.indirectionBytes +
                            b * brick::kBrickProbeCount * kVisibilityTexelBytes,
                        glm::uvec3(0u, 0u, cells.z));
    }
    finishImageUpload(cmd, staging, image.image, integer_regions);
}

} // namespace

Result<void> GpuVolumeSet::Impl::uploadBricked(size_t index, VolumeState which,
                                               const Volume& source) {
    Slot& slot = slots[index];
    StateImages& state = slot.states[size_t(which)];
    const bool primary = which == VolumeState::Primary;
    const bool visible = primary && slot.visibility;
    assert(!visible || source.hasVisibility());
    const BrickedStaging staged = brickedStaging(source, primary, visible);
    PK_TRY(ensureStaging(staged.total()));
    packBrickedStaging(source, staged, static_cast<uint8_t*>(staging.mapped));
    PK_TRY(context->submitAndWait([&](VkCommandBuffer cmd) {
        recordBrickPlanes(cmd, staging.buffer, slot, state, source);
        if (primary) {
            recordBrickIntegerImage(cmd, staging.buffer, slot, source, staged);
        }
        if (dirty) {
            recordUniforms(cmd);
        }
    }));
    state.initialised = true;
    uploaded += staged.total();
    return {};
}

Result<void> GpuVolumeSet::Impl::uploadWhole(size_t index, VolumeState which,
                                             const Volume& source) {
    if (isBricked(source.desc)) {
        return uploadBricked(index, which, source);
    }
    return upload(index, which, source, glm::uvec3(0u), source.desc.grid.resolution());
}

namespace {

// The update calls' index check (ARCHITECTURE.md, "Preconditions"): a slot index outside the
// set is an error naming the call, never a read past the slots.
Result<void> checkSlotIndex(const char* call, size_t index, size_t size) {
    if (index >= size) {
        return makeError(ErrorCode::OutOfRange, std::string("GpuVolumeSet::") + call +
                                                    ": volume index " + std::to_string(index) +
                                                    " is outside the set of " +
                                                    std::to_string(size) + " volumes");
    }
    return {};
}

} // namespace

GpuVolumeSet::GpuVolumeSet(std::unique_ptr<Impl> impl) : m_impl(std::move(impl)) {}
GpuVolumeSet::GpuVolumeSet(GpuVolumeSet&&) noexcept = default;
GpuVolumeSet& GpuVolumeSet::operator=(GpuVolumeSet&&) noexcept = default;
GpuVolumeSet::~GpuVolumeSet() = default;

Result<GpuVolumeSet> GpuVolumeSet::create(GpuContext& context, std::span<const Volume> volumes) {
    if (volumes.empty() || volumes.size() > kMaxGpuVolumes) {
        return makeError(ErrorCode::OutOfRange,
                         "a GPU volume set holds 1.." + std::to_string(kMaxGpuVolumes) +
                             " volumes, not " + std::to_string(volumes.size()));
    }
    for (size_t i = 0; i < volumes.size(); ++i) {
        if (Result<void> valid = validateVolume(volumes[i]); !valid) {
            return makeError(valid.error().code,
                             slotName(i, volumes[i].desc) + ": " + valid.error().message);
        }
    }
    auto impl = std::make_unique<Impl>();
    impl->context = &context;
    const VkDevice device = context.device();

    Result<VkDescriptorSetLayout> layout = createVolumeSetLayout(context);
    if (!layout) {
        return layout.error();
    }
    impl->layout = layout.value();
    const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
                                          {VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, 2 * kPlaneElements},
                                          {VK_DESCRIPTOR_TYPE_SAMPLER, 1}};
    VkDescriptorPoolCreateInfo pool{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool.maxSets = 1;
    pool.poolSizeCount = 3;
    pool.pPoolSizes = sizes;
    PK_VK_TRY(vkCreateDescriptorPool(device, &pool, nullptr, &impl->pool));
    VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocate.descriptorPool = impl->pool;
    allocate.descriptorSetCount = 1;
    allocate.pSetLayouts = &impl->layout;
    PK_VK_TRY(vkAllocateDescriptorSets(device, &allocate, &impl->set));

    // Linear filtering + clamp-to-edge + LOD 0 only: the CPU sampler's clamp and trilinear.
    PK_TRY(
        detail::createLinearSampler(device, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE, impl->sampler));

    Result<Buffer> uniforms = detail::createBuffer(
        context, sizeof(gpu::PkVolumeSetGpu),
        VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
    if (!uniforms) {
        return uniforms.error();
    }
    impl->uniforms = uniforms.value();
    PK_TRY(impl->initDummy());

    for (size_t i = 0; i < volumes.size(); ++i) {
        Slot slot;
        slot.desc = volumes[i].desc;
        slot.validity = volumes[i].validity;
        slot.visibility = volumes[i].hasVisibility();
        impl->slots.push_back(std::move(slot));
        if (Result<void> allocated = impl->allocateLayout(impl->slots.back()); !allocated) {
            return makeError(allocated.error().code,
                             slotName(i, volumes[i].desc) + ": " + allocated.error().message);
        }
    }
    PK_TRY(impl->writeDescriptors());
    for (size_t i = 0; i < volumes.size(); ++i) {
        PK_TRY(impl->uploadWhole(i, VolumeState::Primary, volumes[i]));
    }
    return GpuVolumeSet(std::move(impl));
}

size_t GpuVolumeSet::size() const {
    return m_impl->slots.size();
}

const VolumeDesc& GpuVolumeSet::desc(size_t index) const {
    PK_CHECK(index < size());
    return m_impl->slots[index].desc;
}

const std::vector<uint8_t>& GpuVolumeSet::validity(size_t index) const {
    PK_CHECK(index < size());
    return m_impl->slots[index].validity;
}

bool GpuVolumeSet::hasVisibility(size_t index) const {
    PK_CHECK(index < size());
    return m_impl->slots[index].visibility;
}

bool GpuVolumeSet::anyVisibility() const {
    return std::any_of(m_impl->slots.begin(), m_impl->slots.end(),
                       [](const Slot& slot) { return slot.visibility; });
}

bool GpuVolumeSet::hasSecondState(size_t index) const {
    PK_CHECK(index < size());
    return m_impl->slots[index].states[1].initialised;
}

float GpuVolumeSet::stateBlend(size_t index) const {
    PK_CHECK(index < size());
    return m_impl->slots[index].blend;
}

float GpuVolumeSet::normalOffset() const {
    return m_impl->normalOffset;
}

size_t GpuVolumeSet::texelBytes() const {
    size_t bytes = 0;
    for (const Slot& slot : m_impl->slots) {
        const VkExtent3D e = planeExtent(slot);
        const size_t one = size_t(planeCount(slot.desc.shOrder)) * e.width * e.height * e.depth *
                           texelSize(slot.desc.storage);
        bytes += slot.states[1].allocated ? 2 * one : one;
        const VkExtent3D e_int = slot.integer.extent;
        const size_t texel =
            slot.integer.format == kVisibilityFormat ? kVisibilityTexelBytes : sizeof(uint32_t);
        bytes += size_t(e_int.width) * e_int.height * e_int.depth * texel;
    }
    return bytes;
}

size_t GpuVolumeSet::uploadedBytes() const {
    return m_impl->uploaded;
}

VkDescriptorSetLayout GpuVolumeSet::descriptorSetLayout() const {
    return m_impl->layout;
}

VkDescriptorSet GpuVolumeSet::descriptorSet() const {
    return m_impl->set;
}

Result<void> GpuVolumeSet::replaceVolume(size_t index, const Volume& volume, VolumeState state) {
    PK_TRY(checkSlotIndex("replaceVolume", index, size()));
    Slot& slot = m_impl->slots[index];
    const std::string where = slotName(index, slot.desc);
    if (Result<void> valid = validateVolume(volume); !valid) {
        return makeError(valid.error().code, where + ": " + valid.error().message);
    }
    const std::string mismatch = layoutMismatch(slot.desc, volume.desc);
    // Bricked layouts may change on a primary replacement (new images); dense ones keep theirs.
    const bool relayout = !mismatch.empty() && state == VolumeState::Primary &&
                          (isBricked(slot.desc) || isBricked(volume.desc)) &&
                          formatMismatch(slot.desc, volume.desc).empty();
    if (!mismatch.empty() && !relayout) {
        return makeError(ErrorCode::InvalidArgument, where + ": replacement " + mismatch);
    }
    if (relayout && slot.states[1].allocated) {
        return makeError(ErrorCode::InvalidArgument,
                         where + ": replacement " + mismatch +
                             ", and a volume with a second state keeps its layout");
    }
    if (relayout) {
        // The set may be bound by work still in flight; replace the images once that is done.
        PK_TRY(m_impl->context->waitIdle());
        m_impl->releaseImages(slot);
        slot.desc = volume.desc;
        slot.validity = volume.validity;
        slot.visibility = volume.hasVisibility();
        m_impl->dirty = true;
        Result<void> allocated = m_impl->allocateLayout(slot);
        // Dead views must leave the set even when the allocation failed (dummies take over).
        PK_TRY(m_impl->writeDescriptors());
        if (!allocated) {
            return makeError(allocated.error().code, where + ": " + allocated.error().message);
        }
    } else if (state == VolumeState::Secondary) {
        const grid::Aabb& a = slot.desc.grid.bounds();
        const grid::Aabb& b = volume.desc.grid.bounds();
        if (a.min != b.min || a.max != b.max) {
            return makeError(ErrorCode::InvalidArgument,
                             where + ": a second state must have the volume's bounds");
        }
        StateImages& images = slot.states[1];
        if (!images.allocated) {
            PK_TRY(m_impl->allocateState(slot, images));
            // The set may be bound by work still in flight; rewrite it only once that is done.
            PK_TRY(m_impl->context->waitIdle());
            PK_TRY(m_impl->writeDescriptors());
            m_impl->dirty = true;
        }
    } else {
        slot.desc = volume.desc;
        slot.validity = volume.validity;
        m_impl->dirty = true;
        if (slot.visibility != volume.hasVisibility()) {
            // Visibility switched on or off: a new integer image (for a bricked volume it holds
            // the indirection too, in the other format), bound once work in flight is done.
            PK_TRY(m_impl->context->waitIdle());
            slot.visibility = volume.hasVisibility();
            Result<void> allocated = m_impl->allocateIntegerImage(slot);
            PK_TRY(m_impl->writeDescriptors());
            if (!allocated) {
                slot.visibility = false;
                return makeError(allocated.error().code, where + ": " + allocated.error().message);
            }
        }
    }
    return m_impl->uploadWhole(index, state, volume);
}

Result<void> GpuVolumeSet::updateBox(size_t index, const Volume& source, glm::uvec3 first,
                                     glm::uvec3 count, VolumeState state) {
    PK_TRY(checkSlotIndex("updateBox", index, size()));
    Slot& slot = m_impl->slots[index];
    const std::string where = slotName(index, slot.desc);
    if (Result<void> valid = validateVolume(source); !valid) {
        return makeError(valid.error().code, where + ": " + valid.error().message);
    }
    if (isBricked(slot.desc) || isBricked(source.desc)) {
        return makeError(ErrorCode::InvalidArgument,
                         where + ": updateBox takes dense volumes only (replace a bricked volume "
                                 "whole with replaceVolume)");
    }
    if (std::string mismatch = layoutMismatch(slot.desc, source.desc); !mismatch.empty()) {
        return makeError(ErrorCode::InvalidArgument, where + ": box source " + mismatch);
    }
    const glm::uvec3 res = slot.desc.grid.resolution();
    static constexpr const char* kAxes[3] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
        if (!axisInside(first[axis], count[axis], res[axis])) {
            return makeError(ErrorCode::OutOfRange,
                             where + ": box " + kAxes[axis] + " [" + std::to_string(first[axis]) +
                                 ", +" + std::to_string(count[axis]) +
                                 ") is empty or leaves the grid (resolution " +
                                 std::to_string(res[axis]) + ")");
        }
    }
    if (!slot.states[size_t(state)].initialised) {
        return makeError(ErrorCode::InvalidArgument,
                         where + ": no second state to update (upload one with replaceVolume)");
    }
    if (state == VolumeState::Primary && source.hasVisibility() != slot.visibility) {
        return makeError(ErrorCode::InvalidArgument,
                         where + (slot.visibility
                                      ? ": box source has no visibility data and the volume has"
                                      : ": box source has visibility data and the volume has "
                                        "none (replace the volume to switch it on)"));
    }
    if (state == VolumeState::Primary) {
        for (uint32_t z = first.z; z < first.z + count.z; ++z) {
            for (uint32_t y = first.y; y < first.y + count.y; ++y) {
                for (uint32_t x = first.x; x < first.x + count.x; ++x) {
                    const size_t probe = slot.desc.grid.linearIndex(glm::uvec3(x, y, z));
                    slot.validity[probe] = source.validity[probe];
                }
            }
        }
    }
    return m_impl->upload(index, state, source, first, count);
}

Result<void> GpuVolumeSet::setFrame(size_t index, const grid::RigidFrame& frame) {
    PK_TRY(checkSlotIndex("setFrame", index, size()));
    Slot& slot = m_impl->slots[index];
    const grid::GridLayout& layout = slot.desc.grid;
    Result<grid::GridLayout> moved =
        grid::GridLayout::make(layout.bounds(), layout.resolution(), layout.mode(), frame);
    if (!moved) {
        return makeError(moved.error().code,
                         slotName(index, slot.desc) + ": " + moved.error().message);
    }
    slot.desc.grid = moved.value();
    m_impl->dirty = true;
    return {};
}

Result<void> GpuVolumeSet::setStateBlend(size_t index, float blend) {
    PK_TRY(checkSlotIndex("setStateBlend", index, size()));
    const float clamped = std::isnan(blend) ? 0.0f : std::clamp(blend, 0.0f, 1.0f);
    if (clamped != 0.0f && !hasSecondState(index)) {
        return makeError(ErrorCode::InvalidArgument,
                         "GpuVolumeSet::setStateBlend: " + slotName(index, desc(index)) +
                             " has no second state to blend towards (upload one with "
                             "replaceVolume(..., VolumeState::Secondary))");
    }
    m_impl->slots[index].blend = clamped;
    m_impl->dirty = true;
    return {};
}

void GpuVolumeSet::setNormalOffset(float metres) {
    m_impl->normalOffset = metres;
    m_impl->dirty = true;
}

void GpuVolumeSet::recordUniformUpdate(VkCommandBuffer cmd) {
    if (m_impl->dirty) {
        m_impl->recordUniforms(cmd);
    }
}

} // namespace probekit::runtime
