#include "volume/visibility.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "probekit/formats/brick.hpp"
#include "probekit/formats/sh.hpp"
#include "trace/parallel.hpp"

namespace probekit::baker {

namespace {

// The bundle of one half-axis in local coordinates, unit directions; [0] is the axis itself.
// Cone rays sit at azimuths 22.5 + 45 k degrees, so none lies in a plane of two axes: a probe
// on a floor sees half of the cone go down and the median stays with the upper half.
std::array<glm::vec3, kBundleRays> bundle(int axis, float sign) {
    const glm::vec3 e = glm::vec3(axis == 0, axis == 1, axis == 2) * sign;
    const glm::vec3 u = glm::vec3(axis == 1, axis == 2, axis == 0); // the next axis
    const glm::vec3 w = glm::vec3(axis == 2, axis == 0, axis == 1); // the one after
    constexpr float kPi = 3.14159265358979323846f;
    const float tilt = kBundleAngleDeg * kPi / 180.0f;
    std::array<glm::vec3, kBundleRays> dirs;
    dirs[0] = e;
    for (int k = 0; k < kBundleRays - 1; ++k) {
        const float phi = (22.5f + 45.0f * float(k)) * kPi / 180.0f;
        dirs[k + 1] = std::cos(tilt) * e + std::sin(tilt) * (std::cos(phi) * u + std::sin(phi) * w);
    }
    return dirs;
}

} // namespace

std::array<uint8_t, visibility::kBytesPerProbe>
traceProbeVisibility(const RayTracer& tracer, glm::vec3 world_position, glm::vec3 spacing,
                     const grid::RigidFrame& frame) {
    std::array<uint8_t, visibility::kBytesPerProbe> out{};
    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            const std::array<glm::vec3, kBundleRays> dirs = bundle(axis, side == 0 ? 1.0f : -1.0f);
            const float cell = spacing[axis];
            const float start = kVisibilityStartCells * cell;
            std::array<float, kBundleRays> cells;
            for (int k = 0; k < kBundleRays; ++k) {
                const glm::vec3 dir = frame.directionToWorld(dirs[k]);
                const float cos_axis = std::abs(dirs[k][axis]);
                // Far enough that a hit projecting to one cell or more is found.
                const float t_max = cell / cos_axis;
                const std::optional<Hit> hit =
                    tracer.intersect(world_position + start * dir, dir, t_max);
                cells[k] = hit ? (start + hit->t) * cos_axis / cell : 1.0f;
            }
            std::nth_element(cells.begin(), cells.begin() + kBundleRays / 2, cells.end());
            out[2 * axis + side] = visibility::encodeDistance(cells[kBundleRays / 2]);
        }
    }
    return out;
}

std::vector<uint8_t> traceVolumeVisibility(const RayTracer& tracer, const VolumeDesc& desc,
                                           std::span<const uint8_t> validity, uint32_t threads,
                                           std::span<const glm::vec3> moves) {
    const size_t count = desc.probeCount();
    const grid::GridLayout& grid = desc.grid;
    // Lattice position and cell size of probe i.
    auto probe_at = [&](size_t i, glm::vec3& local, glm::vec3& spacing) {
        if (desc.layout == VolumeLayout::Dense) {
            local = grid.probeLocal(grid.probeCoords(i));
            spacing = grid.spacing();
            return;
        }
        const brick::Brick& b = desc.bricks.bricks[i / brick::kBrickProbeCount];
        const uint32_t k = uint32_t(i % brick::kBrickProbeCount);
        const glm::uvec3 in_brick(k % 4, (k / 4) % 4, k / 16);
        const glm::uvec3 lattice = brick::latticeCoord(b, in_brick, desc.bricks.maxLevel);
        const glm::vec3 lattice_points =
            glm::vec3(brick::finestCells(grid.resolution(), desc.bricks.maxLevel)) *
            float(brick::kBrickCells);
        const grid::Aabb& box = grid.bounds();
        local = box.min + glm::vec3(lattice) / lattice_points * box.size();
        spacing = box.size() / glm::vec3(grid.resolution()) / float(1u << b.level) /
                  float(brick::kBrickCells);
    };

    std::vector<uint8_t> out(count * visibility::kBytesPerProbe, 0);
    parallelFor(count, threads, 16, [&](size_t begin, size_t end) {
        const ScopedFloatMode float_mode;
        for (size_t i = begin; i < end; ++i) {
            if (!validity.empty() && validity[i] == kProbeInvalid) {
                continue; // zeros: hidden everywhere but at the probe itself
            }
            glm::vec3 local, spacing;
            probe_at(i, local, spacing);
            auto bytes =
                traceProbeVisibility(tracer, grid.frame().toWorld(local), spacing, grid.frame());
            if (!moves.empty() && moves[i] != glm::vec3(0.0f)) {
                const glm::vec3 move = grid.frame().directionToLocal(moves[i]);
                for (int axis = 0; axis < 3; ++axis) {
                    if (move[axis] < 0.0f) {
                        bytes[2 * axis] = 0; // +axis points away from the move
                    } else if (move[axis] > 0.0f) {
                        bytes[2 * axis + 1] = 0;
                    }
                }
            }
            std::copy(bytes.begin(), bytes.end(),
                      out.begin() + std::ptrdiff_t(i * visibility::kBytesPerProbe));
        }
    });
    return out;
}

std::optional<glm::vec3> relocationTarget(const RayTracer& tracer, glm::vec3 p, float max_distance,
                                          float margin_scale, float backface_threshold) {
    struct Exit {
        float t;
        int direction;
    };
    std::array<Exit, kRelocationDirections> exits;
    int found = 0;
    for (int k = 0; k < kRelocationDirections; ++k) {
        const glm::vec3 dir = sh::fibonacciDirection(k, kRelocationDirections);
        const std::optional<Hit> hit = tracer.intersect(p, dir, max_distance);
        if (hit && hit->backFace) {
            exits[size_t(found++)] = Exit{hit->t, k};
        }
    }
    std::sort(exits.begin(), exits.begin() + found, [](const Exit& a, const Exit& b) {
        return a.t < b.t || (a.t == b.t && a.direction < b.direction);
    });
    for (int c = 0; c < std::min(found, kRelocationCandidates); ++c) {
        const glm::vec3 dir =
            sh::fibonacciDirection(exits[size_t(c)].direction, kRelocationDirections);
        const glm::vec3 q = p + dir * (exits[size_t(c)].t + kRelocationMargin * margin_scale);
        int back_faces = 0;
        for (int k = 0; k < kRelocationTestRays; ++k) {
            const std::optional<Hit> hit =
                tracer.intersect(q, sh::fibonacciDirection(k, kRelocationTestRays));
            back_faces += hit && hit->backFace ? 1 : 0;
        }
        if (float(back_faces) <= backface_threshold * float(kRelocationTestRays)) {
            return q;
        }
    }
    return std::nullopt;
}

} // namespace probekit::baker
