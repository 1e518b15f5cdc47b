// probekit::baker light modes on a scene (docs/baking.md#light-modes): which mode each of a
// scene's punctual lights gets from a config's `lights` section, for the bake and for a renderer
// that shades the lights a volume left out.
#pragma once

#include <vector>

#include "probekit/baker/config.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Per light of `scene.lights`: modes.punctual, or the last per_light entry naming it by name or
// by glTF light index (its position in Scene::lights for a scene not loaded from glTF). Fails,
// naming lights.per_light."KEY" and listing the scene's lights, on a key no light has.
Result<std::vector<LightMode>> lightModesOf(const Scene& scene, const LightModesConfig& modes);

} // namespace probekit::baker
