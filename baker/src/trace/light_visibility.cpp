// lightVisibility (light_visibility.hpp).
#include "probekit/baker/light_visibility.hpp"

#include <algorithm>
#include <memory>
#include <string>

#include <glm/geometric.hpp>

#include "trace/parallel.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {
namespace {

// The mask of one point: one shadow ray per light on the lit side of its plane.
uint32_t pointMask(const RayTracer& tracer, const SurfacePoint& point,
                   std::span<const PunctualLight> lights, float lift) {
    if (point.normal == glm::vec3(0.0f)) {
        return 0u;
    }
    const glm::vec3 origin = point.position + lift * point.normal;
    uint32_t mask = 0u;
    for (size_t i = 0; i < lights.size(); ++i) {
        const std::optional<LightDirection> to = directionToLight(lights[i], origin);
        if (!to) {
            mask |= 1u << i; // at the light itself: nothing can be in between
            continue;
        }
        if (glm::dot(point.normal, to->direction) <= 0.0f) {
            continue;
        }
        if (!tracer.occluded(origin, to->direction, to->distance)) {
            mask |= 1u << i;
        }
    }
    return mask;
}

} // namespace

Result<std::vector<uint32_t>> lightVisibility(const Scene& scene,
                                              std::span<const SurfacePoint> points,
                                              std::span<const PunctualLight> lights,
                                              uint32_t threads) {
    if (lights.size() > 32) {
        return makeError(ErrorCode::OutOfRange,
                         "light visibility: " + std::to_string(lights.size()) +
                             " lights, at most 32 (one mask bit each)");
    }
    std::vector<uint32_t> masks(points.size(), 0u);
    if (lights.empty() || points.empty()) {
        return masks;
    }
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    if (!tracer) {
        return tracer.error();
    }
    const float lift = 1e-4f * glm::length(scene.bounds.max - scene.bounds.min);
    const RayTracer& t = *tracer.value();
    parallelFor(points.size(), threads, 4096, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            masks[i] = pointMask(t, points[i], lights, lift);
        }
    });
    return masks;
}

} // namespace probekit::baker
