// The Vulkan context: device choice, and the validation plumbing every gpu test relies on (a
// test that passes with "zero validation messages" means something only if messages arrive).
#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include <vulkan/vulkan.h>

#include "gpu_test_support.hpp"

using namespace probekit;
using namespace probekit::gputest;

namespace {

bool validationLayerInstalled() {
    uint32_t count = 0;
    vkEnumerateInstanceLayerProperties(&count, nullptr);
    std::vector<VkLayerProperties> layers(count);
    vkEnumerateInstanceLayerProperties(&count, layers.data());
    return std::any_of(layers.begin(), layers.end(), [](const VkLayerProperties& l) {
        return std::strcmp(l.layerName, "VK_LAYER_KHRONOS_validation") == 0;
    });
}

class GpuContextTest : public GpuTest {};

TEST_F(GpuContextTest, PrefersADiscreteGpu) {
    Result<std::vector<runtime::DeviceInfo>> devices = runtime::enumerateDevices();
    ASSERT_TRUE(devices.ok());
    const bool discrete_available =
        std::any_of(devices.value().begin(), devices.value().end(), [](const auto& d) {
            return d.suitable && d.type == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
        });
    EXPECT_TRUE(context().deviceInfo().suitable);
    if (discrete_available) {
        EXPECT_EQ(context().deviceInfo().type, VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU);
    }
    RecordProperty("device", context().deviceInfo().name);
}

TEST_F(GpuContextTest, ValidationMessagesReachTheCallback) {
    if (!validationLayerInstalled()) {
        GTEST_SKIP() << "VK_LAYER_KHRONOS_validation is not installed (vulkan-validationlayers)";
    }
    ASSERT_TRUE(context().validationEnabled());
    // Invalid on purpose, and harmless to the driver: a buffer without usage flags.
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = 256;
    info.usage = 0;
    VkBuffer buffer = VK_NULL_HANDLE;
    if (vkCreateBuffer(context().device(), &info, nullptr, &buffer) == VK_SUCCESS) {
        vkDestroyBuffer(context().device(), buffer, nullptr);
    }
    const std::vector<std::string> messages = messageLog().take();
    ASSERT_FALSE(messages.empty()) << "the validation layer reported nothing";
    EXPECT_NE(messages.front().find("VkBufferCreateInfo"), std::string::npos) << messages.front();
}

} // namespace
