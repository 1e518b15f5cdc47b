// glTF mesh primitives -> the Scene's triangles: modes, vertex attributes, indices, strips and
// fans, the transform to world space, and the budgeted growth of the Scene's arrays. Part of
// GltfLoader (gltf_loader.hpp).
#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "scene/gltf_loader.hpp"

namespace probekit::baker::gltf {

namespace {

const char* modeName(int mode) {
    switch (mode) {
    case TINYGLTF_MODE_POINTS:
        return "POINTS";
    case TINYGLTF_MODE_LINE:
        return "LINES";
    case TINYGLTF_MODE_LINE_LOOP:
        return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP:
        return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES:
        return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP:
        return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN:
        return "TRIANGLE_FAN";
    default:
        return "unknown";
    }
}

// A glTF NORMAL (three floats) in world space, unit length; zero when it is not finite or
// vanishes (the renderer then falls back to the face normal). Divided by its largest component
// before its length is taken, so that the squares in the length neither underflow (denormal
// components) nor overflow (1e38 through a node's inverse scale) and any non-zero finite
// normal keeps its direction.
glm::vec3 worldNormal(const glm::dmat3& normal_matrix, const float* n) {
    const glm::dvec3 w = normal_matrix * glm::dvec3(n[0], n[1], n[2]);
    const double largest = std::max({std::abs(w.x), std::abs(w.y), std::abs(w.z)});
    if (!isFinite(w) || !(largest > 0.0)) {
        return glm::vec3(0.0f);
    }
    const glm::dvec3 scaled = w / largest;
    return glm::vec3(scaled / glm::length(scaled));
}

} // namespace

// A float vertex attribute of `components` per vertex, empty when the primitive has none;
// its count must match POSITION's.
std::vector<float> GltfLoader::vertexAttribute(const tinygltf::Primitive& primitive,
                                               const char* name, int type, size_t components,
                                               size_t vertex_count,
                                               const std::string& field) const {
    const auto it = primitive.attributes.find(name);
    if (it == primitive.attributes.end()) {
        return {};
    }
    std::vector<float> values = readAccessor<float>(it->second, type, false, field + " " + name);
    if (values.size() / components != vertex_count) {
        fail(ErrorCode::InconsistentSize,
             field + ": " + name + " (accessor " + std::to_string(it->second) + ") has " +
                 std::to_string(values.size() / components) + " elements, POSITION has " +
                 std::to_string(vertex_count));
    }
    return values;
}

void GltfLoader::loadPrimitive(int mesh_index, int primitive_index, const glm::dmat4& world,
                               int32_t scene_node, BoundsBuilder& local_bounds,
                               BoundsBuilder& world_bounds) {
    const tinygltf::Mesh& mesh = m_model.meshes[static_cast<size_t>(mesh_index)];
    const tinygltf::Primitive& primitive = mesh.primitives[static_cast<size_t>(primitive_index)];
    const std::string field = "meshes[" + std::to_string(mesh_index) + "]" + quoted(mesh.name) +
                              ".primitives[" + std::to_string(primitive_index) + "]";
    const int mode = primitive.mode;
    if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_TRIANGLE_FAN) {
        fail(ErrorCode::BadEnum, field + ".mode " + std::to_string(mode) +
                                     " is not a glTF "
                                     "primitive mode");
    }
    if (mode < TINYGLTF_MODE_TRIANGLES) {
        warn(field + ": mode " + modeName(mode) + " has no surface; the primitive is skipped");
        return;
    }
    if (primitive.attributes.find("POSITION") == primitive.attributes.end()) {
        warn(field + " has no POSITION attribute; the primitive is skipped");
        return;
    }
    const uint32_t material_index = primitiveMaterial(primitive, field);
    if (primitive.extensions.count("KHR_draco_mesh_compression")) {
        // gltf_input.cpp has checked that the uncompressed fallback exists.
        warn(field + " is compressed with KHR_draco_mesh_compression, which probekit does not "
                     "decode; its uncompressed accessors are loaded instead");
    }

    // Every array below is charged to the budget while it lives (readAccessor checks each
    // before allocating it); the Scene's growth stays charged.
    HeldBytes held{m_budget};
    const PrimitiveArrays arrays = readPrimitiveArrays(primitive, field, held);
    const std::vector<uint32_t> indices = primitiveIndices(primitive, arrays.vertexCount(), field);
    held.add(indices.size() * sizeof(uint32_t));
    reserveTriangles(mode, indices.size(), arrays.vertexCount(), field, held);
    const std::vector<glm::uvec3> corners = triangleCorners(mode, indices, field);
    appendTriangles(arrays, corners, world, material_index, scene_node, field, local_bounds,
                    world_bounds);
}

