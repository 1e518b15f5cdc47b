// Internal Vulkan helpers of probekit::runtime: VkResult -> Error, buffers and images with their
// own memory, shader modules, and the embedded SPIR-V. Not installed.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <vulkan/vulkan.h>

#include "probekit/formats/result.hpp"
#include "probekit/runtime/gpu_context.hpp"

namespace probekit::runtime::detail {

const char* toString(VkResult result);

// "vkCreateImage: VK_ERROR_OUT_OF_DEVICE_MEMORY".
Error vulkanError(const char* call, VkResult result);

// Evaluates a Vulkan call once and returns its error from the enclosing function (whose return
// type is a Result) when it is not VK_SUCCESS.
#define PK_VK_TRY(call)                                                                            \
    do {                                                                                           \
        const VkResult pk_vk_result = (call);                                                      \
        if (pk_vk_result != VK_SUCCESS) {                                                          \
            return ::probekit::runtime::detail::vulkanError(#call, pk_vk_result);                  \
        }                                                                                          \
    } while (false)

// Propagates the error of a Result-returning expression.
#define PK_TRY(expression)                                                                         \
    do {                                                                                           \
        if (auto pk_result = (expression); !pk_result) {                                           \
            return pk_result.error();                                                              \
        }                                                                                          \
    } while (false)

struct Buffer {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkDeviceSize size = 0;
    void* mapped = nullptr; // host-visible buffers stay mapped for their lifetime
};

// A buffer with its own allocation: host-visible and coherent (mapped) or device-local.
Result<Buffer> createBuffer(const GpuContext& context, VkDeviceSize size, VkBufferUsageFlags usage,
                            bool host_visible);
void destroy(VkDevice device, Buffer& buffer);

struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
    VkFormat format = VK_FORMAT_UNDEFINED;
    VkExtent3D extent{0, 0, 0};
};

// A device-local, optimally tiled, single-mip image (2D or 3D) with a view of the whole image.
Result<Image> createImage(const GpuContext& context, VkImageType type, VkFormat format,
                          VkExtent3D extent, VkImageUsageFlags usage, VkImageAspectFlags aspect);
void destroy(VkDevice device, Image& image);

Result<VkShaderModule> createShaderModule(VkDevice device, std::span<const uint32_t> code);

// A descriptor set layout of `bindings`, written to `layout`.
Result<void> createDescriptorSetLayout(VkDevice device,
                                       std::span<const VkDescriptorSetLayoutBinding> bindings,
                                       VkDescriptorSetLayout& layout);

// A sampler with linear filtering, LOD 0 only, and `address_mode` on every axis, written to
// `sampler`.
Result<void> createLinearSampler(VkDevice device, VkSamplerAddressMode address_mode,
                                 VkSampler& sampler);

// One image layout transition (or same-layout dependency) of a whole single-mip image.
void imageBarrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect,
                  VkImageLayout old_layout, VkImageLayout new_layout,
                  VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                  VkPipelineStageFlags dst_stage, VkAccessFlags dst_access);

// The shaders of shaders/, compiled by glslc at build time (runtime/CMakeLists.txt).
namespace spirv {
std::span<const uint32_t> gbufferVert();
std::span<const uint32_t> probeSphereVert();
std::span<const uint32_t> gbufferFrag();
std::span<const uint32_t> backgroundVert();
std::span<const uint32_t> backgroundFrag();
std::span<const uint32_t> shadeComp();
std::span<const uint32_t> shadeProbeViewsComp();
std::span<const uint32_t> shadeFetchOnlyComp();
std::span<const uint32_t> shadeGiComp(); // gi_shade.comp
std::span<const uint32_t> irradiancePointsComp();
std::span<const uint32_t> giGeometryComp();
std::span<const uint32_t> giSurfaceComp();
std::span<const uint32_t> giInjectComp();
std::span<const uint32_t> giPropagateComp();
std::span<const uint32_t> giKeepComp(); // gi_propagate.comp with PK_GI_KEEP
std::span<const uint32_t> giReduceComp();
std::span<const uint32_t> giResolveComp();
} // namespace spirv

} // namespace probekit::runtime::detail
