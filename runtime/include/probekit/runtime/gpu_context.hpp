// probekit::runtime::GpuContext — the Vulkan instance, device and queue every GPU object of the
// runtime is created on.
//
// Device choice: the first discrete GPU that qualifies, otherwise the first device that does
// (lavapipe, Mesa's CPU implementation, in CI). A device qualifies when it has a queue family
// with graphics and compute, linear filtering of RGBA16F and RGBA32F 3D images, and the storage
// and attachment formats of the renderer (see gpu_context.cpp).
//
// Threading: one context may be used from one thread at a time (Vulkan queues need external
// synchronisation). Failures of untrusted operations (no loader, no device, a Vulkan call that
// fails) come back as Result errors whose message names the Vulkan call and its VkResult.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <vulkan/vulkan.h>

#include "probekit/formats/result.hpp"

namespace probekit::runtime {

struct DeviceInfo {
    std::string name;
    VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
    uint32_t apiVersion = 0;
    bool suitable = false; // meets the requirements above
    std::string reason;    // why not, when !suitable
};

// The Vulkan devices this machine exposes, without creating any. An error when the Vulkan loader
// or instance is unavailable; an empty list when there is no device at all. Tests skip on
// either.
Result<std::vector<DeviceInfo>> enumerateDevices();

enum class MessageSeverity : uint8_t { Info, Warning, Error };

// Receives validation-layer and driver messages (the library never prints). Called from
// whatever thread made the Vulkan call that triggered it.
using MessageCallback = std::function<void(MessageSeverity, std::string_view message)>;

struct ContextOptions {
    // Enable VK_LAYER_KHRONOS_validation (with synchronisation validation) when it is installed;
    // GpuContext::validationEnabled() says whether it was. A layer enabled from outside
    // (VK_INSTANCE_LAYERS) reports through the same callback.
    bool validation = false;
    // Where messages go; none are collected without one.
    MessageCallback onMessage;
    // Only devices whose name contains this (empty: any); the discrete-first rule still applies.
    std::string deviceNameFilter;
};

class GpuContext {
public:
    // Creates instance, device and queue. Fails when no device qualifies (the message lists the
    // devices and why each was refused) or a Vulkan call fails.
    static Result<std::unique_ptr<GpuContext>> create(const ContextOptions& options = {});

    ~GpuContext();
    GpuContext(const GpuContext&) = delete;
    GpuContext& operator=(const GpuContext&) = delete;

    VkInstance instance() const { return m_instance; }
    VkPhysicalDevice physicalDevice() const { return m_physicalDevice; }
    VkDevice device() const { return m_device; }
    VkQueue queue() const { return m_queue; }
    uint32_t queueFamily() const { return m_queueFamily; }
    const DeviceInfo& deviceInfo() const { return m_deviceInfo; }
    const VkPhysicalDeviceLimits& limits() const { return m_limits; }
    bool validationEnabled() const { return m_validation; }
    // Nanoseconds per timestamp tick; 0 when the queue cannot write timestamps.
    double timestampPeriodNs() const { return m_timestampPeriodNs; }

    // A memory type index allowed by `type_bits` with all of `properties`.
    Result<uint32_t> findMemoryType(uint32_t type_bits, VkMemoryPropertyFlags properties) const;

    // Records commands into a one-time command buffer, submits it on the queue and waits for it
    // to complete. Work submitted earlier on the queue is ordered before it only as far as the
    // recorded barriers say.
    Result<void> submitAndWait(const std::function<void(VkCommandBuffer)>& record);

    // Blocks until the queue is idle (before descriptor sets that earlier submissions use are
    // rewritten).
    Result<void> waitIdle();

private:
    GpuContext() = default;
    static VKAPI_ATTR VkBool32 VKAPI_CALL debugCallback(
        VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT types,
        const VkDebugUtilsMessengerCallbackDataEXT* data, void* user);

    VkInstance m_instance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT m_messenger = VK_NULL_HANDLE;
    VkPhysicalDevice m_physicalDevice = VK_NULL_HANDLE;
    VkDevice m_device = VK_NULL_HANDLE;
    VkQueue m_queue = VK_NULL_HANDLE;
    uint32_t m_queueFamily = 0;
    VkCommandPool m_commandPool = VK_NULL_HANDLE;
    VkFence m_fence = VK_NULL_HANDLE;
    DeviceInfo m_deviceInfo;
    VkPhysicalDeviceLimits m_limits{};
    VkPhysicalDeviceMemoryProperties m_memory{};
    double m_timestampPeriodNs = 0.0;
    bool m_validation = false;
    MessageCallback m_onMessage;
};

} // namespace probekit::runtime
