#include "probekit/runtime/gpu_context.hpp"

#include <algorithm>
#include <cstring>

#include "probe_volume_layout.h"
#include "vk_util.hpp"

namespace probekit::runtime {

using detail::vulkanError;

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr uint32_t kApiVersion = VK_API_VERSION_1_1;

// Every texel format the runtime uses, with the features it needs of optimally tiled images.
struct FormatNeed {
    VkFormat format;
    VkFormatFeatureFlags features;
    const char* what;
};
constexpr FormatNeed kFormatNeeds[] = {
    {VK_FORMAT_R16G16B16A16_SFLOAT,
     VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT |
         VK_FORMAT_FEATURE_TRANSFER_DST_BIT | VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT |
         VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT,
     "RGBA16F (linear-filtered volumes, G-buffer albedo)"},
    {VK_FORMAT_R32G32B32A32_SFLOAT,
     VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT |
         VK_FORMAT_FEATURE_TRANSFER_DST_BIT | VK_FORMAT_FEATURE_TRANSFER_SRC_BIT |
         VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT,
     "RGBA32F (linear-filtered volumes, G-buffer, output)"},
    {VK_FORMAT_R32_UINT,
     VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_TRANSFER_DST_BIT |
         VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT,
     "R32_UINT (brick indirection, G-buffer ids)"},
    {VK_FORMAT_R32G32_UINT,
     VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_TRANSFER_DST_BIT,
     "RG32_UINT (visibility)"},
    {VK_FORMAT_D32_SFLOAT, VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT, "D32 depth"},
};

// Sampled images one shader stage reads through a volume set (both states of every slot and
// the integer images: indirection and visibility).
constexpr uint32_t kSampledImagesPerSet = PK_SAMPLED_IMAGES;
// Resources (maxPerStageResources counts every descriptor but samplers) of the renderer's
// shading stage: the set's images and uniform buffer, its own uniform buffer and six storage
// images.
constexpr uint32_t kResourcesPerStage = kSampledImagesPerSet + 1 + 7;

bool hasLayer(const char* name) {
    uint32_t count = 0;
    vkEnumerateInstanceLayerProperties(&count, nullptr);
    std::vector<VkLayerProperties> layers(count);
    vkEnumerateInstanceLayerProperties(&count, layers.data());
    return std::any_of(layers.begin(), layers.end(), [name](const VkLayerProperties& l) {
        return std::strcmp(l.layerName, name) == 0;
    });
}

bool hasInstanceExtension(const char* layer, const char* name) {
    uint32_t count = 0;
    vkEnumerateInstanceExtensionProperties(layer, &count, nullptr);
    std::vector<VkExtensionProperties> extensions(count);
    vkEnumerateInstanceExtensionProperties(layer, &count, extensions.data());
    return std::any_of(
        extensions.begin(), extensions.end(),
        [name](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, name) == 0; });
}

// A graphics+compute queue family, or UINT32_MAX.
uint32_t findQueueFamily(VkPhysicalDevice device) {
    uint32_t count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
    std::vector<VkQueueFamilyProperties> families(count);
    vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
    for (uint32_t i = 0; i < count; ++i) {
        const VkQueueFlags needed = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
        if ((families[i].queueFlags & needed) == needed && families[i].queueCount > 0) {
            return i;
        }
    }
    return UINT32_MAX;
}

DeviceInfo describe(VkPhysicalDevice device) {
    VkPhysicalDeviceProperties properties;
    vkGetPhysicalDeviceProperties(device, &properties);
    DeviceInfo info;
    info.name = properties.deviceName;
    info.type = properties.deviceType;
    info.apiVersion = properties.apiVersion;
    info.suitable = false;
    if (properties.apiVersion < kApiVersion) {
        info.reason = "Vulkan 1.1 required";
        return info;
    }
    if (findQueueFamily(device) == UINT32_MAX) {
        info.reason = "no queue family with graphics and compute";
        return info;
    }
    for (const FormatNeed& need : kFormatNeeds) {
        VkFormatProperties format;
        vkGetPhysicalDeviceFormatProperties(device, need.format, &format);
        if ((format.optimalTilingFeatures & need.features) != need.features) {
            info.reason = std::string("format ") + need.what + " lacks a needed feature";
            return info;
        }
    }
    for (VkFormat format : {VK_FORMAT_R16G16B16A16_SFLOAT, VK_FORMAT_R32G32B32A32_SFLOAT,
                            VK_FORMAT_R32_UINT, VK_FORMAT_R32G32_UINT}) {
        VkImageFormatProperties image;
        if (vkGetPhysicalDeviceImageFormatProperties(
                device, format, VK_IMAGE_TYPE_3D, VK_IMAGE_TILING_OPTIMAL,
                VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, 0,
                &image) != VK_SUCCESS ||
            image.maxExtent.width < 256 || image.maxExtent.height < 256 ||
            image.maxExtent.depth < 256) {
            info.reason = "3D images of 256^3 texels unsupported";
            return info;
        }
    }
    const VkPhysicalDeviceLimits& limits = properties.limits;
    if (limits.maxPerStageDescriptorSampledImages < kSampledImagesPerSet ||
        limits.maxDescriptorSetSampledImages < kSampledImagesPerSet ||
        limits.maxPerStageResources < kResourcesPerStage) {
        info.reason = "fewer than " + std::to_string(kSampledImagesPerSet) +
                      " sampled images per shader stage";
        return info;
    }
    info.suitable = true;
    return info;
}

