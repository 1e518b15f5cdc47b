// The glTF node graph: the forest check, the scene's roots, local and world transforms, the
// instanced-growth limit, and each node's meshes and light. Part of GltfLoader (gltf_loader.hpp).
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "scene/gltf_loader.hpp"

namespace probekit::baker::gltf {

// glTF nodes form a forest: every node has at most one parent and no node is its own
// ancestor. Checked over all nodes, not only those a scene reaches, since without `scenes`
// the roots are the nodes nobody lists as a child, and a cycle has none of those: it would
// vanish from the scene without a word.
void GltfLoader::checkNodeForest() const {
    const size_t node_count = m_model.nodes.size();
    std::vector<int> parent(node_count, -1);
    for (size_t i = 0; i < node_count; ++i) {
        for (const int child : m_model.nodes[i].children) {
            if (child < 0 || static_cast<size_t>(child) >= node_count) {
                fail(ErrorCode::OutOfRange,
                     "nodes[" + std::to_string(i) + "].children references node " +
                         std::to_string(child) + ", which is out of range (" +
                         std::to_string(node_count) + " nodes)");
            }
            int& p = parent[static_cast<size_t>(child)];
            if (p >= 0) {
                fail(ErrorCode::InvalidArgument,
                     "node " + std::to_string(child) + " is a child of both node " +
                         std::to_string(p) + " and node " + std::to_string(i) +
                         " (glTF nodes form trees: one parent at most)");
            }
            p = static_cast<int>(i);
        }
    }
    // With one parent each, a cycle is a closed chain of parent links. Walk up from every
    // node; meeting a node of the current walk closes a cycle.
    std::vector<uint32_t> walk_of(node_count, 0); // 0: not yet walked
    for (size_t start = 0; start < node_count; ++start) {
        const uint32_t walk = static_cast<uint32_t>(start) + 1;
        int node = static_cast<int>(start);
        while (node >= 0 && walk_of[size_t(node)] == 0) {
            walk_of[size_t(node)] = walk;
            node = parent[size_t(node)];
        }
        if (node < 0 || walk_of[size_t(node)] != walk) {
            continue; // reached a root, or a chain already walked
        }
        // The cycle through `node`, listed from its smallest index in parent -> child order.
        std::vector<int> cycle = {node};
        for (int up = parent[size_t(node)]; up != node; up = parent[size_t(up)]) {
            cycle.push_back(up);
        }
        std::reverse(cycle.begin(), cycle.end());
        std::rotate(cycle.begin(), std::min_element(cycle.begin(), cycle.end()), cycle.end());
        std::string chain;
        for (const int n : cycle) {
            chain += "node " + std::to_string(n) + " -> ";
        }
        fail(ErrorCode::InvalidArgument, "the node hierarchy has a cycle: " + chain + "node " +
                                             std::to_string(cycle.front()) +
                                             " (each listed in the children of the one "
                                             "before)");
    }
}

std::vector<int> GltfLoader::sceneRoots(std::optional<int> requested) {
    const int scene_count = static_cast<int>(m_model.scenes.size());
    if (requested) {
        if (*requested < 0 || *requested >= scene_count) {
            fail(ErrorCode::OutOfRange, "scene index " + std::to_string(*requested) +
                                            " is out of range (the file has " +
                                            std::to_string(scene_count) + " scenes)");
        }
        return m_model.scenes[static_cast<size_t>(*requested)].nodes;
    }
    if (scene_count == 0) {
        // glTF leaves this case to the application; loading every root node is what viewers
        // do and is what a user expects from a file without a scene list.
        warn("the file defines no scenes; loading every root node");
        std::vector<bool> is_child(m_model.nodes.size(), false);
        for (const tinygltf::Node& node : m_model.nodes) {
            for (const int child : node.children) {
                if (child >= 0 && static_cast<size_t>(child) < is_child.size()) {
                    is_child[static_cast<size_t>(child)] = true;
                }
            }
        }
        std::vector<int> roots;
        for (size_t i = 0; i < m_model.nodes.size(); ++i) {
            if (!is_child[i]) {
                roots.push_back(static_cast<int>(i));
            }
        }
        return roots;
    }
    const int index = m_model.defaultScene >= 0 ? m_model.defaultScene : 0;
    if (index >= scene_count) {
        fail(ErrorCode::OutOfRange, "scene " + std::to_string(index) +
                                        " (the default scene) is out of range (the file has " +
                                        std::to_string(scene_count) + " scenes)");
    }
    return m_model.scenes[static_cast<size_t>(index)].nodes;
}

glm::dmat4 GltfLoader::localMatrix(int node_index) const {
    const tinygltf::Node& node = m_model.nodes[static_cast<size_t>(node_index)];
    const std::string field = "nodes[" + std::to_string(node_index) + "]";
    auto checkFinite = [&](const std::vector<double>& values, const char* name) {
        for (const double v : values) {
            if (!std::isfinite(v)) {
                fail(ErrorCode::NonFinite, field + "." + name + " holds a non-finite value");
            }
        }
    };
    if (!node.matrix.empty()) {
        if (node.matrix.size() != 16) {
            fail(ErrorCode::InvalidArgument, field + ".matrix must have 16 values");
        }
        checkFinite(node.matrix, "matrix");
        // glTF matrices are column-major, as glm's are.
        return glm::make_mat4(node.matrix.data());
    }
    glm::dmat4 result(1.0);
    if (!node.translation.empty()) {
        if (node.translation.size() != 3) {
            fail(ErrorCode::InvalidArgument, field + ".translation must have 3 values");
        }
        checkFinite(node.translation, "translation");
        result[3] = glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1.0);
    }
    if (!node.rotation.empty()) {
        if (node.rotation.size() != 4) {
            fail(ErrorCode::InvalidArgument, field + ".rotation must have 4 values");
        }
        checkFinite(node.rotation, "rotation");
        // glTF stores (x, y, z, w); glm's constructor takes w first.
        glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
        const double length = glm::length(q);
        if (length < 1e-8) {
            fail(ErrorCode::InvalidArgument, field + ".rotation is not a unit quaternion");
        }
        // Exporters write quaternions rounded to float; renormalise so the basis stays
        // orthonormal.
        result = result * glm::mat4_cast(q / length);
    }
    if (!node.scale.empty()) {
        if (node.scale.size() != 3) {
            fail(ErrorCode::InvalidArgument, field + ".scale must have 3 values");
        }
        checkFinite(node.scale, "scale");
        result = result * glm::dmat4(glm::dvec4(node.scale[0], 0, 0, 0),
                                     glm::dvec4(0, node.scale[1], 0, 0),
                                     glm::dvec4(0, 0, node.scale[2], 0), glm::dvec4(0, 0, 0, 1));
    }
    return result;
}