// The scene material of a primitive: glTF's index, or the default material when it has none.
uint32_t GltfLoader::primitiveMaterial(const tinygltf::Primitive& primitive,
                                       const std::string& field) {
    if (primitive.material < 0) {
        return defaultMaterial();
    }
    if (static_cast<size_t>(primitive.material) >= m_model.materials.size()) {
        fail(ErrorCode::OutOfRange, field + ".material " + std::to_string(primitive.material) +
                                        " is out of range (" +
                                        std::to_string(m_model.materials.size()) + " materials)");
    }
    // loadMaterials keeps glTF's material order, so the indices coincide.
    return static_cast<uint32_t>(primitive.material);
}

// POSITION, TEXCOORD_0 and NORMAL, each charged to `held` once read.
GltfLoader::PrimitiveArrays GltfLoader::readPrimitiveArrays(const tinygltf::Primitive& primitive,
                                                            const std::string& field,
                                                            HeldBytes& held) {
    PrimitiveArrays arrays;
    arrays.positions = readAccessor<float>(primitive.attributes.at("POSITION"), TINYGLTF_TYPE_VEC3,
                                           false, field + " POSITION");
    held.add(arrays.positions.size() * sizeof(float));
    const size_t vertex_count = arrays.vertexCount();
    arrays.uvs =
        vertexAttribute(primitive, "TEXCOORD_0", TINYGLTF_TYPE_VEC2, 2, vertex_count, field);
    held.add(arrays.uvs.size() * sizeof(float));
    // Vertex normals (the renderer's smooth shading; light transport uses face normals).
    arrays.normals =
        vertexAttribute(primitive, "NORMAL", TINYGLTF_TYPE_VEC3, 3, vertex_count, field);
    held.add(arrays.normals.size() * sizeof(float));
    return arrays;
}

// The primitive's indices, each checked against the vertex count; 0..n-1 when it has none.
std::vector<uint32_t> GltfLoader::primitiveIndices(const tinygltf::Primitive& primitive,
                                                   size_t vertex_count, const std::string& field) {
    std::vector<uint32_t> indices;
    if (primitive.indices >= 0) {
        indices = readAccessor<uint32_t>(primitive.indices, TINYGLTF_TYPE_SCALAR, true,
                                         field + " indices");
        for (const uint32_t index : indices) {
            if (index >= vertex_count) {
                fail(ErrorCode::OutOfRange,
                     field + ": accessors[" + std::to_string(primitive.indices) +
                         "] (indices) holds index " + std::to_string(index) +
                         ", but POSITION has " + std::to_string(vertex_count) + " vertices");
            }
        }
        return indices;
    }
    if (vertex_count > std::numeric_limits<uint32_t>::max()) {
        fail(ErrorCode::OutOfRange, field + ": too many vertices");
    }
    if (!m_budget.fits(vertex_count * sizeof(uint32_t))) {
        fail(ErrorCode::OutOfRange, m_budget.refusal(field + " (" + std::to_string(vertex_count) +
                                                         " vertices, listed as indices)",
                                                     vertex_count * sizeof(uint32_t)));
    }
    indices.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) {
        indices[i] = static_cast<uint32_t>(i);
    }
    return indices;
}

// Charges the rest, predicted from the counts (corners and the per-vertex work arrays while
// they live, and the Scene's arrays grown for at most every vertex and triangle), and grows
// the Scene; refuses before allocating when it does not fit.
void GltfLoader::reserveTriangles(int mode, size_t n, size_t vertex_count, const std::string& field,
                                  HeldBytes& held) {
    const uint64_t triangle_count = mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : n < 2 ? 0 : n - 2;
    const uint64_t work = triangle_count * sizeof(glm::uvec3) +
                          vertex_count * (sizeof(glm::vec3) + sizeof(uint32_t)) + vertex_count / 8 +
                          1;
    const uint64_t growth = sceneGrowth(vertex_count, triangle_count);
    if (!m_budget.fits(work + growth)) {
        fail(ErrorCode::OutOfRange,
             m_budget.refusal(field + " (" + std::to_string(vertex_count) + " vertices, " +
                                  std::to_string(triangle_count) +
                                  " triangles, expanded and added to the scene)",
                              work + growth));
    }
    held.add(work);
    growScene(vertex_count, triangle_count);
}

// Triangle corners, following the glTF 2.0 specification's definitions of strips (odd
// triangles swap their first two corners to keep the winding) and fans.
std::vector<glm::uvec3> GltfLoader::triangleCorners(int mode, const std::vector<uint32_t>& indices,
                                                    const std::string& field) {
    const size_t n = indices.size();
    std::vector<glm::uvec3> corners;
    corners.reserve(mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : n < 2 ? 0 : n - 2);
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (n % 3 != 0) {
            warn(field + ": " + std::to_string(n) +
                 " vertices/indices is not a multiple of 3; "
                 "the last " +
                 std::to_string(n % 3) + " are ignored");
        }
        for (size_t i = 0; i + 2 < n; i += 3) {
            corners.emplace_back(indices[i], indices[i + 1], indices[i + 2]);
        }
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 0; i + 2 < n; ++i) {
            const size_t odd = i % 2;
            corners.emplace_back(indices[i], indices[i + 1 + odd], indices[i + 2 - odd]);
        }
    } else {
        for (size_t i = 1; i + 1 < n; ++i) {
            corners.emplace_back(indices[i], indices[i + 1], indices[0]);
        }
    }
    return corners;
}

