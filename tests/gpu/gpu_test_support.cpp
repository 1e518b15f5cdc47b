#include "gpu_test_support.hpp"

#include <cmath>
#include <filesystem>
#include <random>

#include <glm/geometric.hpp>

namespace probekit::gputest {

void MessageLog::add(std::string message) {
    std::lock_guard lock(m_mutex);
    m_messages.push_back(std::move(message));
}

std::vector<std::string> MessageLog::take() {
    std::lock_guard lock(m_mutex);
    return std::exchange(m_messages, {});
}

MessageLog& messageLog() {
    static MessageLog log;
    return log;
}

namespace {

struct Shared {
    std::unique_ptr<runtime::GpuContext> context;
    std::string skip;
    std::string error;
};

Shared& shared() {
    static Shared s = [] {
        Shared out;
        Result<std::vector<runtime::DeviceInfo>> devices = runtime::enumerateDevices();
        if (!devices) {
            out.skip = "no Vulkan device: the Vulkan loader or instance is unavailable (" +
                       devices.error().message + "); GPU tests skipped";
            return out;
        }
        if (devices.value().empty()) {
            out.skip = "no Vulkan device on this machine (install mesa-vulkan-drivers for "
                       "lavapipe); GPU tests skipped";
            return out;
        }
        runtime::ContextOptions options;
        options.validation = true;
        options.onMessage = [](runtime::MessageSeverity severity, std::string_view message) {
            if (severity != runtime::MessageSeverity::Info) {
                messageLog().add(std::string(message));
            }
        };
        Result<std::unique_ptr<runtime::GpuContext>> context = runtime::GpuContext::create(options);
        if (!context) {
            out.error = context.error().message;
            return out;
        }
        out.context = std::move(context).value();
        return out;
    }();
    return s;
}

} // namespace

runtime::GpuContext* sharedContext() {
    return shared().context.get();
}

const std::string& skipReason() {
    return shared().skip;
}

const std::string& creationError() {
    return shared().error;
}

void GpuTest::SetUp() {
    if (!skipReason().empty()) {
        GTEST_SKIP() << skipReason();
    }
    ASSERT_NE(sharedContext(), nullptr)
        << "Vulkan devices exist but the context failed: " << creationError();
    m_context = sharedContext();
    messageLog().take(); // messages of earlier tests were reported there
}

void GpuTest::TearDown() {
    if (m_context == nullptr) {
        return;
    }
    const std::vector<std::string> messages = messageLog().take();
    EXPECT_TRUE(messages.empty()) << messages.size()
                                  << " validation/driver message(s), first: " << messages.front();
}

std::string failureOutputPath(const std::string& file_name) {
    const std::filesystem::path dir(PROBEKIT_TEST_OUTPUT_DIR);
    std::filesystem::create_directories(dir);
    return (dir / file_name).string();
}

Volume makeTestVolume(const VolumeSpec& spec, const ProbeFunction& field, size_t invalid_every) {
    const VolumeDesc desc = densetest::volumeDesc(spec);
    const std::vector<sh::ShRgb> probes =
        densetest::fieldProbes(desc, [&](glm::uvec3, glm::vec3 world) { return field(world); });
    std::vector<uint8_t> validity(probes.size(), kProbeValid);
    for (size_t i = 0; invalid_every > 0 && i < probes.size(); i += invalid_every) {
        validity[i] = kProbeInvalid;
    }
    Result<Volume> volume = probekit::makeVolume(desc, probes, validity);
    EXPECT_TRUE(volume.ok()) << volume.error().message;
    return std::move(volume).value();
}

ProbeFunction skyAndLight(glm::vec3 sky, glm::vec3 light, float intensity) {
    return [=](glm::vec3 x) {
        const glm::vec3 to_light = light - x;
        const float d2 = glm::dot(to_light, to_light);
        sh::ShRgb s =
            sh::projectDelta(glm::normalize(to_light), glm::vec3(intensity / d2), sh::Order::L2);
        s.rgb[0] += sky * (2.0f * std::sqrt(sh::kPi));
        return s;
    };
}

void addVisibility(Volume& volume, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::uniform_int_distribution<int> byte(0, 255);
    volume.visibility.assign(volume.probeCount() * visibility::kBytesPerProbe, 0);
    for (size_t probe = 0; probe < volume.probeCount(); ++probe) {
        const bool hidden = unit(rng) < 0.15f;
        for (size_t h = 0; h < visibility::kBytesPerProbe; ++h) {
            volume.visibility[probe * visibility::kBytesPerProbe + h] =
                hidden ? 0 : (unit(rng) < 0.25f ? visibility::kClear : uint8_t(byte(rng)));
        }
    }
    ASSERT_TRUE(validateVolume(volume).ok());
}

} // namespace probekit::gputest
