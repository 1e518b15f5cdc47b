// Dense test volumes described field by field, for the CPU sampler tests (tests/unit) and the GPU
// tests (gpu_test_support): the spec of a volume and its probes filled from a field. Header-only
// and formats-only, so both test executables can use it.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::densetest {

// What a test volume is; each suite picks its default resolution.
template <uint32_t DefaultResolution>
struct BasicVolumeSpec {
    grid::Aabb bounds{glm::vec3(0.0f), glm::vec3(1.0f)};
    glm::uvec3 resolution{DefaultResolution};
    grid::PositionMode mode = grid::PositionMode::Center;
    grid::RigidFrame frame{};
    sh::Order order = sh::Order::L2;
    Storage storage = Storage::Float32;
    int32_t priority = 0;
    float fade = 0.0f;
    std::string name = "test";
};

template <uint32_t DefaultResolution>
VolumeDesc volumeDesc(const BasicVolumeSpec<DefaultResolution>& spec) {
    VolumeDesc desc;
    desc.name = spec.name;
    desc.grid = grid::GridLayout(spec.bounds, spec.resolution, spec.mode, spec.frame);
    desc.shOrder = spec.order;
    desc.storage = spec.storage;
    desc.blendPriority = spec.priority;
    desc.fadeDistance = spec.fade;
    return desc;
}

// Every probe of `desc`'s grid: probe_sh(its coordinates, its world position), truncated to L1
// for L1 volumes.
inline std::vector<sh::ShRgb>
fieldProbes(const VolumeDesc& desc,
            const std::function<sh::ShRgb(glm::uvec3 probe, glm::vec3 world)>& probe_sh) {
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        const glm::uvec3 c = desc.grid.probeCoords(i);
        probes[i] = probe_sh(c, desc.grid.probeWorld(c));
        if (desc.shOrder == sh::Order::L1) {
            probes[i] = sh::truncateToL1(probes[i]);
        }
    }
    return probes;
}

} // namespace probekit::densetest
