// probekit::RgbaImage and probekit::Environment — linear images and the distant environment,
// shared by the baker (which lights probes with the environment and albedo textures) and the
// runtime renderer (which draws the environment behind the geometry and samples base-colour
// textures per pixel). Both need the same lat-long mapping and the same bilinear lookup, so they
// live here once (ARCHITECTURE.md: what baker and runtime both need lives in formats). Decoding
// image files (OpenImageIO) stays in the baker.
//
// Units follow formats/CONVENTIONS.md: environment texels are radiance in W/(sr m^2), linear.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace probekit {

// A linear-light RGBA float image. Row 0 is the top of the image (glTF uv (0, 0) is the
// top-left corner; lat-long row 0 is +Y).
struct RgbaImage {
    uint32_t width = 0;
    uint32_t height = 0;
    std::vector<glm::vec4> texels; // width * height, row-major

    // Bilinear lookup with repeat wrapping at glTF uv (u right, v down), texel centres at
    // (i + 0.5) / size: what a Vulkan sampler with LINEAR filtering and REPEAT addressing
    // returns, so the runtime's GPU texture fetches take this as their CPU twin. An empty image
    // returns 1 (an untextured material keeps its factor).
    glm::vec4 sampleBilinear(glm::vec2 uv) const;
};

// Lat-long mapping (documented here once): image column u in [0, 1) left to right and row v in
// [0, 1) top to bottom map to the world direction (before rotation)
//     phi = 2 pi u, theta = pi v,
//     dir = (sin theta sin phi, cos theta, -sin theta cos phi)
// so the top row is +Y, the bottom row -Y, the image centre (u = 0.5) looks along +Z, and the
// left/right edge (u = 0) along -Z. `rotation_deg` turns the map about +Y (counter-clockwise
// seen from above, right-handed). Returns the (u, v) that a unit direction `dir` reads.
// GPU twin: pk_latlong_uv (shaders/background.frag).
glm::vec2 latLongUv(glm::vec3 dir, float rotation_deg);

// Radiance arriving from infinitely far away in direction `dir` (pointing away from the scene):
// a constant, or a lat-long image (latLongUv) scaled by `intensity`.
struct Environment {
    enum class Type : uint8_t { Constant, LatLong };
    Type type = Type::Constant;
    glm::vec3 constant{0.0f}; // W/(sr m^2), used when type == Constant
    RgbaImage image;          // linear radiance, used when type == LatLong
    float intensity = 1.0f;
    float rotationDeg = 0.0f;
    std::string source; // file name, for messages

    glm::vec3 radiance(glm::vec3 dir) const;
    bool isBlack() const;
};

} // namespace probekit
