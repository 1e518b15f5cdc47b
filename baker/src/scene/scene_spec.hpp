// The bundled scenes as data (generators.cpp writes them as glTF): materials, meshes built of
// boxes, ellipsoids and cylinders, textures and lights. Private to baker/src/scene.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace probekit::baker::generated {

struct MaterialSpec {
    std::string name;
    glm::vec3 albedo;
    glm::vec3 emission{0.0f}; // radiance, W/(sr m^2)
    int texture = -1;         // base-colour texture, index into SceneSpec::textures, or -1
};

// An 8-bit sRGB-encoded RGB image, row 0 at the top (glTF uv (0, 0) is its top-left corner),
// written as a PNG beside the .gltf: glTF base-colour textures are sRGB (formats/CONVENTIONS.md
// keeps radiometry linear, so the loader decodes them).
struct TextureSpec {
    std::string name;
    uint32_t width = 0;
    uint32_t height = 0;
    std::vector<uint8_t> rgb; // width * height * 3, row-major
};

// Counter-clockwise seen from outside everywhere: the baker's validity test counts back-face
// hits to find probes inside solids (docs/baking.md#config: validity), so the winding says which
// side is out.
struct MeshSpec {
    int material = 0;
    std::vector<glm::vec3> positions;
    std::vector<glm::vec2> uvs; // one per position; written only when the material is textured
    std::vector<uint32_t> indices;

    uint32_t vertex(glm::vec3 p, glm::vec2 uv) {
        positions.push_back(p);
        uvs.push_back(uv);
        return uint32_t(positions.size() - 1);
    }
    // Adds a planar quad a-b-c-d (in order around its edge), the whole texture across it.
    void quad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
        const uint32_t base = vertex(a, {0.0f, 1.0f});
        vertex(b, {1.0f, 1.0f});
        vertex(c, {1.0f, 0.0f});
        vertex(d, {0.0f, 0.0f});
        indices.insert(indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    }
    // Adds an axis-aligned box.
    void box(glm::vec3 lo, glm::vec3 hi) {
        const glm::vec3 p[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
                                {lo.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                                {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
        quad(p[0], p[3], p[2], p[1]); // -z
        quad(p[4], p[5], p[6], p[7]); // +z
        quad(p[0], p[4], p[7], p[3]); // -x
        quad(p[1], p[2], p[6], p[5]); // +x
        quad(p[0], p[1], p[5], p[4]); // -y
        quad(p[3], p[7], p[6], p[2]); // +y
    }
    // Adds an ellipsoid: `segments` around +Y, `rings` from top to bottom, one triangle per
    // segment at each pole (segments x (2 rings - 2) triangles). The texture wraps once
    // around (u) and runs from the top pole (v = 0) to the bottom one (v = 1).
    void ellipsoid(glm::vec3 center, glm::vec3 radii, uint32_t segments, uint32_t rings) {
        const uint32_t base = uint32_t(positions.size());
        for (uint32_t j = 0; j <= rings; ++j) {
            const float theta = std::numbers::pi_v<float> * float(j) / float(rings);
            for (uint32_t i = 0; i <= segments; ++i) {
                const float phi = 2.0f * std::numbers::pi_v<float> * float(i) / float(segments);
                const glm::vec3 dir(std::sin(theta) * std::cos(phi), std::cos(theta),
                                    std::sin(theta) * std::sin(phi));
                vertex(center + radii * dir, {float(i) / float(segments), float(j) / float(rings)});
            }
        }
        auto at = [&](uint32_t i, uint32_t j) { return base + j * (segments + 1) + i; };
        for (uint32_t j = 0; j < rings; ++j) {
            for (uint32_t i = 0; i < segments; ++i) {
                // At the top pole the first triangle, at the bottom one the second, collapses.
                if (j != 0) {
                    indices.insert(indices.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
                }
                if (j + 1 != rings) {
                    indices.insert(indices.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
                }
            }
        }
    }
    // Adds a closed cylinder from `a` to `b` (4 x segments triangles: sides and two caps).
    void cylinder(glm::vec3 a, glm::vec3 b, float radius, uint32_t segments) {
        const glm::vec3 w = glm::normalize(b - a);
        const glm::vec3 helper = std::abs(w.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
        const glm::vec3 u = glm::normalize(glm::cross(helper, w));
        const glm::vec3 v = glm::cross(w, u); // (u, v, w) right-handed: sides face out
        const uint32_t base = uint32_t(positions.size());
        for (uint32_t i = 0; i <= segments; ++i) {
            const float phi = 2.0f * std::numbers::pi_v<float> * float(i) / float(segments);
            const glm::vec3 r = radius * (std::cos(phi) * u + std::sin(phi) * v);
            vertex(a + r, {float(i) / float(segments), 1.0f});
            vertex(b + r, {float(i) / float(segments), 0.0f});
        }
        const uint32_t bottom = vertex(a, {0.5f, 0.5f});
        const uint32_t top = vertex(b, {0.5f, 0.5f});
        for (uint32_t i = 0; i < segments; ++i) {
            const uint32_t a0 = base + 2 * i, b0 = a0 + 1, a1 = a0 + 2, b1 = a0 + 3;
            indices.insert(indices.end(), {a0, a1, b1, a0, b1, b0, top, b0, b1, bottom, a1, a0});
        }
    }
};

struct PointLightSpec {
    glm::vec3 position;
    glm::vec3 color;
    float intensity; // W/sr
};

struct SpotLightSpec {
    glm::vec3 position;
    glm::vec3 direction; // unit vector the cone's axis points along
    glm::vec3 color;
    float intensity; // W/sr on the axis
    float innerConeDeg;
    float outerConeDeg;
};

struct DirectionalLightSpec {
    glm::vec3 direction; // unit vector the light travels along
    glm::vec3 color;
    float intensity; // W/m^2 on a surface facing the light
};

struct SceneSpec {
    std::vector<MaterialSpec> materials;
    std::vector<MeshSpec> meshes;
    std::vector<TextureSpec> textures;
    std::vector<PointLightSpec> lights;
    std::vector<SpotLightSpec> spots;
    std::vector<DirectionalLightSpec> suns;
};

// The game levels (level_generators.cpp; generators.hpp describes them).
SceneSpec arenaLevel();
SceneSpec arenaSealed();

} // namespace probekit::baker::generated