// Adds the triangles to the Scene. Every vertex is transformed once; only those used by a
// kept triangle are remapped to scene vertices, so no non-finite or unused vertex reaches it.
void GltfLoader::appendTriangles(const PrimitiveArrays& arrays,
                                 const std::vector<glm::uvec3>& corners, const glm::dmat4& world,
                                 uint32_t material_index, int32_t scene_node,
                                 const std::string& field, BoundsBuilder& local_bounds,
                                 BoundsBuilder& world_bounds) {
    const std::vector<float>& positions = arrays.positions;
    const std::vector<float>& uvs = arrays.uvs;
    const std::vector<float>& normals = arrays.normals;
    const size_t vertex_count = arrays.vertexCount();
    // Normals transform by the inverse transpose of the node's matrix.
    const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(world)));
    std::vector<glm::vec3> world_positions(vertex_count);
    std::vector<bool> finite(vertex_count);
    for (size_t v = 0; v < vertex_count; ++v) {
        const glm::dvec3 local(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
        const glm::dvec3 transformed = glm::dvec3(world * glm::dvec4(local, 1.0));
        world_positions[v] = glm::vec3(transformed);
        finite[v] = isFinite(local) && isFinite(glm::dvec3(world_positions[v])) &&
                    (uvs.empty() || (std::isfinite(uvs[2 * v]) && std::isfinite(uvs[2 * v + 1])));
    }
    constexpr uint32_t kUnused = std::numeric_limits<uint32_t>::max();
    std::vector<uint32_t> remap(vertex_count, kUnused);
    size_t skipped = 0;
    for (const glm::uvec3& tri : corners) {
        if (!finite[tri.x] || !finite[tri.y] || !finite[tri.z]) {
            ++skipped;
            continue;
        }
        glm::uvec3 out;
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = tri[k];
            if (remap[v] == kUnused) {
                if (m_scene.positions.size() >= kUnused) {
                    fail(ErrorCode::OutOfRange, field + ": the scene exceeds 2^32 vertices");
                }
                remap[v] = static_cast<uint32_t>(m_scene.positions.size());
                m_scene.positions.push_back(world_positions[v]);
                m_scene.uvs.push_back(uvs.empty() ? glm::vec2(0.0f)
                                                  : glm::vec2(uvs[2 * v], uvs[2 * v + 1]));
                m_scene.normals.push_back(normals.empty()
                                              ? glm::vec3(0.0f)
                                              : worldNormal(normal_matrix, normals.data() + 3 * v));
                local_bounds.add(
                    glm::vec3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]));
                world_bounds.add(world_positions[v]);
            }
            out[k] = remap[v];
        }
        m_scene.triangles.push_back(out);
        m_scene.triangleMaterial.push_back(material_index);
        m_scene.triangleNode.push_back(scene_node);
    }
    if (skipped > 0) {
        warn(field + ": " + std::to_string(skipped) +
             " triangles with a non-finite (NaN or infinite) vertex position or uv skipped");
    }
}

// The Scene's arrays grow as std::vector's do (to at least twice their capacity), but once
// per primitive and predicted: the new storage must fit while the old still lives, and stays
// charged to the budget.
template <class T>
uint64_t GltfLoader::grownCapacity(const std::vector<T>& v, uint64_t more) {
    return v.size() + more <= v.capacity()
               ? v.capacity()
               : std::max<uint64_t>(v.size() + more, 2 * uint64_t(v.capacity()));
}
template <class T>
uint64_t GltfLoader::growthBytes(const std::vector<T>& v, uint64_t more) {
    const uint64_t capacity = grownCapacity(v, more);
    return capacity == v.capacity() ? 0 : capacity * sizeof(T);
}
uint64_t GltfLoader::sceneGrowth(uint64_t vertices, uint64_t triangles) const {
    return growthBytes(m_scene.positions, vertices) + growthBytes(m_scene.uvs, vertices) +
           growthBytes(m_scene.normals, vertices) + growthBytes(m_scene.triangles, triangles) +
           growthBytes(m_scene.triangleMaterial, triangles) +
           growthBytes(m_scene.triangleNode, triangles);
}
template <class T>
void GltfLoader::grow(std::vector<T>& v, uint64_t more) {
    const uint64_t before = v.capacity() * sizeof(T);
    v.reserve(grownCapacity(v, more));
    m_budget.add(v.capacity() * sizeof(T));
    m_budget.release(before);
}
void GltfLoader::growScene(uint64_t vertices, uint64_t triangles) {
    grow(m_scene.positions, vertices);
    grow(m_scene.uvs, vertices);
    grow(m_scene.normals, vertices);
    grow(m_scene.triangles, triangles);
    grow(m_scene.triangleMaterial, triangles);
    grow(m_scene.triangleNode, triangles);
}

} // namespace probekit::baker::gltf
