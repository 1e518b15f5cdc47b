#include "scene/coordinate_range.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace probekit::baker {

namespace {

// The largest |component|, or NaN when one is NaN (so that a comparison with it fails).
float largestMagnitude(glm::vec3 p) {
    if (std::isnan(p.x) || std::isnan(p.y) || std::isnan(p.z)) {
        return NAN;
    }
    return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
}

bool outOfRange(float magnitude) {
    return !(magnitude <= kMaxCoordinate);
}

std::string describe(glm::vec3 p) {
    char text[96];
    std::snprintf(text, sizeof text, "(%.4g, %.4g, %.4g)", double(p.x), double(p.y), double(p.z));
    return text;
}

std::string rangeText() {
    char text[300];
    std::snprintf(text, sizeof text,
                  "outside the coordinate range a bake supports, |x|, |y|, |z| <= %.0e m (beyond "
                  "it float32 resolves a metre or worse and rays leave surfaces hundreds of "
                  "metres off); check the scene's units (--scale) or move it near the origin",
                  double(kMaxCoordinate));
    return text;
}

} // namespace

Result<void> checkSceneCoordinates(const Scene& scene) {
    const std::string file = scene.source.empty() ? "scene" : scene.source;
    // Only vertices a triangle uses are traced; find the farthest one and its triangle.
    float worst = 0.0f;
    size_t worst_triangle = 0;
    uint32_t worst_vertex = 0;
    for (size_t i = 0; i < scene.triangles.size() && !std::isnan(worst); ++i) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = scene.triangles[i][k];
            if (v >= scene.positions.size()) {
                continue; // RayTracer::create reports the bad index
            }
            const float m = largestMagnitude(scene.positions[v]);
            if (std::isnan(m) || m > worst) {
                worst = m;
                worst_triangle = i;
                worst_vertex = v;
            }
        }
    }
    if (outOfRange(worst)) {
        std::string where;
        if (worst_triangle < scene.triangleNode.size()) {
            const int32_t node = scene.triangleNode[worst_triangle];
            if (node >= 0 && size_t(node) < scene.nodes.size()) {
                const SceneNode& n = scene.nodes[size_t(node)];
                where = " node " + std::to_string(n.gltfIndex) +
                        (n.name.empty() ? "" : " ('" + n.name + "')") + ",";
            }
        }
        return makeError(ErrorCode::OutOfRange, file + ":" + where + " triangle " +
                                                    std::to_string(worst_triangle) + ": vertex " +
                                                    describe(scene.positions[worst_vertex]) +
                                                    " m lies " + rangeText());
    }
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        const PunctualLight& light = scene.lights[i];
        if (light.type == LightType::Directional) {
            continue; // no position: it shines from infinitely far
        }
        if (outOfRange(largestMagnitude(light.position))) {
            const int index = i < scene.gltfLights.size() ? scene.gltfLights[i].index : int(i);
            return makeError(ErrorCode::OutOfRange,
                             file + ": light " + std::to_string(index) +
                                 (light.name.empty() ? "" : " ('" + light.name + "')") + " at " +
                                 describe(light.position) + " m lies " + rangeText());
        }
    }
    return {};
}

Result<void> checkVolumeCoordinates(const grid::Aabb& world_box, const std::string& label) {
    const float m = std::max(largestMagnitude(world_box.min), largestMagnitude(world_box.max));
    if (outOfRange(m) || std::isnan(largestMagnitude(world_box.min)) ||
        std::isnan(largestMagnitude(world_box.max))) {
        return makeError(ErrorCode::OutOfRange, label + ": the box " + describe(world_box.min) +
                                                    " .. " + describe(world_box.max) +
                                                    " m reaches " + rangeText());
    }
    return {};
}

std::string precisionNote(const Scene& scene, const grid::Aabb& volumes_box, float finest_spacing) {
    float farthest = std::max(largestMagnitude(volumes_box.min), largestMagnitude(volumes_box.max));
    if (scene.hasGeometry()) {
        farthest = std::max(
            {farthest, largestMagnitude(scene.bounds.min), largestMagnitude(scene.bounds.max)});
    }
    if (!(farthest > 0.0f) || !(finest_spacing > 0.0f)) {
        return {};
    }
    // offsetOrigin moves each coordinate by up to 256 ulps.
    const float ulp = std::nextafter(farthest, INFINITY) - farthest;
    const float offset = 256.0f * ulp;
    if (!(offset > 0.25f * finest_spacing)) {
        return {};
    }
    char text[400];
    std::snprintf(text, sizeof text,
                  "coordinates reach %.4g m, where float32 resolves %.3g m and rays leave "
                  "surfaces up to %.3g m off, more than a quarter of the finest probe spacing "
                  "%.3g m: light near surfaces will be wrong; move the scene near the origin",
                  double(farthest), double(ulp), double(offset), double(finest_spacing));
    return text;
}

} // namespace probekit::baker
