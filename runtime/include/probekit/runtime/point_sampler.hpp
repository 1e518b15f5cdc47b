// probekit::runtime::GpuPointSampler — pk_irradiance evaluated on the GPU at arbitrary points
// (a compute shader, shaders/irradiance_points.comp), read back to the caller. It is how the
// gpu tests compare the GPU path with the CPU reference VolumeSet::irradiance, and a batch query
// for tools.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/result.hpp"
#include "probekit/runtime/gpu_context.hpp"
#include "probekit/runtime/gpu_volumes.hpp"

namespace probekit::runtime {

class GpuPointSampler {
public:
    // Builds the compute pipeline. The context must outlive the sampler.
    static Result<GpuPointSampler> create(GpuContext& context);

    GpuPointSampler(GpuPointSampler&&) noexcept;
    GpuPointSampler& operator=(GpuPointSampler&&) noexcept;
    ~GpuPointSampler();

    // Irradiance E (W/m^2, not divided by pi) at each world position (m) for the unit world
    // normal of the same index: the GPU twin of
    // VolumeSet::irradiance(position, normal, volumes.normalOffset()). Records the set's
    // pending uniform update, dispatches, waits and reads back. Fails with InvalidArgument
    // when positions and normals differ in count.
    Result<std::vector<glm::vec3>> irradiance(GpuVolumeSet& volumes,
                                              std::span<const glm::vec3> positions,
                                              std::span<const glm::vec3> normals);

private:
    struct Impl;
    explicit GpuPointSampler(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> m_impl;
};

} // namespace probekit::runtime
