// The probe spheres of the probes and validity views: every probe of every volume, where it
// lands in the image, and the decimation that keeps the drawn spheres within probeBudget.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <string>

#include <glm/geometric.hpp>

#include "renderer_internal.hpp"

namespace probekit::runtime {

namespace {

// A probe the probes and validity views may draw: world position, radius before decimation,
// G-buffer id (render_layout.h), lattice coordinates (decimation keeps every stride-th).
struct ProbeCandidate {
    glm::vec3 world;
    float radius;
    uint32_t id;
    glm::uvec3 lattice;
    bool valid;
};

// Calls visit(candidate) for every probe of every volume: dense volumes' probes at their grid
// coordinates, bricked volumes' brick probe k at its finest-level lattice position (radius 0.15
// x the brick's own probe spacing); `fixed_radius` > 0 replaces the radius.
template <class Visit>
Result<void> forEachProbe(const GpuVolumeSet& volumes, float fixed_radius, const Visit& visit) {
    auto radiusOf = [&](glm::vec3 spacing) {
        return fixed_radius > 0.0f ? fixed_radius
                                   : 0.15f * std::min(spacing.x, std::min(spacing.y, spacing.z));
    };
    for (size_t s = 0; s < volumes.size(); ++s) {
        const VolumeDesc& desc = volumes.desc(s);
        const std::vector<uint8_t>& validity = volumes.validity(s);
        const uint32_t slot = uint32_t(s) << 3u;
        const grid::GridLayout& layout = desc.grid;
        if (desc.layout != VolumeLayout::Bricked) {
            const float radius = radiusOf(layout.spacing());
            for (size_t i = 0; i < layout.probeCount(); ++i) {
                const glm::uvec3 c = layout.probeCoords(i);
                const bool valid = validity[i] == kProbeValid;
                const uint32_t id = PK_KIND_PROBE | (uint32_t(valid) << 2u) | slot | (c.x << 8u) |
                                    (c.y << 16u) | (c.z << 24u);
                visit(ProbeCandidate{layout.probeWorld(c), radius, id, c, valid});
            }
            continue;
        }
        const brick::BrickLayout& bricks = desc.bricks;
        if (desc.probeCount() >= (size_t(1) << 24)) {
            return makeError(ErrorCode::OutOfRange,
                             "renderer: volume \"" + desc.name + "\" has " +
                                 std::to_string(desc.probeCount()) +
                                 " probes; the probe views show at most 2^24 per bricked volume");
        }
        const grid::Aabb& box = layout.bounds();
        const glm::uvec3 cells = brick::finestCells(layout.resolution(), bricks.maxLevel);
        // Lattice step (finest level): a finest cell holds 3 probe intervals.
        const glm::vec3 lattice_step = box.size() / (3.0f * glm::vec3(cells));
        for (size_t b = 0; b < bricks.bricks.size(); ++b) {
            const brick::Brick& br = bricks.bricks[b];
            const float radius = radiusOf(lattice_step * float(1u << (bricks.maxLevel - br.level)));
            for (uint32_t k = 0; k < brick::kBrickProbeCount; ++k) {
                const size_t probe = b * brick::kBrickProbeCount + k;
                const glm::uvec3 lattice = brick::latticeCoord(
                    br, glm::uvec3(k % 4, (k / 4) % 4, k / 16), bricks.maxLevel);
                const glm::vec3 at = box.min + glm::vec3(lattice) * lattice_step;
                const bool valid = validity[probe] == kProbeValid;
                const uint32_t id = PK_KIND_PROBE | (uint32_t(valid) << 2u) | slot |
                                    (uint32_t(br.level) << 6u) | (uint32_t(probe) << 8u);
                visit(ProbeCandidate{layout.frame().toWorld(at), radius, id, lattice, valid});
            }
        }
    }
    return {};
}

// Where a probe sphere lands in the image (probeBudget's visibility rule).
class ProbeProjector {
public:
    ProbeProjector(const FrameSettings& settings, const glm::mat4& view_projection)
        : m_viewProjection(view_projection), m_eye(settings.camera.eye),
          m_forward(glm::normalize(settings.camera.target - settings.camera.eye)),
          m_near(settings.camera.nearPlane), m_width(float(settings.width)),
          m_height(float(settings.height)),
          m_pixelsPerUnit(float(settings.height) * 0.5f /
                          std::tan(glm::radians(settings.camera.verticalFovDeg) * 0.5f)) {}

