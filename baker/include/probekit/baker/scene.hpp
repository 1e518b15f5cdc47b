// probekit::baker::Scene — a glTF 2.0 scene flattened for light transport.
//
// Frame and units follow formats/CONVENTIONS.md: right-handed, +Y up, metres, linear radiometry.
// All geometry is in world space (node transforms applied). Every surface is Lambertian and
// two-sided: albedo = baseColorFactor x baseColorTexture(uv) (texture sRGB-decoded to linear),
// emitted radiance = emissiveFactor x KHR_materials_emissive_strength x emissiveTexture(uv),
// emitted from both sides.
//
// The scene owns all its data; it is immutable after loading and safe to read from any thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "probekit/formats/environment.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/light.hpp"
#include "probekit/formats/result.hpp"

namespace probekit::baker {

// Linear RGBA images and the environment are shared with the runtime renderer, so they are
// defined in formats (formats/include/probekit/formats/environment.hpp, which also documents the
// lat-long mapping).
using Image = RgbaImage;
using Environment = probekit::Environment;

// The largest light intensity (W/sr, or W/m^2 for directional lights, per channel) and emitted
// or environment radiance (W/(sr m^2)) a scene may hold; the loader and the bake config refuse
// more. The sun is about 1.2e5 lux and the brightest real emitters' radiance about 1e9, so
// anything beyond is an authoring or unit error, and the bound keeps the bake's float sums
// finite: a point light of 1e20 W/sr 1 mm from a probe gives 1e26 W/m^2, below the texel bound
// of 1e30 (formats/volume.hpp).
constexpr double kMaxEmission = 1e20;

struct Material {
    std::string name;
    glm::vec3 baseColor{1.0f}; // linear albedo factor, each channel in [0, 1]
    int baseColorTexture = -1; // index into Scene::images (already linear), or -1
    glm::vec3 emission{0.0f};  // emissiveFactor x emissive_strength, W/(sr m^2)
    int emissiveTexture = -1;  // index into Scene::images (already linear), or -1
    int baseColorTexCoord = 0; // which TEXCOORD_n set (only 0 is loaded; others warn)

    bool isEmissive() const { return emission.x > 0 || emission.y > 0 || emission.z > 0; }
};

// Loads an environment from a lat-long HDR/EXR (OpenImageIO). Errors name the file. 8- and
// 16-bit integer images in sRGB (PNG and JPEG unless they say otherwise) are decoded to linear.
// A map whose decode (the pixels as float, then the RGBA texels) would take more than
// `max_bytes` is refused from its header, before the pixels are read.
Result<Environment> loadLatLongEnvironment(const std::filesystem::path& path, float intensity,
                                           float rotation_deg, uint64_t max_bytes = UINT64_MAX);

struct SceneNode {
    std::string name;
    int gltfIndex = -1;
    glm::mat4 world{1.0f};  // local -> world
    grid::Aabb localBounds; // of this node's own mesh, in its local frame (empty: no mesh)
    grid::Aabb worldBounds; // of this node's own mesh, world space
    bool hasMesh = false;
};

// What the glTF said about one of Scene::lights: the KHR_lights_punctual light it came from, its
// colour and its intensity (candela for point and spot lights, lux for directional ones);
// the light's intensity is their product (formats/CONVENTIONS.md gives the units).
struct GltfLight {
    int index = -1; // into the file's KHR_lights_punctual lights
    glm::vec3 color{1.0f};
    float intensity = 0.0f;
};

struct Scene {
    // Triangles, world space.
    std::vector<glm::vec3> positions;
    std::vector<glm::vec2> uvs; // one per position (zero when the mesh has none)
    // One per position: the glTF NORMAL in world space (transformed by the inverse transpose of
    // the node's matrix), unit length; zero where the mesh has none. Scenes built in code may
    // leave it empty. The light transport uses face normals; the renderer shades with these.
    std::vector<glm::vec3> normals;
    std::vector<glm::uvec3> triangles;      // indices into positions
    std::vector<uint32_t> triangleMaterial; // per triangle, index into materials
    std::vector<int32_t> triangleNode;      // per triangle, index into nodes

    std::vector<Material> materials;   // always holds at least one (the glTF default)
    std::vector<Image> images;         // linear RGBA
    std::vector<PunctualLight> lights; // KHR_lights_punctual (formats/light.hpp)
    std::vector<GltfLight>
        gltfLights; // one per light when loaded from glTF; empty when built in code
    Environment environment;
    std::vector<SceneNode> nodes; // every node of the chosen scene, in glTF order

    grid::Aabb bounds;       // world bounds of all triangles (empty scene: zero)
    float unitScale = 1.0f;  // metres per file unit applied at load (LoadOptions::scale)
    uint64_t sourceHash = 0; // xxHash64 of the glTF/glb file bytes
    std::string source;      // the file it was loaded from, for messages (may be empty)
    // Every file the load read: the glTF or glb file (loadGltf only), then its buffers and
    // images. Commands refuse an output that is one of them (checkOutputs, file_io.hpp).
    std::vector<std::filesystem::path> files;
    std::vector<std::string> warnings; // non-fatal problems, each naming file and field
    // Light modes (BakeConfig::lights; applied by bake() to its own copy of the scene): whether a
    // probe stores each source's direct light. Per light, 0 = left out (mode indirect: only its
    // bounced light is stored); empty = every light's is stored. Lights in mode none are removed.
    std::vector<uint8_t> lightDirectStored;
    bool emissiveDirectStored = true;
    bool environmentDirectStored = true;
    bool directStored(size_t light) const {
        return lightDirectStored.empty() || lightDirectStored[light] != 0;
    }

