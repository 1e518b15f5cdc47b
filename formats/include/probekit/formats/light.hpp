// probekit::PunctualLight — the one punctual-light model shared by the baker (its scenes and
// integrators) and the runtime renderer (its unshadowed direct light).
//
// KHR_lights_punctual lights, already in world space and in the radiometric units of
// formats/CONVENTIONS.md: point and spot intensity (candela) is taken as W/sr, directional
// intensity (lux) as W/m^2 on a surface facing the light. Nothing here traces shadows: every
// function is the light's unshadowed contribution, and callers that need visibility (the baker)
// trace their own shadow ray along directionToLight.
//
// The light terms, each defined once here:
//   point:       E_facing = I / d^2 x window(d)
//   spot:        E_facing = I / d^2 x window(d) x t^2,
//                t = clamp((cos_angle - cos_outer) / max(0.001, cos_inner - cos_outer), 0, 1),
//                cos_angle between the spot's direction and the ray from the light to the point
//                (glTF's quadratic ramp between the outer and inner cones, no smoothstep);
//   directional: E_facing = I, everywhere;
//   window(d) = clamp(1 - (d / range)^4, 0, 1)^2 when range > 0, else 1 (KHR_lights_punctual's
//                recommended smooth window).
// A surface with unit normal n receives E = E_facing x max(0, n . l), l the unit direction from
// the surface towards the light (irradianceAt).
//
// CPU twin: irradianceAt is the specification and test oracle of shaders/shade.comp's
// pk_direct_irradiance (summed over the frame's lights), which mirrors it term for term
// (ARCHITECTURE.md: every GPU computation has a CPU twin).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <glm/vec3.hpp>

namespace probekit {

enum class LightType : uint8_t { Point, Spot, Directional };

struct PunctualLight {
    LightType type = LightType::Point;
    glm::vec3 position{0.0f};               // world, metres (point, spot)
    glm::vec3 direction{0.0f, 0.0f, -1.0f}; // world unit vector light travels along (spot, dir.)
    glm::vec3 intensity{0.0f};              // colour x intensity: W/sr (point, spot), W/m^2 (dir.)
    float range = 0.0f;                     // metres; 0 = infinite
    float innerConeCos = 1.0f;              // spot: cos(innerConeAngle)
    float outerConeCos = 0.70710678f;       // spot: cos(outerConeAngle), glTF's default pi/4
    std::string name;                       // for messages; may be empty
};

struct LightDirection {
    glm::vec3 direction; // unit, from the point towards the light
    float distance;      // to the light, metres; infinite for directional lights
};

// Where the light is seen from `point`: the direction towards it (for a directional light,
// -normalize(direction)) and the distance a shadow ray must cover. Nothing for a point or spot
// light at the point itself.
std::optional<LightDirection> directionToLight(const PunctualLight& light, glm::vec3 point);

// KHR_lights_punctual's range window clamp(1 - (d / range)^4, 0, 1)^2 at squared distance
// `distance_squared`; 1 when range is 0 (infinite).
float rangeWindow(float range, float distance_squared);

// Irradiance (W/m^2 per channel) on a surface at `point` that faces the light, without
// visibility: the E_facing of the list above. Zero for a point or spot light at the point.
glm::vec3 normalIrradianceAt(const PunctualLight& light, glm::vec3 point);

// Irradiance E (W/m^2 per channel) on a surface at `point` with unit normal `normal`, without
// visibility: normalIrradianceAt x max(0, normal . directionToLight). The CPU twin of
// pk_direct_irradiance (shaders/shade.comp); a Lambertian surface of albedo rho reflects
// rho E / pi (formats/CONVENTIONS.md).
glm::vec3 irradianceAt(const PunctualLight& light, glm::vec3 point, glm::vec3 normal);

} // namespace probekit
