#include "probekit/runtime/sampler.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

namespace probekit::runtime {

namespace {

// The probes along one axis that contribute to a sample, with their weights. An axis whose
// two neighbours coincide (one probe, or a coordinate clamped onto the last probe) reads one
// probe, so a sample never fetches the same texel twice.
struct AxisTaps {
    uint32_t index[2] = {0, 0};
    float weight[2] = {1.0f, 0.0f};
    int count = 1;
};

AxisTaps axisTaps(float grid_coord, uint32_t resolution) {
    const float last = float(resolution - 1);
    // Clamp addressing (step 2); a NaN coordinate falls to probe 0 rather than indexing
    // out of range.
    const float g = std::isnan(grid_coord) ? 0.0f : std::clamp(grid_coord, 0.0f, last);
    AxisTaps taps;
    const float lower = std::floor(g);
    taps.index[0] = uint32_t(lower);
    if (taps.index[0] + 1 < resolution) {
        const float t = g - lower;
        taps.index[1] = taps.index[0] + 1;
        taps.weight[0] = 1.0f - t;
        taps.weight[1] = t;
        taps.count = 2;
    }
    return taps;
}

// Distance from a local position to the nearest face of the box, positive inside, negative
// (or zero) outside along at least one axis.
float depthInside(const grid::Aabb& box, glm::vec3 local) {
    const glm::vec3 to_faces = glm::min(local - box.min, box.max - local);
    return std::min(to_faces.x, std::min(to_faces.y, to_faces.z));
}

// Step 3 (and B4): the taps' stored texels of every plane, weighted and summed, then unpacked.
// `probe_of(x, y, z)` gives the probe index of a tap's per-axis indices.
template <class ProbeOf>
sh::ShRgb interpolateTexels(const Volume& volume, const AxisTaps& tx, const AxisTaps& ty,
                            const AxisTaps& tz, ProbeOf probe_of) {
    const uint32_t planes = volume.planes();
    glm::vec4 accumulated[7] = {};
    for (int k = 0; k < tz.count; ++k) {
        for (int j = 0; j < ty.count; ++j) {
            const float wyz = ty.weight[j] * tz.weight[k];
            for (int i = 0; i < tx.count; ++i) {
                const float w = tx.weight[i] * wyz;
                const size_t probe = probe_of(tx.index[i], ty.index[j], tz.index[k]);
                // Volume::texel decodes half texels to float first, as a GPU's filtering does.
                for (uint32_t p = 0; p < planes; ++p) {
                    accumulated[p] += w * volume.texel(p, probe);
                }
            }
        }
    }
    return unpackProbe(accumulated, volume.desc.shOrder);
}

// Bricked steps B1-B4 of sampler.hpp; pk_brick_uvw (shaders/probe_volume.glsl) is the GPU twin,
// whose hardware trilinear filtering inside the brick's atlas slot is the loop below.
sh::ShRgb sampleBrickedSh(const Volume& volume, glm::vec3 world_position) {
    const grid::GridLayout& layout = volume.desc.grid;
    const brick::BrickLayout& bricks = volume.desc.bricks;
    const glm::uvec3 top = layout.resolution();
    const grid::Aabb& box = layout.bounds();
    const glm::vec3 local = layout.frame().toLocal(world_position);
    const glm::vec3 cell_coord =
        (local - box.min) / box.size() * glm::vec3(brick::finestCells(top, bricks.maxLevel));
    const brick::BrickSample at = brick::locate(top, bricks, volume.indirection, cell_coord);
    const size_t first_probe = size_t(at.brick) * brick::kBrickProbeCount;
    const AxisTaps tx = axisTaps(at.local.x, brick::kBrickSize);
    const AxisTaps ty = axisTaps(at.local.y, brick::kBrickSize);
    const AxisTaps tz = axisTaps(at.local.z, brick::kBrickSize);
    return interpolateTexels(volume, tx, ty, tz, [first_probe](uint32_t x, uint32_t y, uint32_t z) {
        return first_probe + x + brick::kBrickSize * (y + brick::kBrickSize * z);
    });
}

} // namespace

sh::ShRgb sampleVolumeSh(const Volume& volume, glm::vec3 world_position) {
    if (volume.desc.layout == VolumeLayout::Bricked) {
        return sampleBrickedSh(volume, world_position);
    }
    const grid::GridLayout& layout = volume.desc.grid;
    const glm::vec3 g = layout.worldToGrid(world_position);
    const glm::uvec3 res = layout.resolution();
    const AxisTaps tx = axisTaps(g.x, res.x);
    const AxisTaps ty = axisTaps(g.y, res.y);
    const AxisTaps tz = axisTaps(g.z, res.z);
    return interpolateTexels(volume, tx, ty, tz, [&layout](uint32_t x, uint32_t y, uint32_t z) {
        return layout.linearIndex(glm::uvec3(x, y, z));
    });
}

float volumeWeight(const Volume& volume, glm::vec3 world_position) {
    const grid::GridLayout& layout = volume.desc.grid;
    const float depth = depthInside(layout.bounds(), layout.frame().toLocal(world_position));
    if (!(depth >= 0.0f)) {
        return 0.0f;
    }
    const float fade = volume.desc.fadeDistance;
    if (fade <= 0.0f) {
        return 1.0f; // hard border: the closed box counts in full
    }
    return std::min(depth / fade, 1.0f);
}

float distanceToVolume(const Volume& volume, glm::vec3 world_position) {
    const grid::GridLayout& layout = volume.desc.grid;
    // The frame is rigid, so distances measured in the local frame are world distances.
    const glm::vec3 local = layout.frame().toLocal(world_position);
    const grid::Aabb& box = layout.bounds();
    const glm::vec3 outside = glm::max(glm::max(box.min - local, local - box.max), 0.0f);
    return glm::length(outside);
}

VolumeSet::VolumeSet(std::vector<Volume> volumes) : m_volumes(std::move(volumes)) {
    for ([[maybe_unused]] const Volume& v : m_volumes) {
        assert(validateVolume(v).ok());
    }
    m_byPriority.resize(m_volumes.size());
    std::iota(m_byPriority.begin(), m_byPriority.end(), size_t(0));
    // Stable, so equal priorities keep file order.
    std::stable_sort(m_byPriority.begin(), m_byPriority.end(), [this](size_t a, size_t b) {
        return m_volumes[a].desc.blendPriority > m_volumes[b].desc.blendPriority;
    });
}

Result<VolumeSet> VolumeSet::load(const std::filesystem::path& path) {
    Result<PvolFile> file = readPvol(path);
    if (!file) {
        return file.error();
    }
    return VolumeSet(std::move(file.value().volumes));
}

glm::vec3 VolumeSet::irradiance(glm::vec3 world_position, glm::vec3 normal) const {
    assert(!empty());
    glm::vec3 weighted_sum(0.0f);
    float weight_sum = 0.0f;
    float remaining = 1.0f;
    for (size_t index : m_byPriority) {
        const Volume& volume = m_volumes[index];
        const float w = volumeWeight(volume, world_position);
        if (w <= 0.0f) {
            continue;
        }
        const float a = w * remaining;
        weighted_sum +=
            a * sh::irradiance(sampleVolumeSh(volume, world_position), volume.desc.shOrder, normal);
        weight_sum += a;
        remaining -= a;
        // A volume at full weight hides everything of lower priority: skip sampling them.
        if (remaining <= 0.0f) {
            break;
        }
    }
    if (weight_sum > 0.0f) {
        // Normalising keeps the last volume's fade band from fading to black.
        return weighted_sum / weight_sum;
    }

    // Outside every volume: the nearest box, ties to the earlier entry of m_byPriority
    // (higher priority, then file order).
    const Volume* nearest = nullptr;
    float nearest_distance = std::numeric_limits<float>::infinity();
    for (size_t index : m_byPriority) {
        const float d = distanceToVolume(m_volumes[index], world_position);
        if (nearest == nullptr || d < nearest_distance) {
            nearest = &m_volumes[index];
            nearest_distance = d;
        }
    }
    return sh::irradiance(sampleVolumeSh(*nearest, world_position), nearest->desc.shOrder, normal);
}

glm::vec3 VolumeSet::irradiance(glm::vec3 world_position, glm::vec3 normal,
                                float normal_offset) const {
    return irradiance(world_position + normal_offset * normal, normal);
}

} // namespace probekit::runtime