    bool hasGeometry() const { return !triangles.empty(); }
    // Linear albedo / emission of triangle `tri` at barycentrics (b1, b2) (Embree's u, v).
    glm::vec3 albedoAt(uint32_t tri, glm::vec2 bary) const;
    glm::vec3 emissionAt(uint32_t tri, glm::vec2 bary) const;
};

// The bytes a scene's arrays have allocated (vertices, triangles and their per-triangle ids,
// image texels, nodes, materials, lights and the environment; the capacity, which loadGltf
// reserves once per primitive): what a bake's memory model charges for the loaded scene. Strings
// and the fixed-size members are left out.
uint64_t sceneBytes(const Scene& scene);

struct LoadOptions {
    std::optional<int> sceneIndex; // glTF scene to load; default: the file's default scene, or 0
    // Metres per file unit: glTF says metres, but exports in centimetres (0.01) and millimetres
    // (0.001) are common. Positions, node transforms, light positions and ranges are scaled;
    // radiance, albedo and light intensities are not (they do not depend on length units).
    float scale = 1.0f;
    // The most memory the load may take, in bytes: the file, the parsed JSON, buffers, decoded
    // images (also at most 8192 x 8192 pixels each) and every accessor the loader expands,
    // predicted from the counts in the file before anything is allocated. The default is the
    // bake's max_memory_mb default; probekit bake passes its max_memory_mb.
    uint64_t maxMemoryBytes = 4ull << 30;
    // Buffer and image URIs are relative paths to regular files under the scene file's folder;
    // these folders (which must exist) are allowed too: a URI's canonical path (`..` and symbolic
    // links resolved) may lie under any of them. Absolute URIs are refused whatever this holds.
    std::vector<std::filesystem::path> assetRoots;
};

// Units: a scene is plausible in metres when its longest side (after the scale) is within
// kPlausibleSceneMinMetres..kPlausibleSceneMaxMetres, or when its storey height (the median
// distance from its floors straight up to the next surface: storeyHeight, scene.cpp) is within
// kPlausibleStoreyMinMetres..kPlausibleStoreyMaxMetres, whatever its extent; loadGltf warns
// otherwise and names the scales, first those that make its storeys plausible. Under
// kPlausibleSceneMinMetres it refuses the scene (checkSceneSize).
constexpr float kPlausibleSceneMaxMetres = 100.0f; // a large building; more is a cm/mm export
constexpr float kPlausibleSceneMinMetres = 0.01f;  // a coin; less bakes wrong
constexpr float kPlausibleStoreyMinMetres = 2.0f;  // a low room or a door
constexpr float kPlausibleStoreyMaxMetres = 6.0f;  // a hall's storey

// Scales the scene's lengths by `scale` (metres per unit, > 0) and records it in unitScale.
void applyUnitScale(Scene& scene, float scale);

// The warning loadGltf gives for a scene whose size is implausible in metres (empty when it is
// plausible by the rule above, or it has no geometry, or it is under 1 cm, which
// checkSceneSize refuses), naming the --scale values that would make it plausible: 0.01,
// 0.0254 and 0.001 over 100 m (those that make its storeys 2..6 m first, each with the size and
// storey height it gives).
std::string implausibleSizeWarning(const Scene& scene, const std::string& file);

// Refuses a scene with geometry whose longest side, after the scale (`scale`, metres per unit,
// named in the message), is under kPlausibleSceneMinMetres: the bake's lengths are in metres
// and such a scene bakes wrong (scene.cpp has the figures). The message gives the size at 1 m
// per unit, or the scale that makes a file in kilometres plausible.
Result<void> checkSceneSize(const Scene& scene, const std::string& file, float scale);

// Loads a .gltf or .glb (embedded or external buffers and images), glTF 2.x only. Triangle
// primitives of every index type and non-indexed ones are loaded; points and lines are skipped
// with a warning; triangles with NaN/inf vertices are skipped with a warning. Fails with a
// message naming the file and field on a missing, non-regular or malformed file, a damaged GLB
// container (naming the byte offset), JSON nested deeper than 512 levels, a field of the wrong
// JSON kind, an unsupported glTF version or required extension, an out-of-range accessor or
// index, a node cycle, a value that overflows a float, a URI outside the allowed folders, more
// memory than options.maxMemoryBytes, or a bad scene index.
Result<Scene> loadGltf(const std::filesystem::path& path, const LoadOptions& options = {});

// The same from bytes already in memory: `name` labels messages, its extension (.glb) and the
// GLB magic choose the container, and its folder is the scene folder that relative URIs
// resolve against. Never crashes, blocks or allocates beyond options.maxMemoryBytes, whatever
// the bytes (fuzzed).
Result<Scene> loadGltfBytes(std::span<const uint8_t> bytes, const std::filesystem::path& name,
                            const LoadOptions& options = {});

} // namespace probekit::baker