// World matrices (parent x local) of every node reachable from `roots`; returns the reachable
// nodes in glTF node order, which is the order of Scene::nodes and of the triangles, so the
// output does not depend on how the hierarchy is drawn. Iterative, so a deep chain of nodes
// cannot overflow the stack.
std::vector<int> GltfLoader::traverse(const std::vector<int>& roots) {
    const size_t node_count = m_model.nodes.size();
    m_world.assign(node_count, glm::dmat4(1.0));
    std::vector<bool> visited(node_count, false);
    std::vector<int> stack;
    auto visit = [&](int index, const glm::dmat4& parent, const std::string& referrer) {
        if (index < 0 || static_cast<size_t>(index) >= node_count) {
            fail(ErrorCode::OutOfRange, referrer + " references node " + std::to_string(index) +
                                            ", which is out of range (" +
                                            std::to_string(node_count) + " nodes)");
        }
        if (visited[static_cast<size_t>(index)]) {
            fail(ErrorCode::InvalidArgument,
                 "node " + std::to_string(index) +
                     " is reached twice (a root listed twice, or a root that is also a "
                     "child)");
        }
        visited[static_cast<size_t>(index)] = true;
        m_world[static_cast<size_t>(index)] = parent * localMatrix(index);
        stack.push_back(index);
    };
    for (const int root : roots) {
        visit(root, glm::dmat4(1.0), "the scene");
    }
    while (!stack.empty()) {
        const int index = stack.back();
        stack.pop_back();
        const tinygltf::Node& node = m_model.nodes[static_cast<size_t>(index)];
        for (const int child : node.children) {
            visit(child, m_world[static_cast<size_t>(index)],
                  "nodes[" + std::to_string(index) + "].children");
        }
    }
    std::vector<int> reachable;
    for (size_t i = 0; i < node_count; ++i) {
        if (visited[i]) {
            reachable.push_back(static_cast<int>(i));
        }
    }
    return reachable;
}

