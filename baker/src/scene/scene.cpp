#include "probekit/baker/scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>

namespace probekit::baker {

namespace {
glm::vec2 interpolatedUv(const Scene& scene, uint32_t tri, glm::vec2 bary) {
    const glm::uvec3 t = scene.triangles[tri];
    return (1.0f - bary.x - bary.y) * scene.uvs[t.x] + bary.x * scene.uvs[t.y] +
           bary.y * scene.uvs[t.z];
}
} // namespace

glm::vec3 Scene::albedoAt(uint32_t tri, glm::vec2 bary) const {
    const Material& m = materials[triangleMaterial[tri]];
    if (m.baseColorTexture < 0) {
        return m.baseColor;
    }
    return m.baseColor *
           glm::vec3(images[m.baseColorTexture].sampleBilinear(interpolatedUv(*this, tri, bary)));
}

glm::vec3 Scene::emissionAt(uint32_t tri, glm::vec2 bary) const {
    const Material& m = materials[triangleMaterial[tri]];
    if (m.emissiveTexture < 0) {
        return m.emission;
    }
    return m.emission *
           glm::vec3(images[m.emissiveTexture].sampleBilinear(interpolatedUv(*this, tri, bary)));
}

namespace {
template <class T>
uint64_t arrayBytes(const std::vector<T>& v) {
    return uint64_t(v.capacity()) * sizeof(T);
}
uint64_t imageBytes(const Image& image) {
    return arrayBytes(image.texels);
}
} // namespace

uint64_t sceneBytes(const Scene& scene) {
    uint64_t bytes = arrayBytes(scene.positions) + arrayBytes(scene.uvs) +
                     arrayBytes(scene.normals) + arrayBytes(scene.triangles) +
                     arrayBytes(scene.triangleMaterial) + arrayBytes(scene.triangleNode) +
                     arrayBytes(scene.materials) + arrayBytes(scene.lights) +
                     arrayBytes(scene.gltfLights) + arrayBytes(scene.nodes) +
                     imageBytes(scene.environment.image);
    for (const Image& image : scene.images) {
        bytes += imageBytes(image);
    }
    return bytes;
}

void applyUnitScale(Scene& scene, float scale) {
    scene.unitScale *= scale;
    if (scale == 1.0f) {
        return;
    }
    for (glm::vec3& p : scene.positions) {
        p *= scale;
    }
    scene.bounds = grid::Aabb{scene.bounds.min * scale, scene.bounds.max * scale};
    const glm::mat4 to_metres = glm::mat4(glm::vec4(scale, 0, 0, 0), glm::vec4(0, scale, 0, 0),
                                          glm::vec4(0, 0, scale, 0), glm::vec4(0, 0, 0, 1));
    for (SceneNode& n : scene.nodes) {
        n.world = to_metres * n.world;
        n.worldBounds = grid::Aabb{n.worldBounds.min * scale, n.worldBounds.max * scale};
    }
    for (PunctualLight& l : scene.lights) {
        l.position *= scale;
        l.range *= scale;
    }
}

namespace {
// A triangle is a wall (a vertical surface) when its face normal is within ~11.5 degrees of
// horizontal.
constexpr float kWallNormalY = 0.2f;

// The scene's storey height, in metres: the area-weighted median of the vertical extent of its
// walls (a wall made of two triangles spans its whole height; the risers of stairs and trims
// are short but small in area). 0 when the scene has no walls. A wall tessellated into many
// rows of triangles reads shorter than it is, so this only ever clears or narrows a warning.
float storeyHeight(const Scene& scene) {
    std::vector<std::pair<float, float>> walls; // (height, area)
    double total = 0.0;
    for (const glm::uvec3& t : scene.triangles) {
        const glm::vec3 a = scene.positions[t.x], b = scene.positions[t.y],
                        c = scene.positions[t.z];
        const glm::vec3 n = glm::cross(b - a, c - a);
        const float twice_area = glm::length(n);
        if (!(twice_area > 0.0f) || std::abs(n.y) > kWallNormalY * twice_area) {
            continue;
        }
        const float height = std::max({a.y, b.y, c.y}) - std::min({a.y, b.y, c.y});
        walls.emplace_back(height, 0.5f * twice_area);
        total += 0.5 * twice_area;
    }
    if (walls.empty()) {
        return 0.0f;
    }
    std::sort(walls.begin(), walls.end());
    double below = 0.0;
    for (const auto& [height, area] : walls) {
        below += area;
        if (below >= 0.5 * total) {
            return height;
        }
    }
    return walls.back().first;
}

bool plausibleStorey(float metres) {
    return metres >= kPlausibleStoreyMinMetres && metres <= kPlausibleStoreyMaxMetres;
}

// The "--scale S makes it X m" clauses for a scene over kPlausibleSceneMaxMetres: the scales
// whose storey height is plausible, or every scale when none is (or the scene has no walls).
std::string scaleSuggestions(float longest, float storey) {
    struct Unit {
        const char* name;
        const char* flag;
        float scale;
    };
    const Unit units[] = {{"centimetres", "0.01", 0.01f},
                          {"inches", "0.0254", 0.0254f},
                          {"millimetres", "0.001", 0.001f}};
    bool any = false;
    for (const Unit& u : units) {
        any = any || plausibleStorey(storey * u.scale);
    }
    std::string out;
    char clause[160];
    for (const Unit& u : units) {
        if (any && !plausibleStorey(storey * u.scale)) {
            continue;
        }
        std::snprintf(clause, sizeof clause, "%sin %s, --scale %s makes it %.4g m",
                      out.empty() ? "if the file is " : "; ", u.name, u.flag, longest * u.scale);
        out += clause;
        if (storey > 0.0f) {
            std::snprintf(clause, sizeof clause, " with %.3g m walls", storey * u.scale);
            out += clause;
        }
    }
    return out;
}
} // namespace

// The rule (scene.hpp): plausible in metres when the longest side is 1 cm..100 m, or when the
// walls' median height is a storey (2..6 m) whatever the extent, so a 120 m level of 3 m rooms
// is not questioned. Over 100 m with implausible walls, the warning names the scales that make
// the walls a storey: a 3 m room in centimetres is 300 units high (0.01 fits, 0.0254 makes
// 7.6 m), in inches 118 units (0.0254 fits, 0.01 makes 1.2 m).
std::string implausibleSizeWarning(const Scene& scene, const std::string& file) {
    if (!scene.hasGeometry()) {
        return {};
    }
    const glm::vec3 size = scene.bounds.size();
    const float longest = std::max({size.x, size.y, size.z});
    if (longest >= kPlausibleSceneMinMetres && longest <= kPlausibleSceneMaxMetres) {
        return {};
    }
    char text[768];
    if (longest > kPlausibleSceneMaxMetres) {
        const float storey = storeyHeight(scene);
        if (plausibleStorey(storey)) {
            return {};
        }
        char walls[96] = "it has no walls";
        if (storey > 0.0f) {
            std::snprintf(walls, sizeof walls,
                          "its walls are %.3g m high (median; a storey is %g "
                          "to %g m)",
                          storey, kPlausibleStoreyMinMetres, kPlausibleStoreyMaxMetres);
        }
        std::snprintf(text, sizeof text,
                      "%s: the scene is %.4g m across (%.4g x %.4g x %.4g m), more than %g m, and "
                      "%s: %s (glTF says metres; exporters often write other units)",
                      file.c_str(), longest, size.x, size.y, size.z, kPlausibleSceneMaxMetres,
                      walls, scaleSuggestions(longest, storey).c_str());
    } else {
        std::snprintf(text, sizeof text,
                      "%s: the scene is %.4g m across, less than %g m: if the file is in "
                      "kilometres, --scale 1000 makes it %.4g m",
                      file.c_str(), longest, kPlausibleSceneMinMetres, longest * 1000.0f);
    }
    return text;
}

} // namespace probekit::baker
