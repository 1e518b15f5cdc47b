#include "probekit/runtime/sampler.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

#include "probekit/formats/check.hpp"

namespace probekit::runtime {

namespace {

// The probes along one axis that contribute to a sample, with their weights. An axis whose
// two neighbours coincide (one probe, or a coordinate clamped onto the last probe) reads one
// probe, so a sample never fetches the same texel twice.
struct AxisTaps {
    uint32_t index[2] = {0, 0};
    float weight[2] = {1.0f, 0.0f};
    int count = 1;
    float coord = 0.0f; // the clamped coordinate (visibility offsets are coord - index)
};

AxisTaps axisTaps(float grid_coord, uint32_t resolution) {
    const float last = float(resolution - 1);
    // Clamp addressing (step 2); a NaN coordinate falls to probe 0 rather than indexing
    // out of range.
    const float g = std::isnan(grid_coord) ? 0.0f : std::clamp(grid_coord, 0.0f, last);
    AxisTaps taps;
    taps.coord = g;
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
// `probe_of(x, y, z)` gives the probe index of a tap's per-axis indices. With visibility data
// (step V) each tap's trilinear weight is scaled by vis + kFloor and the sum normalised.
template <class ProbeOf>
sh::ShRgb interpolateTexels(const Volume& volume, const AxisTaps& tx, const AxisTaps& ty,
                            const AxisTaps& tz, ProbeOf probe_of) {
    const uint32_t planes = volume.planes();
    const bool visible_weights = volume.hasVisibility();
    glm::vec4 accumulated[7] = {};
    float weight_sum = 0.0f;
    for (int k = 0; k < tz.count; ++k) {
        for (int j = 0; j < ty.count; ++j) {
            const float wyz = ty.weight[j] * tz.weight[k];
            for (int i = 0; i < tx.count; ++i) {
                float w = tx.weight[i] * wyz;
                const size_t probe = probe_of(tx.index[i], ty.index[j], tz.index[k]);
                if (visible_weights) {
                    const glm::vec3 offset(tx.coord - float(tx.index[i]),
                                           ty.coord - float(ty.index[j]),
                                           tz.coord - float(tz.index[k]));
                    w *= visibility::probeVisibility(
                             &volume.visibility[visibility::kBytesPerProbe * probe], offset) +
                         visibility::kFloor;
                    weight_sum += w;
                }
                // Volume::texel decodes half texels to float first, as a GPU's filtering does.
                for (uint32_t p = 0; p < planes; ++p) {
                    accumulated[p] += w * volume.texel(p, probe);
                }
            }
        }
    }
    if (visible_weights) {
        for (uint32_t p = 0; p < planes; ++p) {
            accumulated[p] /= weight_sum;
        }
    }
    return unpackProbe(accumulated, volume.desc.shOrder);
}

// The visible share of the trilinear weight, sum trilinear_i * vis_i (1 without visibility).
template <class ProbeOf>
float visibleShare(const Volume& volume, const AxisTaps& tx, const AxisTaps& ty, const AxisTaps& tz,
                   ProbeOf probe_of) {
    if (!volume.hasVisibility()) {
        return 1.0f;
    }
    float share = 0.0f;
    for (int k = 0; k < tz.count; ++k) {
        for (int j = 0; j < ty.count; ++j) {
            for (int i = 0; i < tx.count; ++i) {
                const size_t probe = probe_of(tx.index[i], ty.index[j], tz.index[k]);
                const glm::vec3 offset(tx.coord - float(tx.index[i]), ty.coord - float(ty.index[j]),
                                       tz.coord - float(tz.index[k]));
                share += tx.weight[i] * ty.weight[j] * tz.weight[k] *
                         visibility::probeVisibility(
                             &volume.visibility[visibility::kBytesPerProbe * probe], offset);
            }
        }
    }
    return share;
}

// The taps of one volume at a world position (steps 1-2 or B1-B2) handed to `fn(tx, ty, tz,
// probe_of)`.
template <class Fn>
auto withTaps(const Volume& volume, glm::vec3 world_position, Fn fn) {
    if (volume.desc.layout == VolumeLayout::Bricked) {
        const grid::GridLayout& layout = volume.desc.grid;
        const brick::BrickLayout& bricks = volume.desc.bricks;
        const glm::uvec3 top = layout.resolution();
        const grid::Aabb& box = layout.bounds();
        const glm::vec3 local = layout.frame().toLocal(world_position);
        const glm::vec3 cell_coord =
            (local - box.min) / box.size() * glm::vec3(brick::finestCells(top, bricks.maxLevel));
        const brick::BrickSample at = brick::locate(top, bricks, volume.indirection, cell_coord);
        const size_t first_probe = size_t(at.brick) * brick::kBrickProbeCount;
        return fn(axisTaps(at.local.x, brick::kBrickSize), axisTaps(at.local.y, brick::kBrickSize),
                  axisTaps(at.local.z, brick::kBrickSize),
                  [first_probe](uint32_t x, uint32_t y, uint32_t z) {
                      return first_probe + x + brick::kBrickSize * (y + brick::kBrickSize * z);
                  });
    }
    const grid::GridLayout& layout = volume.desc.grid;
    const glm::vec3 g = layout.worldToGrid(world_position);
    const glm::uvec3 res = layout.resolution();
    return fn(axisTaps(g.x, res.x), axisTaps(g.y, res.y), axisTaps(g.z, res.z),
              [&layout](uint32_t x, uint32_t y, uint32_t z) {
                  return layout.linearIndex(glm::uvec3(x, y, z));
              });
}

} // namespace

// Dense steps 1-4 and bricked B1-B4 (pk_volume_uvw / pk_brick_uvw and the fetches in
// shaders/probe_volume.glsl are the GPU twin; without visibility the hardware's trilinear
// filtering is the tap loop).
sh::ShRgb sampleVolumeSh(const Volume& volume, glm::vec3 world_position) {
    return withTaps(volume, world_position, [&volume](auto tx, auto ty, auto tz, auto probe_of) {
        return interpolateTexels(volume, tx, ty, tz, probe_of);
    });
}

float visibleWeight(const Volume& volume, glm::vec3 world_position) {
    return withTaps(volume, world_position, [&volume](auto tx, auto ty, auto tz, auto probe_of) {
        return visibleShare(volume, tx, ty, tz, probe_of);
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

VolumeSet::VolumeSet(std::vector<Volume> volumes) : VolumeSet(std::move(volumes), Validated{}) {
    // Always on (ARCHITECTURE.md, "Preconditions"): sampling indexes texels, visibility and
    // indirection with the sizes validateVolume checks.
    for (const Volume& v : m_volumes) {
        PK_CHECK_OK(validateVolume(v));
    }
}

VolumeSet::VolumeSet(std::vector<Volume> volumes, Validated) : m_volumes(std::move(volumes)) {
    m_byPriority.resize(m_volumes.size());
    std::iota(m_byPriority.begin(), m_byPriority.end(), size_t(0));
    // Stable, so equal priorities keep file order.
    std::stable_sort(m_byPriority.begin(), m_byPriority.end(), [this](size_t a, size_t b) {
        return m_volumes[a].desc.blendPriority > m_volumes[b].desc.blendPriority;
    });
}

Result<VolumeSet> VolumeSet::make(std::vector<Volume> volumes) {
    for (size_t i = 0; i < volumes.size(); ++i) {
        if (Result<void> valid = validateVolume(volumes[i]); !valid) {
            return makeError(valid.error().code,
                             "volumes[" + std::to_string(i) + "]: " + valid.error().message);
        }
    }
    return VolumeSet(std::move(volumes), Validated{});
}

Result<VolumeSet> VolumeSet::load(const std::filesystem::path& path) {
    Result<PvolFile> file = readPvol(path);
    if (!file) {
        return file.error();
    }
    // readPvol has validated every volume.
    return VolumeSet(std::move(file.value().volumes), Validated{});
}

glm::vec3 VolumeSet::irradiance(glm::vec3 world_position, glm::vec3 normal) const {
    // Always on: an empty set has no nearest volume to fall back to below. One branch per
    // sample (its cost is measured in ARCHITECTURE.md, "Preconditions").
    PK_CHECK(!empty());
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