namespace {

// How many of the reachable nodes use each mesh (an index out of range is left to loadNode).
std::vector<uint64_t> meshInstances(const tinygltf::Model& model,
                                    const std::vector<int>& reachable) {
    std::vector<uint64_t> instances(model.meshes.size(), 0);
    for (const int node_index : reachable) {
        const int mesh = model.nodes[static_cast<size_t>(node_index)].mesh;
        if (mesh >= 0 && static_cast<size_t>(mesh) < instances.size()) {
            ++instances[static_cast<size_t>(mesh)];
        }
    }
    return instances;
}

} // namespace

// Every node that uses a mesh adds a transformed copy of its triangles to the scene, so a
// small file can name one large (or sparse, zero-backed) accessor from many nodes. The
// per-primitive checks in loadPrimitive catch that only once the first copies exist (a 1.3
// KB file with a 2^24-vertex sparse accessor under 21 nodes held 1.9 GB, 12 s in, before
// its refusal). This sums the scene arrays every instance will add, from the accessor
// counts alone, and refuses before the first is built. It is a lower bound of what loading
// charges (the per-primitive work arrays come on top), so it never refuses a scene the
// per-primitive checks would take; malformed accessors and meshes are left to those checks,
// which name the precise field. What it admits is reserved at once (below), so the arrays
// never grow past it.
void GltfLoader::checkInstancedGrowth(const std::vector<int>& reachable) {
    constexpr uint64_t kVertexBytes = sizeof(glm::vec3) + sizeof(glm::vec2) + sizeof(glm::vec3);
    constexpr uint64_t kTriangleBytes = sizeof(glm::uvec3) + sizeof(uint32_t) + sizeof(int32_t);
    // An accessor's count, when it is plausible: backed by nothing (zeros and sparse
    // values, the amplifying case), or fitting its buffer view. A count its view cannot
    // hold is left to readAccessor, whose error names the accessor and the view.
    const auto count_of = [&](int index) -> uint64_t {
        if (index < 0 || static_cast<size_t>(index) >= m_model.accessors.size()) {
            return 0;
        }
        const tinygltf::Accessor& accessor = m_model.accessors[static_cast<size_t>(index)];
        if (accessor.bufferView < 0) {
            return accessor.count;
        }
        if (static_cast<size_t>(accessor.bufferView) >= m_model.bufferViews.size()) {
            return 0;
        }
        const uint64_t element =
            componentSize(accessor.componentType) * componentCount(accessor.type);
        const uint64_t view =
            m_model.bufferViews[static_cast<size_t>(accessor.bufferView)].byteLength;
        return element > 0 && accessor.count <= view / element ? accessor.count : 0;
    };
    const std::vector<uint64_t> instances = meshInstances(m_model, reachable);
    // Counts x instances can pass 2^64 in a forged file: sum in long double, print clamped.
    long double total = 0.0L;
    long double vertices = 0.0L;
    long double triangles = 0.0L;
    size_t largest = 0;
    long double largest_bytes = -1.0L;
    for (size_t m = 0; m < instances.size(); ++m) {
        const auto copies = static_cast<long double>(instances[m]);
        long double mesh_bytes = 0.0L;
        for (const tinygltf::Primitive& primitive : m_model.meshes[m].primitives) {
            const auto position = primitive.attributes.find("POSITION");
            if (primitive.mode < TINYGLTF_MODE_TRIANGLES ||
                position == primitive.attributes.end()) {
                continue;
            }
            const uint64_t v = count_of(position->second);
            const uint64_t n = primitive.indices >= 0 ? count_of(primitive.indices) : v;
            const uint64_t t =
                primitive.mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : (n < 2 ? 0 : n - 2);
            mesh_bytes +=
                copies * ((long double)(v)*kVertexBytes + (long double)(t)*kTriangleBytes);
            vertices += copies * (long double)(v);
            triangles += copies * (long double)(t);
        }
        total += mesh_bytes;
        if (mesh_bytes > largest_bytes) {
            largest_bytes = mesh_bytes;
            largest = m;
        }
    }
    const auto clamped = [](long double x) {
        return x >= 1.8e19L ? UINT64_MAX : static_cast<uint64_t>(x);
    };
    const uint64_t bytes = clamped(total);
    if (bytes > 0 && !m_budget.fits(bytes)) {
        fail(ErrorCode::OutOfRange,
             m_budget.refusal("adding every mesh instance to the scene (" +
                                  std::to_string(clamped(vertices)) + " vertices and " +
                                  std::to_string(clamped(triangles)) +
                                  " triangles; the most from meshes[" + std::to_string(largest) +
                                  "]" + quoted(m_model.meshes[largest].name) + ", used by " +
                                  std::to_string(instances[largest]) +
                                  (instances[largest] == 1 ? " node)" : " nodes)"),
                              bytes));
    }
    // The arrays are reserved once, at the size just charged: grown instance by instance
    // they would double past it (and hold old and new storage while they move), so a scene
    // the sum admits could still be refused gigabytes later. The per-primitive growth then
    // finds the room already there.
    growScene(clamped(vertices), clamped(triangles));
}

