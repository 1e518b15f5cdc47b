// KHR_lights_punctual -> Scene::lights: type, colour, intensity and range, spot cones, and the
// placement from the node's world matrix. Part of GltfLoader (gltf_loader.hpp).
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include "scene/gltf_loader.hpp"

namespace probekit::baker::gltf {

void GltfLoader::loadLight(int node_index, const tinygltf::Value& extension,
                           const glm::dmat4& world) {
    const std::string node_field =
        "nodes[" + std::to_string(node_index) + "].extensions.KHR_lights_punctual";
    if (!extension.Has("light") || !extension.Get("light").IsNumber()) {
        fail(ErrorCode::InvalidArgument, node_field + ".light must be a light index");
    }
    const int light_index = extension.Get("light").GetNumberAsInt();
    if (light_index < 0 || static_cast<size_t>(light_index) >= m_model.lights.size()) {
        fail(ErrorCode::OutOfRange, node_field + ".light " + std::to_string(light_index) +
                                        " is out of range (" +
                                        std::to_string(m_model.lights.size()) + " lights)");
    }
    const tinygltf::Light& source = m_model.lights[static_cast<size_t>(light_index)];
    const std::string field =
        "extensions.KHR_lights_punctual.lights[" + std::to_string(light_index) + "]";

    PunctualLight light;
    light.name = source.name.empty() ? m_model.nodes[size_t(node_index)].name : source.name;
    light.type = lightType(source, field);
    const glm::dvec3 colour = lightColour(source, field);
    setLightStrength(light, colour, source, field);
    if (light.type == LightType::Spot) {
        setSpotCones(light, source, field);
    }
    if (!placeLight(light, world, node_field, light_index)) {
        return;
    }
    m_scene.lights.push_back(std::move(light));
    m_scene.gltfLights.push_back(
        GltfLight{light_index, glm::vec3(colour), static_cast<float>(source.intensity)});
}

LightType GltfLoader::lightType(const tinygltf::Light& source, const std::string& field) const {
    if (source.type == "point") {
        return LightType::Point;
    }
    if (source.type == "spot") {
        return LightType::Spot;
    }
    if (source.type != "directional") {
        fail(ErrorCode::BadEnum, field + ".type '" + source.type +
                                     "' is not point, spot or "
                                     "directional");
    }
    return LightType::Directional;
}

// The light's colour (white when absent), finite and >= 0.
glm::dvec3 GltfLoader::lightColour(const tinygltf::Light& source, const std::string& field) const {
    glm::dvec3 colour(1.0);
    if (!source.color.empty()) {
        if (source.color.size() != 3) {
            fail(ErrorCode::InvalidArgument, field + ".color must have 3 components");
        }
        colour = glm::dvec3(source.color[0], source.color[1], source.color[2]);
    }
    if (!isFinite(colour) || colour.x < 0 || colour.y < 0 || colour.z < 0) {
        fail(ErrorCode::OutOfRange, field + ".color must be finite and >= 0");
    }
    return colour;
}

// Intensity x colour and range, checked as the floats they become.
void GltfLoader::setLightStrength(PunctualLight& light, glm::dvec3 colour,
                                  const tinygltf::Light& source, const std::string& field) const {
    if (!std::isfinite(source.intensity) || source.intensity < 0) {
        fail(ErrorCode::OutOfRange, field + ".intensity must be finite and >= 0");
    }
    // Finite doubles, but the light keeps floats (largest 3.4e38): an intensity of 1e300
    // would become infinite radiance and NaN SH coefficients far from here.
    light.intensity = glm::vec3(colour * source.intensity);
    if (!isFinite(glm::dvec3(light.intensity)) || !isFinite(glm::dvec3(glm::vec3(colour))) ||
        !std::isfinite(static_cast<float>(source.intensity))) {
        fail(ErrorCode::NonFinite, field + ".intensity " + numberText(source.intensity) +
                                       " x color (" + numberText(colour.x) + ", " +
                                       numberText(colour.y) + ", " + numberText(colour.z) +
                                       ") overflows a 32-bit float");
    }
    const glm::dvec3 exact = colour * source.intensity; // compared before rounding to float
    if (std::max({exact.x, exact.y, exact.z}) > kMaxEmission) {
        fail(ErrorCode::OutOfRange,
             field + ".intensity " + numberText(source.intensity) + " x color (" +
                 numberText(colour.x) + ", " + numberText(colour.y) + ", " + numberText(colour.z) +
                 ") is above " + numberText(kMaxEmission) +
                 ", the brightest light probekit bakes (the sun is about 1.2e5 lux)");
    }
    if (!std::isfinite(source.range) || source.range < 0) {
        fail(ErrorCode::OutOfRange, field + ".range must be finite and > 0 (absent: infinite)");
    }
    light.range = static_cast<float>(source.range);
    if (!std::isfinite(light.range)) {
        fail(ErrorCode::NonFinite,
             field + ".range " + numberText(source.range) + " overflows a 32-bit float");
    }
}

// The cone angles, 0 <= inner <= outer <= pi/2, as cosines.
void GltfLoader::setSpotCones(PunctualLight& light, const tinygltf::Light& source,
                              const std::string& field) const {
    const double inner = source.spot.innerConeAngle;
    const double outer = source.spot.outerConeAngle;
    constexpr double kHalfPi = 1.57079632679489662;
    if (!std::isfinite(inner) || !std::isfinite(outer) || inner < 0 || inner > outer ||
        outer > kHalfPi) {
        fail(ErrorCode::OutOfRange,
             field + ".spot: need 0 <= innerConeAngle <= outerConeAngle <= pi/2 (got " +
                 std::to_string(inner) + ", " + std::to_string(outer) + ")");
    }
    light.innerConeCos = static_cast<float>(std::cos(inner));
    light.outerConeCos = static_cast<float>(std::cos(outer));
}

// Position and direction from the node's world matrix; false (with a warning) when the
// transform collapses a spot or directional light's direction.
bool GltfLoader::placeLight(PunctualLight& light, const glm::dmat4& world,
                            const std::string& node_field, int light_index) {
    light.position = glm::vec3(world[3]);
    if (!isFinite(glm::dvec3(light.position))) {
        fail(ErrorCode::NonFinite,
             node_field + ": the node's world position overflows a 32-bit float");
    }
    // Lights shine along the node's local -Z; the linear part of the world matrix carries
    // it (normalised, since a scaled node must not change the light).
    const glm::dvec3 direction = glm::dmat3(world) * glm::dvec3(0.0, 0.0, -1.0);
    const double length = glm::length(direction);
    if (light.type != LightType::Point) {
        if (!(length > 1e-12) || !std::isfinite(length)) {
            warn(node_field + ": the node's transform collapses the light direction; light " +
                 std::to_string(light_index) + " is skipped");
            return false;
        }
        light.direction = glm::vec3(direction / length);
    }
    return true;
}

} // namespace probekit::baker::gltf
