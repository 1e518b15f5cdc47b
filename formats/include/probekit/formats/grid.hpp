// probekit::grid — where the probes of a volume are.
//
// A volume is an axis-aligned box in its own local frame, optionally placed in the world by a
// rigid transform (for volumes bound to a glTF node). Units are metres, glTF frame (+Y up).
//
// Probes form a resolution.x * resolution.y * resolution.z lattice; each axis is a power of two
// from 1 to 256. Two position modes:
//   center: probe i at  min + (i + 0.5) * size / res     (res >= 1; res 1 is the box centre)
//   corner: probe i at  min + i * size / (res - 1)       (res >= 2; probes on the faces)
// Probe (x, y, z) has linear index x + res.x * (y + res.y * z): x varies fastest.
//
// "Grid coordinates" are continuous: probe i sits at grid coordinate i on each axis, so
// trilinear interpolation between probes floor(g) and floor(g) + 1 uses weight fract(g).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "probekit/formats/result.hpp"

namespace probekit::grid {

constexpr uint32_t kMaxResolution = 256;

enum class PositionMode : uint8_t {
    Center = 0,
    Corner = 1,
};

std::string_view toString(PositionMode mode);

struct Aabb {
    glm::vec3 min{0.0f};
    glm::vec3 max{0.0f};

    glm::vec3 size() const { return max - min; }
    glm::vec3 center() const { return 0.5f * (min + max); }
};

// Local -> world rigid transform: world = rotation * local + translation. The identity by
// default. rotation must be a unit quaternion.
struct RigidFrame {
    glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f}; // (w, x, y, z)
    glm::vec3 translation{0.0f};

    glm::vec3 toWorld(glm::vec3 local) const { return rotation * local + translation; }
    glm::vec3 toLocal(glm::vec3 world) const {
        return glm::conjugate(rotation) * (world - translation);
    }
    glm::vec3 directionToWorld(glm::vec3 local) const { return rotation * local; }
    glm::vec3 directionToLocal(glm::vec3 world) const { return glm::conjugate(rotation) * world; }
    glm::mat4 matrix() const;
};

// Checks one resolution: power of two in 1..256, and >= 2 for corner mode. The error message
// names the axis and the value, e.g. "resolution.y = 12 is not a power of two".
Result<void> validateResolution(glm::uvec3 resolution, PositionMode mode);

// Checks bounds: finite, and max > min on every axis.
Result<void> validateBounds(const Aabb& bounds);

class GridLayout {
public:
    GridLayout() = default;
    // Preconditions (checked in every build type; a failure prints the validation message and
    // aborts, ARCHITECTURE.md "Preconditions"): validateResolution and validateBounds pass. Use
    // make() for untrusted values.
    GridLayout(Aabb bounds, glm::uvec3 resolution, PositionMode mode, RigidFrame frame = {});

    // Validating constructor for untrusted input.
    static Result<GridLayout> make(Aabb bounds, glm::uvec3 resolution, PositionMode mode,
                                   RigidFrame frame = {});

    const Aabb& bounds() const { return m_bounds; }
    glm::uvec3 resolution() const { return m_resolution; }
    PositionMode mode() const { return m_mode; }
    const RigidFrame& frame() const { return m_frame; }
    void setFrame(const RigidFrame& frame) { m_frame = frame; }

    size_t probeCount() const { return size_t(m_resolution.x) * m_resolution.y * m_resolution.z; }
    size_t linearIndex(glm::uvec3 probe) const {
        return probe.x + size_t(m_resolution.x) * (probe.y + size_t(m_resolution.y) * probe.z);
    }
    glm::uvec3 probeCoords(size_t linear_index) const;

    // Distance between neighbouring probes per axis, in metres (the box size on an axis with
    // one centre-mode probe).
    glm::vec3 spacing() const;

    // World-space axis-aligned box around the (possibly rotated) volume box.
    Aabb worldBounds() const;

    glm::vec3 probeLocal(glm::uvec3 probe) const;
    glm::vec3 probeWorld(glm::uvec3 probe) const { return m_frame.toWorld(probeLocal(probe)); }

    // Continuous grid coordinates (probe i at i) of a local / world position, unclamped.
    glm::vec3 localToGrid(glm::vec3 local) const;
    glm::vec3 gridToLocal(glm::vec3 grid) const;
    glm::vec3 worldToGrid(glm::vec3 world) const { return localToGrid(m_frame.toLocal(world)); }
    glm::vec3 gridToWorld(glm::vec3 grid) const { return m_frame.toWorld(gridToLocal(grid)); }

private:
    // What make() uses once it has validated the arguments: no second check.
    struct Checked {};
    GridLayout(Aabb bounds, glm::uvec3 resolution, PositionMode mode, RigidFrame frame, Checked);

    Aabb m_bounds;
    glm::uvec3 m_resolution{1u};
    PositionMode m_mode = PositionMode::Center;
    RigidFrame m_frame;
};

constexpr bool isPowerOfTwo(uint32_t v) {
    return v != 0 && (v & (v - 1)) == 0;
}

} // namespace probekit::grid