void GltfLoader::loadNode(int node_index) {
    const tinygltf::Node& node = m_model.nodes[static_cast<size_t>(node_index)];
    const glm::dmat4& world = m_world[static_cast<size_t>(node_index)];
    const int32_t scene_node = static_cast<int32_t>(m_scene.nodes.size());
    SceneNode out;
    out.name = node.name;
    out.gltfIndex = node_index;
    out.world = glm::mat4(world);
    out.hasMesh = node.mesh >= 0;
    m_scene.nodes.push_back(out);
    m_node_has_triangles.push_back(false);

    if (node.mesh >= 0) {
        if (static_cast<size_t>(node.mesh) >= m_model.meshes.size()) {
            fail(ErrorCode::OutOfRange, "nodes[" + std::to_string(node_index) + "].mesh " +
                                            std::to_string(node.mesh) + " is out of range (" +
                                            std::to_string(m_model.meshes.size()) + " meshes)");
        }
        if (node.skin >= 0) {
            warn("nodes[" + std::to_string(node_index) +
                 "] is skinned; its mesh is loaded unskinned (bind pose)");
        }
        BoundsBuilder local_bounds;
        BoundsBuilder world_bounds;
        const tinygltf::Mesh& mesh = m_model.meshes[static_cast<size_t>(node.mesh)];
        for (size_t p = 0; p < mesh.primitives.size(); ++p) {
            loadPrimitive(node.mesh, static_cast<int>(p), world, scene_node, local_bounds,
                          world_bounds);
        }
        m_scene.nodes.back().localBounds = local_bounds.box();
        m_scene.nodes.back().worldBounds = world_bounds.box();
        m_node_has_triangles.back() = !world_bounds.empty;
    }

    if (const auto it = node.extensions.find("KHR_lights_punctual"); it != node.extensions.end()) {
        loadLight(node_index, it->second, world);
    }
}

} // namespace probekit::baker::gltf
