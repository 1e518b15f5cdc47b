// Light modes (BakeConfig::lights, docs/baking.md#light-modes) applied to a scene: lights in mode
// none removed, emissive surfaces and the environment in mode none turned off, and which sources'
// direct light a probe stores (Scene::lightDirectStored, emissiveDirectStored,
// environmentDirectStored) for the integrators to read.
#pragma once

#include <optional>

#include "probekit/baker/config.hpp"
#include "probekit/baker/light_modes.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Nothing when every mode is baked (the scene is used as it is); otherwise a copy of `scene`
// with config.lights applied. Fails, naming the config field, when lights.per_light names a light
// the scene does not have, or when the method cannot honour a mode (indirect with lpv.direct
// propagated, where the grid carries direct and bounced light together).
Result<std::optional<Scene>> applyLightModes(const Scene& scene, const BakeConfig& config);

} // namespace probekit::baker
