// A glTF scene relit by the runtime's dynamic GI (viewer/include/probekit/viewer/scene_gi.hpp).
#include "probekit/viewer/scene_gi.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace probekit::viewer {

DynamicLights dynamicLights(const baker::Scene& scene, bool baked, bool makeSun) {
    DynamicLights out;
    std::vector<PunctualLight>& lights = out.lights;
    for (const PunctualLight& light : scene.lights) {
        if ((!baked || light.type == LightType::Directional) &&
            lights.size() < runtime::kMaxGiLights) {
            lights.push_back(light);
        }
    }
    auto sun = std::find_if(lights.begin(), lights.end(), [](const PunctualLight& l) {
        return l.type == LightType::Directional;
    });
    if (sun == lights.end() && makeSun) {
        PunctualLight made;
        made.type = LightType::Directional;
        made.intensity = glm::vec3(3.0f);
        made.name = "sun (--sun-path)";
        lights.insert(lights.begin(), made);
        sun = lights.begin();
    }
    out.sun = size_t(sun - lights.begin());
    return out;
}

glm::vec3 sunTravel(const std::array<float, 4>& path, float t) {
    const float az = glm::radians(path[0] + t * (path[2] - path[0]));
    const float el = glm::radians(path[1] + t * (path[3] - path[1]));
    return -glm::vec3(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
}

sh::ShRgb skySh(const Environment& environment) {
    constexpr int kDirections = 4096;
    sh::ShRgb out;
    const float weight = 4.0f * float(M_PI) / float(kDirections);
    for (int i = 0; i < kDirections; ++i) {
        const glm::vec3 w = sh::fibonacciDirection(i, kDirections);
        const glm::vec3 radiance = environment.radiance(w);
        const sh::Coeffs y = sh::evalBasis(w);
        for (int k = 0; k < sh::kMaxCoefficients; ++k) {
            out.rgb[size_t(k)] += (weight * y[size_t(k)]) * radiance;
        }
    }
    return out;
}

runtime::DynamicGiSettings fitCascades(runtime::DynamicGiSettings settings,
                                       const baker::Scene& scene) {
    const glm::vec3 size = scene.bounds.max - scene.bounds.min;
    const float longest = std::max({size.x, size.y, size.z});
    settings.cellSize =
        longest / float(settings.resolution - 2) / float(1u << (settings.cascades - 1));
    settings.aheadFraction = 0.0f;
    return settings;
}

Result<void> prepareGi(runtime::DynamicGi& gi, const RenderScene& flat, const baker::Scene& scene,
                       const Environment& environment, const runtime::Camera& camera,
                       bool centred) {
    if (auto r = gi.setGeometry(flat.vertices, flat.indices); !r) {
        return r;
    }
    if (!environment.isBlack()) {
        gi.setSky(skySh(environment));
    }
    const glm::vec3 forward = glm::normalize(camera.target - camera.eye);
    gi.setCamera(centred ? scene.bounds.center() : camera.eye, forward);
    return {};
}

} // namespace probekit::viewer
