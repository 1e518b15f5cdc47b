#include "vk_util.hpp"

namespace probekit::runtime::detail {

const char* toString(VkResult result) {
    switch (result) {
    case VK_SUCCESS:
        return "VK_SUCCESS";
    case VK_NOT_READY:
        return "VK_NOT_READY";
    case VK_TIMEOUT:
        return "VK_TIMEOUT";
    case VK_INCOMPLETE:
        return "VK_INCOMPLETE";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
        return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
        return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED:
        return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST:
        return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED:
        return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT:
        return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT:
        return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT:
        return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER:
        return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_TOO_MANY_OBJECTS:
        return "VK_ERROR_TOO_MANY_OBJECTS";
    case VK_ERROR_FORMAT_NOT_SUPPORTED:
        return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    case VK_ERROR_FRAGMENTED_POOL:
        return "VK_ERROR_FRAGMENTED_POOL";
    case VK_ERROR_OUT_OF_POOL_MEMORY:
        return "VK_ERROR_OUT_OF_POOL_MEMORY";
    default:
        return "VkResult (unnamed)";
    }
}

Error vulkanError(const char* call, VkResult result) {
    // Only the function name: the arguments make long, unhelpful messages.
    std::string name(call);
    if (const size_t paren = name.find('('); paren != std::string::npos) {
        name.resize(paren);
    }
    return makeError(ErrorCode::Io, "Vulkan: " + name + " failed: " + toString(result) + " (" +
                                        std::to_string(int(result)) + ")");
}

Result<Buffer> createBuffer(const GpuContext& context, VkDeviceSize size, VkBufferUsageFlags usage,
                            bool host_visible) {
    const VkDevice device = context.device();
    Buffer buffer;
    buffer.size = size;
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = size;
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    PK_VK_TRY(vkCreateBuffer(device, &info, nullptr, &buffer.buffer));

    VkMemoryRequirements requirements;
    vkGetBufferMemoryRequirements(device, buffer.buffer, &requirements);
    // Host-visible buffers are coherent, so writes need no flush and reads no invalidate.
    const VkMemoryPropertyFlags properties =
        host_visible ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                     : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
    Result<uint32_t> type = context.findMemoryType(requirements.memoryTypeBits, properties);
    if (!type) {
        destroy(device, buffer);
        return type.error();
    }
    VkMemoryAllocateInfo allocate{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    allocate.allocationSize = requirements.size;
    allocate.memoryTypeIndex = type.value();
    VkResult r = vkAllocateMemory(device, &allocate, nullptr, &buffer.memory);
    if (r == VK_SUCCESS) {
        r = vkBindBufferMemory(device, buffer.buffer, buffer.memory, 0);
    }
    if (r == VK_SUCCESS && host_visible) {
        r = vkMapMemory(device, buffer.memory, 0, VK_WHOLE_SIZE, 0, &buffer.mapped);
    }
    if (r != VK_SUCCESS) {
        destroy(device, buffer);
        return vulkanError("vkAllocateMemory/vkBindBufferMemory/vkMapMemory (buffer)", r);
    }
    return buffer;
}

void destroy(VkDevice device, Buffer& buffer) {
    if (buffer.buffer != VK_NULL_HANDLE) {
        vkDestroyBuffer(device, buffer.buffer, nullptr);
    }
    if (buffer.memory != VK_NULL_HANDLE) {
        // Freeing mapped memory unmaps it implicitly.
        vkFreeMemory(device, buffer.memory, nullptr);
    }
    buffer = Buffer{};
}

Result<Image> createImage(const GpuContext& context, VkImageType type, VkFormat format,
                          VkExtent3D extent, VkImageUsageFlags usage, VkImageAspectFlags aspect) {
    const VkDevice device = context.device();
    Image image;
    image.format = format;
    image.extent = extent;
    VkImageCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    info.imageType = type;
    info.format = format;
    info.extent = extent;
    info.mipLevels = 1;
    info.arrayLayers = 1;
    info.samples = VK_SAMPLE_COUNT_1_BIT;
    info.tiling = VK_IMAGE_TILING_OPTIMAL;
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    PK_VK_TRY(vkCreateImage(device, &info, nullptr, &image.image));

    VkMemoryRequirements requirements;
    vkGetImageMemoryRequirements(device, image.image, &requirements);
    Result<uint32_t> memory_type =
        context.findMemoryType(requirements.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    if (!memory_type) {
        destroy(device, image);
        return memory_type.error();
    }
    VkMemoryAllocateInfo allocate{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    allocate.allocationSize = requirements.size;
    allocate.memoryTypeIndex = memory_type.value();
    VkResult r = vkAllocateMemory(device, &allocate, nullptr, &image.memory);
    if (r == VK_SUCCESS) {
        r = vkBindImageMemory(device, image.image, image.memory, 0);
    }
    if (r == VK_SUCCESS) {
        VkImageViewCreateInfo view{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
        view.image = image.image;
        view.viewType = type == VK_IMAGE_TYPE_3D ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D;
        view.format = format;
        view.subresourceRange = {aspect, 0, 1, 0, 1};
        r = vkCreateImageView(device, &view, nullptr, &image.view);
    }
    if (r != VK_SUCCESS) {
        destroy(device, image);
        return vulkanError("vkAllocateMemory/vkBindImageMemory/vkCreateImageView", r);
    }
    return image;
}

void destroy(VkDevice device, Image& image) {
    if (image.view != VK_NULL_HANDLE) {
        vkDestroyImageView(device, image.view, nullptr);
    }
    if (image.image != VK_NULL_HANDLE) {
        vkDestroyImage(device, image.image, nullptr);
    }
    if (image.memory != VK_NULL_HANDLE) {
        vkFreeMemory(device, image.memory, nullptr);
    }
    image = Image{};
}

Result<VkShaderModule> createShaderModule(VkDevice device, std::span<const uint32_t> code) {
    VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    info.codeSize = code.size_bytes();
    info.pCode = code.data();
    VkShaderModule module = VK_NULL_HANDLE;
    PK_VK_TRY(vkCreateShaderModule(device, &info, nullptr, &module));
    return module;
}

Result<void> createDescriptorSetLayout(VkDevice device,
                                       std::span<const VkDescriptorSetLayoutBinding> bindings,
                                       VkDescriptorSetLayout& layout) {
    VkDescriptorSetLayoutCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    info.bindingCount = uint32_t(bindings.size());
    info.pBindings = bindings.data();
    PK_VK_TRY(vkCreateDescriptorSetLayout(device, &info, nullptr, &layout));
    return {};
}

Result<void> createLinearSampler(VkDevice device, VkSamplerAddressMode address_mode,
                                 VkSampler& sampler) {
    VkSamplerCreateInfo info{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    info.magFilter = info.minFilter = VK_FILTER_LINEAR;
    info.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
    info.addressModeU = info.addressModeV = info.addressModeW = address_mode;
    info.minLod = info.maxLod = 0.0f;
    PK_VK_TRY(vkCreateSampler(device, &info, nullptr, &sampler));
    return {};
}

void imageBarrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect,
                  VkImageLayout old_layout, VkImageLayout new_layout,
                  VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                  VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
    VkImageMemoryBarrier barrier{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    barrier.srcAccessMask = src_access;
    barrier.dstAccessMask = dst_access;
    barrier.oldLayout = old_layout;
    barrier.newLayout = new_layout;
    barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.image = image;
    barrier.subresourceRange = {aspect, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &barrier);
}

} // namespace probekit::runtime::detail