    // The sphere's distance along the view axis when it is in front of the near plane and
    // overlaps the image, else 0.
    float depthInView(glm::vec3 center, float radius) const {
        const float depth = glm::dot(center - m_eye, m_forward);
        if (!(depth > m_near)) {
            return 0.0f;
        }
        const glm::vec4 clip = m_viewProjection * glm::vec4(center, 1.0f);
        const float margin = radius * m_pixelsPerUnit / depth;
        const float x = (clip.x / clip.w * 0.5f + 0.5f) * m_width;
        const float y = (clip.y / clip.w * 0.5f + 0.5f) * m_height;
        const bool inside =
            x > -margin && x < m_width + margin && y > -margin && y < m_height + margin;
        return inside ? depth : 0.0f;
    }
    // World radius that is `pixels` on screen at `depth`.
    float worldRadius(float pixels, float depth) const { return pixels * depth / m_pixelsPerUnit; }

private:
    glm::mat4 m_viewProjection;
    glm::vec3 m_eye, m_forward;
    float m_near, m_width, m_height, m_pixelsPerUnit;
};

// How coarse a sub-grid a probe belongs to: the largest k with every lattice coordinate a
// multiple of 2^k (0 counts as a multiple of all); invalid probes in the validity view rank
// above every sub-grid, so they are the last to go.
constexpr uint32_t kProbeRanks = 32;
uint32_t probeRank(const ProbeCandidate& p, bool keep_invalid) {
    if (keep_invalid && !p.valid) {
        return kProbeRanks - 1;
    }
    auto zeros = [](uint32_t v) {
        return v == 0 ? kProbeRanks - 2 : uint32_t(std::countr_zero(v));
    };
    return std::min({zeros(p.lattice.x), zeros(p.lattice.y), zeros(p.lattice.z), kProbeRanks - 2});
}

} // namespace

Result<void> Renderer::Impl::writeInstances(const GpuVolumeSet& volumes,
                                            const FrameSettings& settings, uint32_t& count) {
    // probeBudget's rule, in two passes over the probes (5 M of them fit no list): count the
    // visible ones by rank, pick the smallest stride 2^k that fits the budget, then write those.
    const ProbeProjector projector(settings, viewProjection(settings));
    const bool keep_invalid = settings.view == RenderView::Validity;
    ProbeStats stats;
    stats.budget = probeBudget(settings.width, settings.height);
    std::array<uint64_t, kProbeRanks> by_rank{};
    PK_TRY(forEachProbe(volumes, settings.probeRadius, [&](const ProbeCandidate& p) {
        ++stats.total;
        if (projector.depthInView(p.world, p.radius) > 0.0f) {
            ++by_rank[probeRank(p, keep_invalid)];
        }
    }));
    uint32_t rank = kProbeRanks - 1;
    uint64_t kept = by_rank[rank];
    while (rank > 0 && kept + by_rank[rank - 1] <= stats.budget) {
        kept += by_rank[--rank];
    }
    for (uint64_t n : by_rank) {
        stats.inView += n;
    }
    // The sub-grid's spacing scales the spheres, up to the coarsest sub-grid the lattice has
    // (ranks above it hold only probes at coordinate 0, or the validity view's invalid ones).
    uint32_t coarsest = 0;
    for (uint32_t r = 0; r + 2 < kProbeRanks; ++r) {
        coarsest = by_rank[r] > 0 ? r : coarsest;
    }
    const uint32_t stride_log2 = std::min(rank, coarsest);
    stats.stride = 1u << stride_log2;
    std::vector<ProbeInstance> list;
    list.reserve(std::min<uint64_t>(kept, stats.budget));
    PK_TRY(forEachProbe(volumes, settings.probeRadius, [&](const ProbeCandidate& p) {
        if (list.size() >= stats.budget || probeRank(p, keep_invalid) < rank) {
            return;
        }
        const float distance = projector.depthInView(p.world, p.radius);
        if (distance > 0.0f) {
            const float radius = std::max(p.radius * float(stats.stride),
                                          projector.worldRadius(kMinProbeRadiusPixels, distance));
            list.push_back({glm::vec4(p.world, radius), p.id});
        }
    }));
    stats.drawn = list.size();
    probeStats = stats;
    const VkDeviceSize bytes = list.size() * sizeof(ProbeInstance);
    if (instances.size < bytes) {
        // Earlier frames are complete (render waits for each), so the old buffer is free.
        detail::destroy(device(), instances);
        Result<Buffer> buffer =
            detail::createBuffer(*context, bytes, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
        if (!buffer) {
            return buffer.error();
        }
        instances = buffer.value();
    }
    if (bytes > 0) {
        std::memcpy(instances.mapped, list.data(), bytes);
    }
    count = uint32_t(list.size());
    return {};
}

} // namespace probekit::runtime
