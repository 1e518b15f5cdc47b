// Shared support for the gpu tests: one Vulkan context for the whole executable, validation
// layers on (when installed) with every message collected, and the skip rule: a test skips only
// when this machine exposes no Vulkan device at all; any other failure to create the context
// fails the test.
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <gtest/gtest.h>

#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"
#include "probekit/runtime/gpu_context.hpp"

#include "dense_test_volume.hpp"

namespace probekit::gputest {

// Validation and driver messages since the last take (thread-safe).
class MessageLog {
public:
    void add(std::string message);
    std::vector<std::string> take();

private:
    std::mutex m_mutex;
    std::vector<std::string> m_messages;
};

MessageLog& messageLog();

// The shared context, created on first use; nullptr when there is no Vulkan device (then
// skipReason() says why) or creation failed (then creationError() says why).
runtime::GpuContext* sharedContext();
const std::string& skipReason();
const std::string& creationError();

// Base fixture: skips without a device, fails when the context cannot be created, and fails
// any test during which the validation layers or the driver reported a warning or an error.
class GpuTest : public ::testing::Test {
protected:
    void SetUp() override;
    void TearDown() override;
    runtime::GpuContext& context() { return *m_context; }

private:
    runtime::GpuContext* m_context = nullptr;
};

// Where a failing test writes its data (CSV, images) so the failure can be looked at.
std::string failureOutputPath(const std::string& file_name);

// ---- Test volumes ----

using ProbeFunction = std::function<sh::ShRgb(glm::vec3 world)>;

using VolumeSpec = densetest::BasicVolumeSpec<4>;

// A volume whose probe at world position x holds field(x) (truncated to L1 for L1 volumes);
// every `invalid_every`-th probe is marked invalid when > 0.
Volume makeTestVolume(const VolumeSpec& spec, const ProbeFunction& field, size_t invalid_every = 0);

// A smooth, realistic lighting field: a uniform sky of radiance `sky` plus a point light of
// intensity `intensity` (W/sr) at `light` (exact SH of a directional delta, as probekit synth).
ProbeFunction skyAndLight(glm::vec3 sky, glm::vec3 light, float intensity);

// Visibility bytes that hide some probes strongly: 15% of the probes get 0 on every half-axis
// (hidden from every point of their cells beyond 1/32 cell), the others per half-axis 255 (no
// surface within a cell) a quarter of the time, else a random distance. Deterministic in `seed`.
void addVisibility(Volume& volume, uint32_t seed);

} // namespace probekit::gputest
