// probekit::viewer — a glTF scene relit by the runtime's dynamic GI (runtime/dynamic_gi.hpp):
// its dynamic lights and sun, its sky as SH, and cascades fitted to it.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/environment.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/runtime/dynamic_gi.hpp"
#include "probekit/viewer/scene_view.hpp"

namespace probekit::viewer {

// The lights the dynamic GI relights with, and which of them is the sun (lights.size() when
// none is).
struct DynamicLights {
    std::vector<PunctualLight> lights;
    size_t sun = 0;

    PunctualLight* sunLight() { return sun < lights.size() ? &lights[sun] : nullptr; }
};

// The scene's directional lights when the volumes hold the rest (`baked`), every punctual
// light otherwise (nothing else lights the scene), up to runtime::kMaxGiLights. With
// `makeSun` and no directional light, a white 3 W/m^2 sun is added first.
DynamicLights dynamicLights(const baker::Scene& scene, bool baked, bool makeSun);

// The direction the sun's light travels at t in [0, 1] along `path` = (azimuth0, elevation0,
// azimuth1, elevation1) in degrees, linear in the angles (azimuth 0: the sun stands in +z; 90:
// in +x; elevation above the horizon).
glm::vec3 sunTravel(const std::array<float, 4>& path, float t);

// The environment's radiance as L2 SH (4096 Fibonacci directions): the dynamic GI's sky.
sh::ShRgb skySh(const Environment& environment);

// The settings with cascades that hold the scene: the finest cell size for which the coarsest
// cascade spans the scene's longest side with a cell to spare on each end, centred on the scene
// (aheadFraction 0). Without this the cascades keep their cell size and follow the camera.
runtime::DynamicGiSettings fitCascades(runtime::DynamicGiSettings settings,
                                       const baker::Scene& scene);

// Gives the dynamic GI the scene's geometry, its sky (unless the environment is black) and the
// camera that places the cascades: the scene's centre when `centred`, the eye otherwise.
Result<void> prepareGi(runtime::DynamicGi& gi, const RenderScene& flat, const baker::Scene& scene,
                       const Environment& environment, const runtime::Camera& camera, bool centred);

} // namespace probekit::viewer
