// probekit::baker::RayTracer — the Embree 3 scene every baker traces against.
//
// One Embree device and one scene of world-space triangles (Scene::positions / triangles),
// built once with high BVH quality (spatial splits: the bake traces billions of rays against
// one build). Immutable after create(); every query is const and thread-safe (Embree queries on
// a committed scene are re-entrant, and this class holds no per-query state).
//
// Surfaces are two-sided: the tracer reports hits on both faces and says which one was hit.
// Embree stays behind this file's .cpp; this header is private to baker/ (and its tests).
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

struct RTCDeviceTy;
struct RTCSceneTy;

namespace probekit::baker {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

struct Hit {
    float t = 0.0f;                  // distance along the ray, in units of |dir|
    uint32_t triangle = 0;           // index into Scene::triangles
    glm::vec2 bary{0.0f};            // Embree (u, v): weights of the triangle's 2nd and 3rd vertex
    glm::vec3 geometricNormal{0.0f}; // unit, world, from the winding: (p1 - p0) x (p2 - p0)
    bool backFace = false;           // dot(dir, geometricNormal) > 0: the ray hit the back face
};

class RayTracer {
public:
    // Builds the Embree device and scene. A scene without triangles is valid (every query then
    // misses). Fails with a message if Embree reports an error (through the device error
    // callback), if this Embree build culls back faces (the baker needs both faces), or if a
    // triangle index is out of range. The tracer copies what it needs: `scene` need not outlive
    // it.
    static Result<std::unique_ptr<RayTracer>> create(const Scene& scene);
    ~RayTracer();
    RayTracer(const RayTracer&) = delete;
    RayTracer& operator=(const RayTracer&) = delete;

    // Closest hit with t in [0, t_max]. `dir` need not be unit length (t is in units of |dir|);
    // it must not be zero. No offsetting is done here: callers leaving a surface pass an origin
    // from offsetOrigin.
    std::optional<Hit> intersect(glm::vec3 origin, glm::vec3 dir, float t_max = kInfinity) const;

    // Whether anything is hit with t in [0, t_max] (any hit, cheaper than intersect).
    bool occluded(glm::vec3 origin, glm::vec3 dir, float t_max) const;

    // Many visibility queries at once: occluded[i] = occluded(rays[i].origin, rays[i].dir,
    // rays[i].tMax) as 0 or 1, same results as the single-ray query. Goes through Embree's ray
    // stream API, which regroups the rays into SIMD packets; `coherent` (rays leaving one point,
    // e.g. a probe gathering lights) lets it use its coherent packet traversal. Preconditions:
    // occluded.size() == rays.size(), every dir non-zero.
    struct OcclusionRay {
        glm::vec3 origin;
        glm::vec3 dir;
        float tMax;
    };
    void occluded(std::span<const OcclusionRay> rays, std::span<uint8_t> occluded,
                  bool coherent) const;

    // The world-space point at barycentrics `bary` of `triangle`, interpolated from the vertices
    // (more precise than origin + t dir far from the origin, which offsetOrigin relies on).
    glm::vec3 surfacePoint(uint32_t triangle, glm::vec2 bary) const;

    uint32_t triangleCount() const { return uint32_t(m_normals.size()); }

    // Bytes Embree allocated for this tracer's device and scene (its memory monitor callback):
    // held now (the BVH), and at most at once (the build's peak). The memory model's BVH
    // constants (memory_model.hpp) are measured with these.
    uint64_t embreeBytes() const { return uint64_t(std::max<int64_t>(0, m_memory->current)); }
    uint64_t embreePeakBytes() const { return uint64_t(std::max<int64_t>(0, m_memory->peak)); }

    // Moves a surface point p off its triangle, to the side of the geometric normal that `dir`
    // leaves on, far enough that a ray from the result towards `dir` cannot hit the same surface
    // through rounding, yet by only a few hundred ulps of p: Wächter and Binder, "A Fast and
    // Robust Method for Avoiding Self-Intersection", Ray Tracing Gems (2019) ch. 6 (integer ulp
    // offset of each coordinate, a fixed float offset near the origin where ulps vanish).
    // Inline: it runs several times per path vertex.
    static glm::vec3 offsetOrigin(glm::vec3 p, glm::vec3 geometric_normal, glm::vec3 dir);

    // Collects messages from Embree's device error callback (thread-safe).
    struct ErrorLog {
        std::mutex mutex;
        std::string messages;
    };
    // Embree's allocations as its memory monitor reports them (thread-safe).
    struct MemoryLog {
        std::atomic<int64_t> current{0};
        std::atomic<int64_t> peak{0};
    };

private:
    // Copies the scene's vertices and triangles into the arrays Embree shares, with the face
    // normals.
    void copyGeometry(const Scene& scene);
    RayTracer() = default;

    RTCDeviceTy* m_device = nullptr;
    RTCSceneTy* m_scene = nullptr;
    std::vector<glm::vec3> m_normals;  // unit geometric normal per triangle (zero if degenerate)
    std::vector<glm::vec3> m_vertices; // world positions, for surfacePoint
    std::vector<glm::uvec3> m_indices; // triangle vertex indices
    std::unique_ptr<ErrorLog> m_errors = std::make_unique<ErrorLog>();
    std::unique_ptr<MemoryLog> m_memory = std::make_unique<MemoryLog>();
};

inline glm::vec3 RayTracer::surfacePoint(uint32_t triangle, glm::vec2 bary) const {
    const glm::uvec3 t = m_indices[triangle];
    const glm::vec3 p0 = m_vertices[t.x];
    return p0 + bary.x * (m_vertices[t.y] - p0) + bary.y * (m_vertices[t.z] - p0);
}

inline glm::vec3 RayTracer::offsetOrigin(glm::vec3 p, glm::vec3 geometric_normal, glm::vec3 dir) {
    // Constants from Ray Tracing Gems ch. 6: below kOrigin in magnitude ulps are too small to
    // cover the intersection error, so a fixed offset of kFloatScale is used there; elsewhere
    // the point moves by kIntScale ulps per unit of normal component.
    constexpr float kOrigin = 1.0f / 32.0f;
    constexpr float kFloatScale = 1.0f / 65536.0f;
    constexpr float kIntScale = 256.0f;
    const glm::vec3 n =
        glm::dot(geometric_normal, dir) < 0.0f ? -geometric_normal : geometric_normal;
    glm::vec3 out;
    for (int axis = 0; axis < 3; ++axis) {
        const int32_t offset = int32_t(kIntScale * n[axis]);
        const int32_t bits = std::bit_cast<int32_t>(p[axis]);
        // Adding to the bit pattern grows the magnitude, so negative coordinates subtract to
        // move along +n.
        const float moved = std::bit_cast<float>(bits + (p[axis] < 0.0f ? -offset : offset));
        out[axis] = std::abs(p[axis]) < kOrigin ? p[axis] + kFloatScale * n[axis] : moved;
    }
    return out;
}

// Fixes the SSE control register for its scope: all exceptions masked, round to nearest,
// flush-to-zero and denormals-are-zero (Embree's recommended mode for tracing threads). A fixed
// state rather than the caller's keeps bakes bit-identical whatever thread runs them; the
// caller's state comes back at the end of the scope.
class ScopedFloatMode {
public:
    ScopedFloatMode();
    ~ScopedFloatMode();
    ScopedFloatMode(const ScopedFloatMode&) = delete;
    ScopedFloatMode& operator=(const ScopedFloatMode&) = delete;

private:
    unsigned m_saved = 0;
};

} // namespace probekit::baker
