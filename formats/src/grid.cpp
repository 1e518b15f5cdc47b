#include "probekit/formats/grid.hpp"

#include <cmath>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "probekit/formats/check.hpp"

namespace probekit::grid {

std::string_view toString(PositionMode mode) {
    switch (mode) {
    case PositionMode::Center:
        return "center";
    case PositionMode::Corner:
        return "corner";
    }
    return "unknown";
}

glm::mat4 RigidFrame::matrix() const {
    glm::mat4 m = glm::mat4_cast(rotation);
    m[3] = glm::vec4(translation, 1.0f);
    return m;
}

Result<void> validateResolution(glm::uvec3 resolution, PositionMode mode) {
    static constexpr const char* kAxes[3] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
        const uint32_t value = resolution[axis];
        const std::string field =
            std::string("resolution.") + kAxes[axis] + " = " + std::to_string(value);
        if (value < 1 || value > kMaxResolution) {
            return makeError(ErrorCode::BadResolution,
                             field + " is outside 1.." + std::to_string(kMaxResolution));
        }
        if (!isPowerOfTwo(value)) {
            return makeError(ErrorCode::BadResolution, field + " is not a power of two");
        }
        if (mode == PositionMode::Corner && value < 2) {
            return makeError(ErrorCode::BadResolution,
                             field + " is too small for corner placement (needs >= 2)");
        }
    }
    return {};
}

Result<void> validateBounds(const Aabb& bounds) {
    static constexpr const char* kAxes[3] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
        if (!std::isfinite(bounds.min[axis]) || !std::isfinite(bounds.max[axis])) {
            return makeError(ErrorCode::NonFinite, std::string("bounds.") + kAxes[axis] +
                                                       " is not finite (min " +
                                                       std::to_string(bounds.min[axis]) + ", max " +
                                                       std::to_string(bounds.max[axis]) + ")");
        }
        if (!(bounds.max[axis] > bounds.min[axis])) {
            return makeError(ErrorCode::OutOfRange,
                             std::string("bounds.") + kAxes[axis] + " is empty or inverted (min " +
                                 std::to_string(bounds.min[axis]) + " >= max " +
                                 std::to_string(bounds.max[axis]) + ")");
        }
        // Both ends finite but far apart (-3e38 to 3e38): the extent, and with it every cell
        // size and probe position computed from it, is infinite or NaN in float.
        if (!std::isfinite(bounds.max[axis] - bounds.min[axis])) {
            return makeError(ErrorCode::NonFinite,
                             std::string("bounds.") + kAxes[axis] + " extent max - min " +
                                 "overflows float (min " + std::to_string(bounds.min[axis]) +
                                 ", max " + std::to_string(bounds.max[axis]) + ")");
        }
    }
    return {};
}

GridLayout::GridLayout(Aabb bounds, glm::uvec3 resolution, PositionMode mode, RigidFrame frame)
    : GridLayout(bounds, resolution, mode, frame, Checked{}) {
    // Always on (ARCHITECTURE.md, "Preconditions"): a zero or oversized resolution makes
    // probeCount() and linearIndex() address memory the volume does not have.
    PK_CHECK_OK(validateResolution(resolution, mode));
    PK_CHECK_OK(validateBounds(bounds));
}

GridLayout::GridLayout(Aabb bounds, glm::uvec3 resolution, PositionMode mode, RigidFrame frame,
                       Checked)
    : m_bounds(bounds), m_resolution(resolution), m_mode(mode), m_frame(frame) {}

Result<GridLayout> GridLayout::make(Aabb bounds, glm::uvec3 resolution, PositionMode mode,
                                    RigidFrame frame) {
    if (auto r = validateResolution(resolution, mode); !r) {
        return r.error();
    }
    if (auto r = validateBounds(bounds); !r) {
        return r.error();
    }
    for (int i = 0; i < 4; ++i) {
        if (!std::isfinite(frame.rotation[i])) {
            return makeError(ErrorCode::NonFinite, "frame.rotation is not finite");
        }
    }
    if (std::abs(glm::length(frame.rotation) - 1.0f) > 1e-3f) {
        return makeError(ErrorCode::OutOfRange, "frame.rotation is not a unit quaternion");
    }
    for (int i = 0; i < 3; ++i) {
        if (!std::isfinite(frame.translation[i])) {
            return makeError(ErrorCode::NonFinite, "frame.translation is not finite");
        }
    }
    return GridLayout(bounds, resolution, mode, frame, Checked{});
}

glm::uvec3 GridLayout::probeCoords(size_t linear_index) const {
    const size_t x = linear_index % m_resolution.x;
    const size_t yz = linear_index / m_resolution.x;
    return glm::uvec3(uint32_t(x), uint32_t(yz % m_resolution.y), uint32_t(yz / m_resolution.y));
}

glm::vec3 GridLayout::spacing() const {
    const glm::vec3 size = m_bounds.size();
    const glm::vec3 res(m_resolution);
    if (m_mode == PositionMode::Center) {
        return size / res;
    }
    return size / (res - 1.0f);
}

Aabb GridLayout::worldBounds() const {
    Aabb out{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (int corner = 0; corner < 8; ++corner) {
        const glm::vec3 local((corner & 1) ? m_bounds.max.x : m_bounds.min.x,
                              (corner & 2) ? m_bounds.max.y : m_bounds.min.y,
                              (corner & 4) ? m_bounds.max.z : m_bounds.min.z);
        const glm::vec3 world = m_frame.toWorld(local);
        out.min = glm::min(out.min, world);
        out.max = glm::max(out.max, world);
    }
    return out;
}

glm::vec3 GridLayout::probeLocal(glm::uvec3 probe) const {
    return gridToLocal(glm::vec3(probe));
}

glm::vec3 GridLayout::localToGrid(glm::vec3 local) const {
    const glm::vec3 t = (local - m_bounds.min) / spacing();
    return m_mode == PositionMode::Center ? t - 0.5f : t;
}

glm::vec3 GridLayout::gridToLocal(glm::vec3 grid_coords) const {
    const glm::vec3 offset = m_mode == PositionMode::Center ? grid_coords + 0.5f : grid_coords;
    return m_bounds.min + offset * spacing();
}

} // namespace probekit::grid