MessageSeverity toSeverity(VkDebugUtilsMessageSeverityFlagBitsEXT severity) {
    if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
        return MessageSeverity::Error;
    }
    if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
        return MessageSeverity::Warning;
    }
    return MessageSeverity::Info;
}

// The instance's layers and extensions: validation when asked for and installed, debug utils
// when someone listens, synchronisation validation with the layer.
struct InstanceSetup {
    std::vector<const char*> layers;
    std::vector<const char*> extensions;
    bool debugUtils = false;
    bool validationFeatures = false;
};

// What the instance enables for `options` (validation: the layer is enabled).
InstanceSetup instanceSetup(const ContextOptions& options, bool validation) {
    InstanceSetup setup;
    if (validation) {
        setup.layers.push_back(kValidationLayer);
    }
    // The messenger also hears a validation layer enabled from the environment.
    setup.debugUtils =
        options.onMessage &&
        (hasInstanceExtension(nullptr, VK_EXT_DEBUG_UTILS_EXTENSION_NAME) ||
         (validation && hasInstanceExtension(kValidationLayer, VK_EXT_DEBUG_UTILS_EXTENSION_NAME)));
    if (setup.debugUtils) {
        setup.extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    }
    // Synchronisation validation catches missing barriers, which core validation does not.
    setup.validationFeatures =
        validation &&
        hasInstanceExtension(kValidationLayer, VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
    if (setup.validationFeatures) {
        setup.extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
    }
    return setup;
}

// The debug messenger's settings: warnings and errors of every type, to `callback`.
VkDebugUtilsMessengerCreateInfoEXT messengerInfo(PFN_vkDebugUtilsMessengerCallbackEXT callback,
                                                 void* user) {
    VkDebugUtilsMessengerCreateInfoEXT messenger{
        VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    messenger.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    messenger.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                            VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                            VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    messenger.pfnUserCallback = callback;
    messenger.pUserData = user;
    return messenger;
}

// The Vulkan instance of `setup`, with the messenger (and the validation features) chained in.
Result<VkInstance> createInstance(const InstanceSetup& setup,
                                  const VkDebugUtilsMessengerCreateInfoEXT& messenger_info) {
    VkDebugUtilsMessengerCreateInfoEXT messenger = messenger_info;
    const VkValidationFeatureEnableEXT enables[] = {
        VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
    VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
    features.enabledValidationFeatureCount = 1;
    features.pEnabledValidationFeatures = enables;

    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "probekit";
    app.applicationVersion = VK_MAKE_VERSION(0, 1, 0);
    app.pEngineName = "probekit";
    app.apiVersion = kApiVersion;
    VkInstanceCreateInfo instance_info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    instance_info.pApplicationInfo = &app;
    instance_info.enabledLayerCount = uint32_t(setup.layers.size());
    instance_info.ppEnabledLayerNames = setup.layers.data();
    instance_info.enabledExtensionCount = uint32_t(setup.extensions.size());
    instance_info.ppEnabledExtensionNames = setup.extensions.data();
    // Chained into instance creation so messages from vkCreateInstance itself arrive too.
    const void* chain = nullptr;
    if (setup.debugUtils) {
        messenger.pNext = chain;
        chain = &messenger;
    }
    if (setup.validationFeatures) {
        features.pNext = chain;
        chain = &features;
    }
    instance_info.pNext = chain;
    VkInstance instance = VK_NULL_HANDLE;
    PK_VK_TRY(vkCreateInstance(&instance_info, nullptr, &instance));
    return instance;
}

// The debug messenger, or none where the instance lacks the function.
Result<VkDebugUtilsMessengerEXT> createMessenger(VkInstance instance,
                                                 const VkDebugUtilsMessengerCreateInfoEXT& info) {
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    auto create_messenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    if (create_messenger != nullptr) {
        PK_VK_TRY(create_messenger(instance, &info, nullptr, &messenger));
    }
    return messenger;
}

// The chosen physical device and its description.
struct ChosenDevice {
    VkPhysicalDevice device = VK_NULL_HANDLE;
    DeviceInfo info;
};

// The first suitable device whose name holds `name_filter`, discrete GPUs first; the error lists
// every device and why it was refused.
Result<ChosenDevice> chooseDevice(VkInstance instance, const std::string& name_filter) {
    uint32_t count = 0;
    PK_VK_TRY(vkEnumeratePhysicalDevices(instance, &count, nullptr));
    std::vector<VkPhysicalDevice> devices(count);
    PK_VK_TRY(vkEnumeratePhysicalDevices(instance, &count, devices.data()));
    std::string refused;
    int chosen = -1;
    ChosenDevice out;
    for (int pass = 0; pass < 2 && chosen < 0; ++pass) {
        for (uint32_t i = 0; i < count && chosen < 0; ++i) {
            const DeviceInfo info = describe(devices[i]);
            if (pass == 0) {
                refused += (refused.empty() ? "" : "; ") + info.name + ": " +
                           (info.suitable ? std::string("usable") : info.reason);
            }
            const bool name_ok =
                name_filter.empty() || info.name.find(name_filter) != std::string::npos;
            // First pass: discrete GPUs only; second pass: any qualifying device.
            const bool type_ok = pass == 1 || info.type == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
            if (info.suitable && name_ok && type_ok) {
                chosen = int(i);
                out.info = info;
            }
        }
    }
    if (chosen < 0) {
        return makeError(
            ErrorCode::InvalidArgument,
            "Vulkan: no usable device" +
                (name_filter.empty() ? std::string() : " matching \"" + name_filter + "\"") +
                (count == 0 ? std::string(" (none found)") : " (" + refused + ")"));
    }
    out.device = devices[size_t(chosen)];
    return out;
}

// Nanoseconds per timestamp tick of the queue family, 0 where it writes no timestamps.
double queueTimestampPeriodNs(VkPhysicalDevice device, uint32_t queue_family, float period) {
    uint32_t family_count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(device, &family_count, nullptr);
    std::vector<VkQueueFamilyProperties> families(family_count);
    vkGetPhysicalDeviceQueueFamilyProperties(device, &family_count, families.data());
    return families[queue_family].timestampValidBits > 0 ? double(period) : 0.0;
}

// The logical device with one queue of `queue_family` and no optional feature.
Result<VkDevice> createDevice(VkPhysicalDevice physical_device, uint32_t queue_family) {
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queue{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queue.queueFamilyIndex = queue_family;
    queue.queueCount = 1;
    queue.pQueuePriorities = &priority;
    VkPhysicalDeviceFeatures enabled{}; // the runtime needs no optional feature
    VkDeviceCreateInfo device_info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    device_info.queueCreateInfoCount = 1;
    device_info.pQueueCreateInfos = &queue;
    device_info.pEnabledFeatures = &enabled;
    VkDevice device = VK_NULL_HANDLE;
    PK_VK_TRY(vkCreateDevice(physical_device, &device_info, nullptr, &device));
    return device;
}

} // namespace

Result<std::vector<DeviceInfo>> enumerateDevices() {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "probekit";
    app.apiVersion = kApiVersion;
    VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    info.pApplicationInfo = &app;
    VkInstance instance = VK_NULL_HANDLE;
    PK_VK_TRY(vkCreateInstance(&info, nullptr, &instance));
    uint32_t count = 0;
    vkEnumeratePhysicalDevices(instance, &count, nullptr);
    std::vector<VkPhysicalDevice> devices(count);
    vkEnumeratePhysicalDevices(instance, &count, devices.data());
    std::vector<DeviceInfo> infos;
    for (VkPhysicalDevice device : devices) {
        infos.push_back(describe(device));
    }
    vkDestroyInstance(instance, nullptr);
    return infos;
}

VKAPI_ATTR VkBool32 VKAPI_CALL GpuContext::debugCallback(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
    const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    const auto* context = static_cast<const GpuContext*>(user);
    if (context->m_onMessage) {
        context->m_onMessage(toSeverity(severity), data->pMessage ? data->pMessage : "");
    }
    return VK_FALSE; // never abort the call that triggered the message
}

Result<std::unique_ptr<GpuContext>> GpuContext::create(const ContextOptions& options) {
    std::unique_ptr<GpuContext> context(new GpuContext());
    context->m_onMessage = options.onMessage;
    context->m_validation = options.validation && hasLayer(kValidationLayer);
    const InstanceSetup setup = instanceSetup(options, context->m_validation);
    const VkDebugUtilsMessengerCreateInfoEXT messenger =
        messengerInfo(&GpuContext::debugCallback, context.get());
    // Each handle goes into the context as soon as it exists, so a later failure destroys it.
    Result<VkInstance> instance = createInstance(setup, messenger);
    if (!instance) {
        return instance.error();
    }
    context->m_instance = instance.value();
    if (setup.debugUtils) {
        Result<VkDebugUtilsMessengerEXT> created = createMessenger(context->m_instance, messenger);
        if (!created) {
            return created.error();
        }
        context->m_messenger = created.value();
    }

    Result<ChosenDevice> chosen = chooseDevice(context->m_instance, options.deviceNameFilter);
    if (!chosen) {
        return chosen.error();
    }
    context->m_deviceInfo = chosen.value().info;
    context->m_physicalDevice = chosen.value().device;
    context->m_queueFamily = findQueueFamily(context->m_physicalDevice);
    VkPhysicalDeviceProperties properties;
    vkGetPhysicalDeviceProperties(context->m_physicalDevice, &properties);
    context->m_limits = properties.limits;
    vkGetPhysicalDeviceMemoryProperties(context->m_physicalDevice, &context->m_memory);
    context->m_timestampPeriodNs = queueTimestampPeriodNs(
        context->m_physicalDevice, context->m_queueFamily, properties.limits.timestampPeriod);

    Result<VkDevice> device = createDevice(context->m_physicalDevice, context->m_queueFamily);
    if (!device) {
        return device.error();
    }
    context->m_device = device.value();
    vkGetDeviceQueue(context->m_device, context->m_queueFamily, 0, &context->m_queue);
    VkCommandPoolCreateInfo pool{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pool.queueFamilyIndex = context->m_queueFamily;
    PK_VK_TRY(vkCreateCommandPool(context->m_device, &pool, nullptr, &context->m_commandPool));
    VkFenceCreateInfo fence{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    PK_VK_TRY(vkCreateFence(context->m_device, &fence, nullptr, &context->m_fence));
    return context;
}

GpuContext::~GpuContext() {
    if (m_device != VK_NULL_HANDLE) {
        vkDeviceWaitIdle(m_device);
        if (m_fence != VK_NULL_HANDLE) {
            vkDestroyFence(m_device, m_fence, nullptr);
        }
        if (m_commandPool != VK_NULL_HANDLE) {
            vkDestroyCommandPool(m_device, m_commandPool, nullptr);
        }
        vkDestroyDevice(m_device, nullptr);
    }
    if (m_messenger != VK_NULL_HANDLE) {
        auto destroy_messenger = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(m_instance, "vkDestroyDebugUtilsMessengerEXT"));
        if (destroy_messenger != nullptr) {
            destroy_messenger(m_instance, m_messenger, nullptr);
        }
    }
    if (m_instance != VK_NULL_HANDLE) {
        vkDestroyInstance(m_instance, nullptr);
    }
}

Result<uint32_t> GpuContext::findMemoryType(uint32_t type_bits,
                                            VkMemoryPropertyFlags properties) const {
    for (uint32_t i = 0; i < m_memory.memoryTypeCount; ++i) {
        if ((type_bits & (1u << i)) &&
            (m_memory.memoryTypes[i].propertyFlags & properties) == properties) {
            return i;
        }
    }
    return makeError(ErrorCode::InvalidArgument, "Vulkan: no memory type with the property flags " +
                                                     std::to_string(properties));
}

Result<void> GpuContext::submitAndWait(const std::function<void(VkCommandBuffer)>& record) {
    VkCommandBufferAllocateInfo allocate{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    allocate.commandPool = m_commandPool;
    allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    allocate.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    PK_VK_TRY(vkAllocateCommandBuffers(m_device, &allocate, &cmd));
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VkResult r = vkBeginCommandBuffer(cmd, &begin);
    if (r == VK_SUCCESS) {
        record(cmd);
        r = vkEndCommandBuffer(cmd);
    }
    if (r == VK_SUCCESS) {
        VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
        submit.commandBufferCount = 1;
        submit.pCommandBuffers = &cmd;
        r = vkQueueSubmit(m_queue, 1, &submit, m_fence);
        if (r == VK_SUCCESS) {
            r = vkWaitForFences(m_device, 1, &m_fence, VK_TRUE, UINT64_MAX);
            vkResetFences(m_device, 1, &m_fence);
        }
    }
    vkFreeCommandBuffers(m_device, m_commandPool, 1, &cmd);
    if (r != VK_SUCCESS) {
        return vulkanError("vkBeginCommandBuffer/vkQueueSubmit/vkWaitForFences", r);
    }
    return {};
}

Result<void> GpuContext::waitIdle() {
    PK_VK_TRY(vkQueueWaitIdle(m_queue));
    return {};
}

} // namespace probekit::runtime
