// The glTF loader's one class, GltfLoader, shared by the files that implement it, one job each
// (private to baker/src/scene/gltf_*.cpp):
//   gltf_loader.cpp      the entry points (loadGltf, loadGltfBytes) and GltfLoader::load
//   gltf_materials.cpp   materials, textures and their images
//   gltf_nodes.cpp       the node graph: forest check, scene roots, transforms, instancing limits
//   gltf_accessors.cpp   accessors: byte ranges, component decoding, sparse substitution
//   gltf_primitives.cpp  mesh primitives: triangles, vertex attributes, the Scene's growth
//   gltf_lights.cpp      KHR_lights_punctual
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/common.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <tiny_gltf.h>

#include "probekit/baker/scene.hpp"
#include "scene/gltf_input.hpp"

namespace probekit::baker::gltf {

inline std::string quoted(const std::string& name) {
    return name.empty() ? std::string() : " ('" + name + "')";
}

// Bytes of one accessor component (0 for a type glTF 2.0 does not allow) and components per
// element (0 for matrices); gltf_accessors.cpp.
size_t componentSize(int component_type);
size_t componentCount(int type);

inline bool isFinite(glm::dvec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

struct BoundsBuilder {
    glm::vec3 min{std::numeric_limits<float>::max()};
    glm::vec3 max{std::numeric_limits<float>::lowest()};
    bool empty = true;

    void add(glm::vec3 p) {
        min = glm::min(min, p);
        max = glm::max(max, p);
        empty = false;
    }
    void add(const grid::Aabb& box) {
        add(box.min);
        add(box.max);
    }
    // A zero box when nothing was added: the documented "no geometry" value.
    grid::Aabb box() const { return empty ? grid::Aabb{} : grid::Aabb{min, max}; }
};

class GltfLoader {
public:
    GltfLoader(const tinygltf::Model& model, std::string file, MemoryBudget& budget)
        : m_model(model), m_file(std::move(file)), m_budget(budget),
          m_image_slots(model.images.size(), -1) {}

    Scene load(std::optional<int> scene_index, uint64_t source_hash,
               const std::string& tinygltf_warnings);

private:
    [[noreturn]] void fail(ErrorCode code, const std::string& what) const {
        throw LoadError{code, m_file + ": " + what};
    }
    void warn(const std::string& what) { m_scene.warnings.push_back(m_file + ": " + what); }

    // ---- materials and textures (gltf_materials.cpp) ----
    uint32_t defaultMaterial();
    void loadMaterials();
    int loadTexture(const tinygltf::TextureInfo& info, const std::string& field);
    int decodeImage(int gltf_index);

    // ---- node graph (gltf_nodes.cpp) ----
    void checkNodeForest() const;
    std::vector<int> sceneRoots(std::optional<int> requested);
    glm::dmat4 localMatrix(int node_index) const;
    std::vector<int> traverse(const std::vector<int>& roots);
    void checkInstancedGrowth(const std::vector<int>& reachable);
    void loadNode(int node_index);

    // ---- accessors (gltf_accessors.cpp) ----
    template <class T>
    std::vector<T> readAccessor(int index, int expected_type, bool indices,
                                const std::string& usage) const;
    const tinygltf::Accessor& checkedAccessor(int index, int expected_type, bool indices,
                                              const std::string& field) const;
    template <class T>
    void checkExpansion(size_t count, size_t components, const std::string& field) const;
    template <class T>
    std::vector<T> readViewElements(const tinygltf::Accessor& accessor, size_t components,
                                    size_t component_size, const std::string& field) const;
    template <class T>
    std::vector<T> zeroElements(const tinygltf::Accessor& accessor, size_t components,
                                const std::string& field) const;
    void applySparse(const tinygltf::Accessor& accessor, const std::string& field,
                     size_t components, size_t component_size, auto& out) const;
    std::span<const uint8_t> bufferViewBytes(int view_index, const std::string& field) const;
    void checkRange(size_t available, size_t offset, size_t count, size_t stride,
                    size_t element_size, const std::string& field) const;

    // ---- primitives (gltf_primitives.cpp) ----

    // Bytes charged to the loader's budget while a primitive's work arrays live.
    struct HeldBytes {
        MemoryBudget& budget;
        uint64_t bytes = 0;
        explicit HeldBytes(MemoryBudget& b) : budget(b) {}
        void add(uint64_t n) {
            budget.add(n);
            bytes += n;
        }
        HeldBytes(const HeldBytes&) = delete;
        HeldBytes& operator=(const HeldBytes&) = delete;
        ~HeldBytes() { budget.release(bytes); }
    };

    // A primitive's vertex arrays as read from its accessors (uvs and normals may be empty).
    struct PrimitiveArrays {
        std::vector<float> positions;
        std::vector<float> uvs;
        std::vector<float> normals;
        size_t vertexCount() const { return positions.size() / 3; }
    };

    std::vector<float> vertexAttribute(const tinygltf::Primitive& primitive, const char* name,
                                       int type, size_t components, size_t vertex_count,
                                       const std::string& field) const;
    void loadPrimitive(int mesh_index, int primitive_index, const glm::dmat4& world,
                       int32_t scene_node, BoundsBuilder& local_bounds,
                       BoundsBuilder& world_bounds);
    uint32_t primitiveMaterial(const tinygltf::Primitive& primitive, const std::string& field);
    PrimitiveArrays readPrimitiveArrays(const tinygltf::Primitive& primitive,
                                        const std::string& field, HeldBytes& held);
    std::vector<uint32_t> primitiveIndices(const tinygltf::Primitive& primitive,
                                           size_t vertex_count, const std::string& field);
    void reserveTriangles(int mode, size_t n, size_t vertex_count, const std::string& field,
                          HeldBytes& held);
    std::vector<glm::uvec3> triangleCorners(int mode, const std::vector<uint32_t>& indices,
                                            const std::string& field);
    void appendTriangles(const PrimitiveArrays& arrays, const std::vector<glm::uvec3>& corners,
                         const glm::dmat4& world, uint32_t material_index, int32_t scene_node,
                         const std::string& field, BoundsBuilder& local_bounds,
                         BoundsBuilder& world_bounds);
    template <class T>
    static uint64_t grownCapacity(const std::vector<T>& v, uint64_t more);
    template <class T>
    static uint64_t growthBytes(const std::vector<T>& v, uint64_t more);
    uint64_t sceneGrowth(uint64_t vertices, uint64_t triangles) const;
    template <class T>
    void grow(std::vector<T>& v, uint64_t more);
    void growScene(uint64_t vertices, uint64_t triangles);

    // ---- KHR_lights_punctual (gltf_lights.cpp) ----
    void loadLight(int node_index, const tinygltf::Value& extension, const glm::dmat4& world);
    LightType lightType(const tinygltf::Light& source, const std::string& field) const;
    glm::dvec3 lightColour(const tinygltf::Light& source, const std::string& field) const;
    void setLightStrength(PunctualLight& light, glm::dvec3 colour, const tinygltf::Light& source,
                          const std::string& field) const;
    void setSpotCones(PunctualLight& light, const tinygltf::Light& source,
                      const std::string& field) const;
    bool placeLight(PunctualLight& light, const glm::dmat4& world, const std::string& node_field,
                    int light_index);

    const tinygltf::Model& m_model;
    std::string m_file;
    MemoryBudget& m_budget;
    Scene m_scene;
    std::vector<int> m_image_slots;         // glTF image -> Scene::images index, -1 until decoded
    std::vector<glm::dmat4> m_world;        // per glTF node, valid for reachable nodes
    std::vector<bool> m_node_has_triangles; // per Scene::nodes entry
    int m_default_material = -1;
};

} // namespace probekit::baker::gltf
