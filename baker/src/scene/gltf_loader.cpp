// glTF 2.0 (.gltf / .glb) -> probekit::baker::Scene, through tinygltf.
//
// Before tinygltf sees the file, gltf_input.cpp checks the GLB container, the JSON's nesting
// depth and the kinds of the fields read here, the glTF version and the required extensions,
// and gltf_io.cpp's callbacks hold every buffer and image read to the scene's folder and the
// memory budget. tinygltf then parses the JSON, resolves buffers (data: URIs, external files, the
// GLB BIN chunk) and decodes images with its stb_image loader (PNG/JPEG come back as 8- or 16-bit
// RGBA). Everything tinygltf does not check (accessor ranges, strides, index values, node graphs,
// light and material values, the bytes each accessor expands to) is checked here, so a malformed
// file gives an error naming the file and the field, never a crash.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <span>
#include <sstream>
#include <string_view>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>
#include <tiny_gltf.h>

#include "probekit/baker/scene.hpp"
#include "probekit/formats/pvol.hpp"
#include "scene/gltf_input.hpp"

namespace probekit::baker {
namespace {

// Largest accessor without a bufferView (all zeros until sparse values apply) that we allocate;
// 2^24 elements is far beyond any real sparse accessor.
constexpr size_t kMaxUnbackedElements = size_t(1) << 24;

using gltf::LoadError;
using gltf::MemoryBudget;
using gltf::numberText;

std::string trimmed(std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' ')) {
        text.pop_back();
    }
    return text;
}

std::string quoted(const std::string& name) {
    return name.empty() ? std::string() : " ('" + name + "')";
}

// The exact sRGB EOTF (IEC 61966-2-1), not a gamma-2.2 approximation: glTF defines base colour
// and emissive textures as sRGB-encoded.
double srgbToLinear(double encoded) {
    return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

size_t componentSize(int component_type) {
    switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
        return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
        return 4;
    default:
        return 0; // INT and DOUBLE are not glTF 2.0 accessor component types
    }
}

size_t componentCount(int type) {
    switch (type) {
    case TINYGLTF_TYPE_SCALAR:
        return 1;
    case TINYGLTF_TYPE_VEC2:
        return 2;
    case TINYGLTF_TYPE_VEC3:
        return 3;
    case TINYGLTF_TYPE_VEC4:
        return 4;
    default:
        return 0; // matrices are never vertex or index data here
    }
}

const char* typeName(int type) {
    switch (type) {
    case TINYGLTF_TYPE_SCALAR:
        return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
        return "VEC2";
    case TINYGLTF_TYPE_VEC3:
        return "VEC3";
    case TINYGLTF_TYPE_VEC4:
        return "VEC4";
    default:
        return "a matrix type";
    }
}

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

// One component as a double (exact for every integer type). Normalized integers follow the
// glTF 2.0 dequantisation rules (signed: max(c / (2^(n-1) - 1), -1)). Values are read
// little-endian through memcpy, which is also what makes unaligned offsets legal.
double readComponent(const uint8_t* p, int component_type, bool normalized) {
    switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
        int8_t v;
        std::memcpy(&v, p, sizeof(v));
        return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
        uint8_t v;
        std::memcpy(&v, p, sizeof(v));
        return normalized ? v / 255.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t v;
        std::memcpy(&v, p, sizeof(v));
        return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t v;
        std::memcpy(&v, p, sizeof(v));
        return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        uint32_t v;
        std::memcpy(&v, p, sizeof(v));
        return normalized ? v / 4294967295.0 : v;
    }
    default: {
        float v;
        std::memcpy(&v, p, sizeof(v));
        return v;
    }
    }
}

bool isFinite(glm::dvec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// A glTF NORMAL (three floats) in world space, unit length; zero when it is not finite or
// vanishes (the renderer then falls back to the face normal).
glm::vec3 worldNormal(const glm::dmat3& normal_matrix, const float* n) {
    const glm::dvec3 w = normal_matrix * glm::dvec3(n[0], n[1], n[2]);
    const double length = glm::length(w);
    return isFinite(w) && length > 0.0 ? glm::vec3(w / length) : glm::vec3(0.0f);
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
               const std::string& tinygltf_warnings) {
        m_scene.sourceHash = source_hash;
        m_scene.source = m_file;
        std::istringstream lines(tinygltf_warnings);
        for (std::string line; std::getline(lines, line);) {
            if (!trimmed(line).empty()) {
                warn("tinygltf: " + trimmed(line));
            }
        }
        loadMaterials();
        checkNodeForest();
        const std::vector<int> roots = sceneRoots(scene_index);
        const std::vector<int> reachable = traverse(roots);
        checkInstancedGrowth(reachable);
        for (const int node_index : reachable) {
            loadNode(node_index);
        }
        BoundsBuilder scene_bounds;
        for (size_t i = 0; i < m_scene.nodes.size(); ++i) {
            if (m_node_has_triangles[i]) {
                scene_bounds.add(m_scene.nodes[i].worldBounds);
            }
        }
        m_scene.bounds = scene_bounds.box();
        if (m_scene.materials.empty()) {
            defaultMaterial();
        }
        return std::move(m_scene);
    }

private:
    [[noreturn]] void fail(ErrorCode code, const std::string& what) const {
        throw LoadError{code, m_file + ": " + what};
    }
    void warn(const std::string& what) { m_scene.warnings.push_back(m_file + ": " + what); }

    // ---- materials and textures ----

    uint32_t defaultMaterial() {
        if (m_default_material < 0) {
            // glTF's default material: base colour 1, no emission.
            Material material;
            material.name = "(glTF default material)";
            m_default_material = static_cast<int>(m_scene.materials.size());
            m_scene.materials.push_back(material);
        }
        return static_cast<uint32_t>(m_default_material);
    }

    void loadMaterials() {
        for (size_t i = 0; i < m_model.materials.size(); ++i) {
            const tinygltf::Material& source = m_model.materials[i];
            const std::string field = "materials[" + std::to_string(i) + "]" + quoted(source.name);
            Material material;
            material.name = source.name;

            const std::vector<double>& base = source.pbrMetallicRoughness.baseColorFactor;
            if (base.size() != 4) {
                fail(ErrorCode::InvalidArgument,
                     field + ".pbrMetallicRoughness.baseColorFactor " + "must have 4 components");
            }
            for (int c = 0; c < 3; ++c) {
                if (!std::isfinite(base[c]) || base[c] < 0.0) {
                    fail(ErrorCode::OutOfRange,
                         field + ".pbrMetallicRoughness.baseColorFactor must be finite and >= 0");
                }
                if (base[c] > 1.0) {
                    // An albedo above 1 creates energy; glTF caps the factor at 1 anyway.
                    warn(field + ".pbrMetallicRoughness.baseColorFactor[" + std::to_string(c) +
                         "] = " + std::to_string(base[c]) + " is above 1; clamped to 1");
                }
                material.baseColor[c] = static_cast<float>(std::min(base[c], 1.0));
            }

            double strength = 1.0;
            if (const auto it = source.extensions.find("KHR_materials_emissive_strength");
                it != source.extensions.end() && it->second.Has("emissiveStrength")) {
                const tinygltf::Value& value = it->second.Get("emissiveStrength");
                if (!value.IsNumber() || !std::isfinite(value.GetNumberAsDouble()) ||
                    value.GetNumberAsDouble() < 0.0) {
                    fail(ErrorCode::OutOfRange, field + ".extensions.KHR_materials_emissive_"
                                                        "strength.emissiveStrength must be a "
                                                        "finite number >= 0");
                }
                strength = value.GetNumberAsDouble();
            }
            const std::vector<double>& emissive = source.emissiveFactor;
            if (emissive.size() != 3) {
                fail(ErrorCode::InvalidArgument, field + ".emissiveFactor must have 3 components");
            }
            for (int c = 0; c < 3; ++c) {
                if (!std::isfinite(emissive[c]) || emissive[c] < 0.0) {
                    fail(ErrorCode::OutOfRange, field + ".emissiveFactor must be finite and >= 0");
                }
                material.emission[c] = static_cast<float>(emissive[c] * strength);
                if (std::isfinite(material.emission[c]) && emissive[c] * strength > kMaxEmission) {
                    fail(ErrorCode::OutOfRange,
                         field + ".emissiveFactor[" + std::to_string(c) + "] " +
                             numberText(emissive[c]) +
                             " x KHR_materials_emissive_strength.emissiveStrength " +
                             numberText(strength) + " is above " + numberText(kMaxEmission) +
                             " W/(sr m^2), the brightest emission probekit bakes");
                }
                if (!std::isfinite(material.emission[c])) {
                    fail(ErrorCode::NonFinite,
                         field + ".emissiveFactor[" + std::to_string(c) + "] " +
                             numberText(emissive[c]) +
                             " x KHR_materials_emissive_strength.emissiveStrength " +
                             numberText(strength) + " overflows a 32-bit float");
                }
            }

            material.baseColorTexCoord = source.pbrMetallicRoughness.baseColorTexture.texCoord;
            material.baseColorTexture =
                loadTexture(source.pbrMetallicRoughness.baseColorTexture,
                            field + ".pbrMetallicRoughness.baseColorTexture");
            material.emissiveTexture =
                loadTexture(source.emissiveTexture, field + ".emissiveTexture");
            m_scene.materials.push_back(std::move(material));
        }
    }

    // Scene::images index of a base colour / emissive texture, or -1 when there is none or it
    // cannot be used (with a warning).
    int loadTexture(const tinygltf::TextureInfo& info, const std::string& field) {
        if (info.index < 0) {
            return -1;
        }
        if (static_cast<size_t>(info.index) >= m_model.textures.size()) {
            fail(ErrorCode::OutOfRange, field + ".index " + std::to_string(info.index) +
                                            " is out of range (" +
                                            std::to_string(m_model.textures.size()) + " textures)");
        }
        if (info.texCoord != 0) {
            // Scene stores one uv set; sampling this texture with TEXCOORD_0 would be wrong.
            warn(field + " uses TEXCOORD_" + std::to_string(info.texCoord) +
                 "; only TEXCOORD_0 is loaded, so the texture is ignored");
            return -1;
        }
        if (info.extensions.count("KHR_texture_transform")) {
            warn(field + " uses KHR_texture_transform, which is not supported; the transform is "
                         "ignored");
        }
        const tinygltf::Texture& texture = m_model.textures[static_cast<size_t>(info.index)];
        if (texture.source < 0) {
            warn(field + ": texture " + std::to_string(info.index) +
                 " has no core image source (an image extension?); the texture is ignored");
            return -1;
        }
        if (static_cast<size_t>(texture.source) >= m_model.images.size()) {
            fail(ErrorCode::OutOfRange, "textures[" + std::to_string(info.index) + "].source " +
                                            std::to_string(texture.source) + " is out of range (" +
                                            std::to_string(m_model.images.size()) + " images)");
        }
        return decodeImage(texture.source);
    }

    // tinygltf has already decoded the pixels (8- or 16-bit, expanded to RGBA); convert them to
    // linear floats once per glTF image. Both users (base colour, emissive) are sRGB-encoded.
    int decodeImage(int gltf_index) {
        int& slot = m_image_slots[static_cast<size_t>(gltf_index)];
        if (slot >= 0) {
            return slot;
        }
        const tinygltf::Image& source = m_model.images[static_cast<size_t>(gltf_index)];
        const std::string field = "images[" + std::to_string(gltf_index) + "]" +
                                  quoted(source.uri.starts_with("data:") ? "" : source.uri);
        if (source.image.empty() || source.width <= 0 || source.height <= 0) {
            fail(ErrorCode::Io, field + " could not be loaded or decoded");
        }
        const size_t channels = static_cast<size_t>(source.component);
        const size_t bytes_per_channel = source.bits == 16 ? 2 : 1;
        const size_t texel_count = size_t(source.width) * size_t(source.height);
        if ((source.bits != 8 && source.bits != 16) || channels < 1 || channels > 4 ||
            source.image.size() != texel_count * channels * bytes_per_channel) {
            fail(ErrorCode::InconsistentSize,
                 field + ": decoded pixel data has an unexpected layout (" +
                     std::to_string(source.component) + " channels, " +
                     std::to_string(source.bits) + " bits)");
        }

        std::array<float, 256> lut8{};
        for (size_t i = 0; i < lut8.size(); ++i) {
            lut8[i] = static_cast<float>(srgbToLinear(double(i) / 255.0));
        }
        auto raw = [&](size_t texel, size_t channel) -> uint32_t {
            const size_t offset = (texel * channels + channel) * bytes_per_channel;
            if (bytes_per_channel == 1) {
                return source.image[offset];
            }
            uint16_t v;
            std::memcpy(&v, &source.image[offset], sizeof(v));
            return v;
        };
        auto colour = [&](uint32_t v) {
            return bytes_per_channel == 1 ? lut8[v]
                                          : static_cast<float>(srgbToLinear(double(v) / 65535.0));
        };
        const double max_value = bytes_per_channel == 1 ? 255.0 : 65535.0;

        Image image;
        image.width = static_cast<uint32_t>(source.width);
        image.height = static_cast<uint32_t>(source.height);
        image.texels.resize(texel_count);
        for (size_t t = 0; t < texel_count; ++t) {
            glm::vec4& out = image.texels[t];
            if (channels <= 2) {
                // Grey (+ alpha): the grey value feeds all three colour channels.
                out = glm::vec4(glm::vec3(colour(raw(t, 0))), 1.0f);
            } else {
                out = glm::vec4(colour(raw(t, 0)), colour(raw(t, 1)), colour(raw(t, 2)), 1.0f);
            }
            if (channels == 2 || channels == 4) {
                // Alpha is linear coverage in glTF, never sRGB-encoded.
                out.w = static_cast<float>(raw(t, channels - 1) / max_value);
            }
        }
        slot = static_cast<int>(m_scene.images.size());
        m_scene.images.push_back(std::move(image));
        return slot;
    }

    // ---- node graph ----

    // glTF nodes form a forest: every node has at most one parent and no node is its own
    // ancestor. Checked over all nodes, not only those a scene reaches, since without `scenes`
    // the roots are the nodes nobody lists as a child, and a cycle has none of those: it would
    // vanish from the scene without a word.
    void checkNodeForest() const {
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

    std::vector<int> sceneRoots(std::optional<int> requested) {
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

    glm::dmat4 localMatrix(int node_index) const {
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
            result[3] =
                glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1.0);
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
            result =
                result * glm::dmat4(glm::dvec4(node.scale[0], 0, 0, 0),
                                    glm::dvec4(0, node.scale[1], 0, 0),
                                    glm::dvec4(0, 0, node.scale[2], 0), glm::dvec4(0, 0, 0, 1));
        }
        return result;
    }

    // World matrices (parent x local) of every node reachable from `roots`; returns the reachable
    // nodes in glTF node order, which is the order of Scene::nodes and of the triangles, so the
    // output does not depend on how the hierarchy is drawn. Iterative, so a deep chain of nodes
    // cannot overflow the stack.
    std::vector<int> traverse(const std::vector<int>& roots) {
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

    // Every node that uses a mesh adds a transformed copy of its triangles to the scene, so a
    // small file can name one large (or sparse, zero-backed) accessor from many nodes. The
    // per-primitive checks in loadPrimitive catch that only once the first copies exist (a 1.3
    // KB file with a 2^24-vertex sparse accessor under 21 nodes held 1.9 GB, 12 s in, before
    // its refusal). This sums the scene arrays every instance will add, from the accessor
    // counts alone, and refuses before the first is built. It is a lower bound of what loading
    // charges (the per-primitive work arrays come on top), so it never refuses a scene the
    // per-primitive checks would take; malformed accessors and meshes are left to those checks,
    // which name the precise field.
    void checkInstancedGrowth(const std::vector<int>& reachable) {
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
        std::vector<uint64_t> instances(m_model.meshes.size(), 0);
        for (const int node_index : reachable) {
            const int mesh = m_model.nodes[static_cast<size_t>(node_index)].mesh;
            if (mesh >= 0 && static_cast<size_t>(mesh) < instances.size()) {
                ++instances[static_cast<size_t>(mesh)];
            }
        }
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
                 m_budget.refusal(
                     "adding every mesh instance to the scene (" +
                         std::to_string(clamped(vertices)) + " vertices and " +
                         std::to_string(clamped(triangles)) + " triangles; the most from meshes[" +
                         std::to_string(largest) + "]" + quoted(m_model.meshes[largest].name) +
                         ", used by " + std::to_string(instances[largest]) +
                         (instances[largest] == 1 ? " node)" : " nodes)"),
                     bytes));
        }
    }

    void loadNode(int node_index) {
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

        if (const auto it = node.extensions.find("KHR_lights_punctual");
            it != node.extensions.end()) {
            loadLight(node_index, it->second, world);
        }
    }

    // ---- accessors ----

    // Reads accessor `index` as `count x components` values of type T (float, or uint32_t for
    // indices), with every byte range checked against its bufferView and buffer, and sparse
    // substitution applied. `usage` names the accessor's role in messages.
    template <class T>
    std::vector<T> readAccessor(int index, int expected_type, bool indices,
                                const std::string& usage) const {
        const std::string field =
            "accessors[" + std::to_string(index) + "]" + (usage.empty() ? "" : " (" + usage + ")");
        const tinygltf::Accessor& accessor = checkedAccessor(index, expected_type, indices, field);
        const size_t component_size = componentSize(accessor.componentType);
        const size_t components = componentCount(accessor.type);
        std::vector<T> out = accessor.bufferView >= 0
                                 ? readViewElements<T>(accessor, components, component_size, field)
                                 : zeroElements<T>(accessor, components, field);
        if (accessor.sparse.isSparse) {
            applySparse(accessor, field, components, component_size, out);
        }
        return out;
    }

    // Accessor `index`, checked to exist, to have the expected type and a componentType glTF
    // allows (unnormalized unsigned integers for indices).
    const tinygltf::Accessor& checkedAccessor(int index, int expected_type, bool indices,
                                              const std::string& field) const {
        if (index < 0 || static_cast<size_t>(index) >= m_model.accessors.size()) {
            fail(ErrorCode::OutOfRange, field + " is out of range (" +
                                            std::to_string(m_model.accessors.size()) +
                                            " accessors)");
        }
        const tinygltf::Accessor& accessor = m_model.accessors[static_cast<size_t>(index)];
        if (accessor.type != expected_type) {
            fail(ErrorCode::InvalidArgument, field + " has type " + typeName(accessor.type) +
                                                 ", expected " + typeName(expected_type));
        }
        if (componentSize(accessor.componentType) == 0) {
            fail(ErrorCode::BadEnum, field + " has componentType " +
                                         std::to_string(accessor.componentType) +
                                         ", which glTF 2.0 does not allow here");
        }
        if (indices &&
            (accessor.componentType == TINYGLTF_COMPONENT_TYPE_BYTE ||
             accessor.componentType == TINYGLTF_COMPONENT_TYPE_SHORT ||
             accessor.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT || accessor.normalized)) {
            fail(ErrorCode::BadEnum, field + " must hold unnormalized unsigned integers");
        }
        return accessor;
    }

    // Refuses `count` elements of `components` T's when they do not fit the budget. Predicted
    // before the vector is allocated, so that no count in the file can make the expansion
    // exceed the budget (a sparse accessor's zeros are backed by nothing).
    template <class T>
    void checkExpansion(size_t count, size_t components, const std::string& field) const {
        const uint64_t per_element = uint64_t(components) * sizeof(T);
        const uint64_t bytes = count > UINT64_MAX / per_element ? UINT64_MAX : count * per_element;
        if (!m_budget.fits(bytes)) {
            fail(ErrorCode::OutOfRange,
                 m_budget.refusal(field + " (" + std::to_string(count) + " x " +
                                      std::to_string(components) + " x " +
                                      std::to_string(sizeof(T)) + " bytes, expanded)",
                                  bytes));
        }
    }

    // The elements of an accessor with a bufferView, converted to T.
    template <class T>
    std::vector<T> readViewElements(const tinygltf::Accessor& accessor, size_t components,
                                    size_t component_size, const std::string& field) const {
        const size_t element_size = components * component_size;
        const size_t count = accessor.count;
        const std::span<const uint8_t> view = bufferViewBytes(accessor.bufferView, field);
        const size_t view_stride = m_model.bufferViews[size_t(accessor.bufferView)].byteStride;
        const size_t stride = view_stride != 0 ? view_stride : element_size;
        if (stride < element_size) {
            fail(ErrorCode::InconsistentSize,
                 field + ": bufferViews[" + std::to_string(accessor.bufferView) + "].byteStride " +
                     std::to_string(view_stride) + " is smaller than one element (" +
                     std::to_string(element_size) + " bytes)");
        }
        checkRange(view.size(), accessor.byteOffset, count, stride, element_size, field);
        checkExpansion<T>(count, components, field);
        std::vector<T> out(count * components);
        for (size_t i = 0; i < count; ++i) {
            const uint8_t* element = view.data() + accessor.byteOffset + i * stride;
            for (size_t c = 0; c < components; ++c) {
                out[i * components + c] = static_cast<T>(readComponent(
                    element + c * component_size, accessor.componentType, accessor.normalized));
            }
        }
        return out;
    }

    // glTF: an accessor without a bufferView is all zeros (until sparse values apply).
    template <class T>
    std::vector<T> zeroElements(const tinygltf::Accessor& accessor, size_t components,
                                const std::string& field) const {
        if (!accessor.sparse.isSparse) {
            fail(ErrorCode::InvalidArgument, field + " has neither a bufferView nor sparse "
                                                     "values");
        }
        // Nothing in the file backs these zeros, so bound them before allocating: a corrupt
        // count must give an error, not exhaust memory.
        const size_t count = accessor.count;
        if (count > kMaxUnbackedElements) {
            fail(ErrorCode::OutOfRange,
                 field + ": count " + std::to_string(count) +
                     " is too large for an accessor without a bufferView (at most " +
                     std::to_string(kMaxUnbackedElements) + ")");
        }
        checkExpansion<T>(count, components, field);
        return std::vector<T>(count * components, T(0));
    }

    void applySparse(const tinygltf::Accessor& accessor, const std::string& field,
                     size_t components, size_t component_size, auto& out) const {
        using T = typename std::remove_reference_t<decltype(out)>::value_type;
        const auto& sparse = accessor.sparse;
        if (sparse.count < 1 || static_cast<size_t>(sparse.count) > accessor.count) {
            fail(ErrorCode::OutOfRange, field + ": sparse.count " + std::to_string(sparse.count) +
                                            " must be in 1.." + std::to_string(accessor.count));
        }
        if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
            fail(ErrorCode::OutOfRange, field + ": sparse byteOffset must be >= 0");
        }
        const int index_type = sparse.indices.componentType;
        if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
            index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
            fail(ErrorCode::BadEnum, field + ": sparse.indices.componentType " +
                                         std::to_string(index_type) + " is not an unsigned type");
        }
        const size_t count = static_cast<size_t>(sparse.count);
        const size_t index_size = componentSize(index_type);
        const size_t element_size = components * component_size;
        // Sparse index and value arrays are tightly packed (glTF forbids byteStride on them).
        const std::span<const uint8_t> index_view =
            bufferViewBytes(sparse.indices.bufferView, field + " sparse.indices");
        checkRange(index_view.size(), size_t(sparse.indices.byteOffset), count, index_size,
                   index_size, field + " sparse.indices");
        const std::span<const uint8_t> value_view =
            bufferViewBytes(sparse.values.bufferView, field + " sparse.values");
        checkRange(value_view.size(), size_t(sparse.values.byteOffset), count, element_size,
                   element_size, field + " sparse.values");
        for (size_t i = 0; i < count; ++i) {
            const double target = readComponent(
                index_view.data() + size_t(sparse.indices.byteOffset) + i * index_size, index_type,
                false);
            if (target >= double(accessor.count)) {
                fail(ErrorCode::OutOfRange, field + ": sparse index " +
                                                std::to_string(uint64_t(target)) + " >= count " +
                                                std::to_string(accessor.count));
            }
            const uint8_t* element =
                value_view.data() + size_t(sparse.values.byteOffset) + i * element_size;
            for (size_t c = 0; c < components; ++c) {
                out[size_t(target) * components + c] = static_cast<T>(readComponent(
                    element + c * component_size, accessor.componentType, accessor.normalized));
            }
        }
    }

    std::span<const uint8_t> bufferViewBytes(int view_index, const std::string& field) const {
        if (view_index < 0 || static_cast<size_t>(view_index) >= m_model.bufferViews.size()) {
            fail(ErrorCode::OutOfRange,
                 field + ": bufferView " + std::to_string(view_index) + " is out of range (" +
                     std::to_string(m_model.bufferViews.size()) + " bufferViews)");
        }
        const tinygltf::BufferView& view = m_model.bufferViews[static_cast<size_t>(view_index)];
        const std::string view_field = "bufferViews[" + std::to_string(view_index) + "]";
        if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= m_model.buffers.size()) {
            fail(ErrorCode::OutOfRange, field + ": " + view_field + ".buffer " +
                                            std::to_string(view.buffer) + " is out of range");
        }
        const std::vector<unsigned char>& data = m_model.buffers[size_t(view.buffer)].data;
        if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
            fail(ErrorCode::Truncated,
                 field + ": " + view_field + " (byteOffset " + std::to_string(view.byteOffset) +
                     ", byteLength " + std::to_string(view.byteLength) + ") exceeds buffer " +
                     std::to_string(view.buffer) + " (" + std::to_string(data.size()) + " bytes)");
        }
        return {data.data() + view.byteOffset, view.byteLength};
    }

    // offset + (count - 1) * stride + element_size <= available, without overflow.
    void checkRange(size_t available, size_t offset, size_t count, size_t stride,
                    size_t element_size, const std::string& field) const {
        if (count == 0) {
            return;
        }
        const bool fits = offset <= available && element_size <= available - offset &&
                          (count - 1) <= (available - offset - element_size) / stride;
        if (!fits) {
            fail(ErrorCode::OutOfRange, field + ": " + std::to_string(count) + " elements of " +
                                            std::to_string(element_size) + " bytes (stride " +
                                            std::to_string(stride) + ", byteOffset " +
                                            std::to_string(offset) + ") exceed the " +
                                            std::to_string(available) + "-byte bufferView");
        }
    }

    // ---- primitives ----

    // A float vertex attribute of `components` per vertex, empty when the primitive has none;
    // its count must match POSITION's.
    std::vector<float> vertexAttribute(const tinygltf::Primitive& primitive, const char* name,
                                       int type, size_t components, size_t vertex_count,
                                       const std::string& field) const {
        const auto it = primitive.attributes.find(name);
        if (it == primitive.attributes.end()) {
            return {};
        }
        std::vector<float> values =
            readAccessor<float>(it->second, type, false, field + " " + name);
        if (values.size() / components != vertex_count) {
            fail(ErrorCode::InconsistentSize,
                 field + ": " + name + " (accessor " + std::to_string(it->second) + ") has " +
                     std::to_string(values.size() / components) + " elements, POSITION has " +
                     std::to_string(vertex_count));
        }
        return values;
    }

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

    void loadPrimitive(int mesh_index, int primitive_index, const glm::dmat4& world,
                       int32_t scene_node, BoundsBuilder& local_bounds,
                       BoundsBuilder& world_bounds) {
        const tinygltf::Mesh& mesh = m_model.meshes[static_cast<size_t>(mesh_index)];
        const tinygltf::Primitive& primitive =
            mesh.primitives[static_cast<size_t>(primitive_index)];
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
        const std::vector<uint32_t> indices =
            primitiveIndices(primitive, arrays.vertexCount(), field);
        held.add(indices.size() * sizeof(uint32_t));
        reserveTriangles(mode, indices.size(), arrays.vertexCount(), field, held);
        const std::vector<glm::uvec3> corners = triangleCorners(mode, indices, field);
        appendTriangles(arrays, corners, world, material_index, scene_node, field, local_bounds,
                        world_bounds);
    }

    // The scene material of a primitive: glTF's index, or the default material when it has none.
    uint32_t primitiveMaterial(const tinygltf::Primitive& primitive, const std::string& field) {
        if (primitive.material < 0) {
            return defaultMaterial();
        }
        if (static_cast<size_t>(primitive.material) >= m_model.materials.size()) {
            fail(ErrorCode::OutOfRange,
                 field + ".material " + std::to_string(primitive.material) + " is out of range (" +
                     std::to_string(m_model.materials.size()) + " materials)");
        }
        // loadMaterials keeps glTF's material order, so the indices coincide.
        return static_cast<uint32_t>(primitive.material);
    }

    // POSITION, TEXCOORD_0 and NORMAL, each charged to `held` once read.
    PrimitiveArrays readPrimitiveArrays(const tinygltf::Primitive& primitive,
                                        const std::string& field, HeldBytes& held) {
        PrimitiveArrays arrays;
        arrays.positions = readAccessor<float>(primitive.attributes.at("POSITION"),
                                               TINYGLTF_TYPE_VEC3, false, field + " POSITION");
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
    std::vector<uint32_t> primitiveIndices(const tinygltf::Primitive& primitive,
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
            fail(ErrorCode::OutOfRange,
                 m_budget.refusal(field + " (" + std::to_string(vertex_count) +
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
    void reserveTriangles(int mode, size_t n, size_t vertex_count, const std::string& field,
                          HeldBytes& held) {
        const uint64_t triangle_count = mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : n < 2 ? 0 : n - 2;
        const uint64_t work = triangle_count * sizeof(glm::uvec3) +
                              vertex_count * (sizeof(glm::vec3) + sizeof(uint32_t)) +
                              vertex_count / 8 + 1;
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
    std::vector<glm::uvec3> triangleCorners(int mode, const std::vector<uint32_t>& indices,
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
    void appendTriangles(const PrimitiveArrays& arrays, const std::vector<glm::uvec3>& corners,
                         const glm::dmat4& world, uint32_t material_index, int32_t scene_node,
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
            finite[v] =
                isFinite(local) && isFinite(glm::dvec3(world_positions[v])) &&
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
                    m_scene.normals.push_back(
                        normals.empty() ? glm::vec3(0.0f)
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
    static uint64_t grownCapacity(const std::vector<T>& v, uint64_t more) {
        return v.size() + more <= v.capacity()
                   ? v.capacity()
                   : std::max<uint64_t>(v.size() + more, 2 * uint64_t(v.capacity()));
    }
    template <class T>
    static uint64_t growthBytes(const std::vector<T>& v, uint64_t more) {
        const uint64_t capacity = grownCapacity(v, more);
        return capacity == v.capacity() ? 0 : capacity * sizeof(T);
    }
    uint64_t sceneGrowth(uint64_t vertices, uint64_t triangles) const {
        return growthBytes(m_scene.positions, vertices) + growthBytes(m_scene.uvs, vertices) +
               growthBytes(m_scene.normals, vertices) + growthBytes(m_scene.triangles, triangles) +
               growthBytes(m_scene.triangleMaterial, triangles) +
               growthBytes(m_scene.triangleNode, triangles);
    }
    template <class T>
    void grow(std::vector<T>& v, uint64_t more) {
        const uint64_t before = v.capacity() * sizeof(T);
        v.reserve(grownCapacity(v, more));
        m_budget.add(v.capacity() * sizeof(T));
        m_budget.release(before);
    }
    void growScene(uint64_t vertices, uint64_t triangles) {
        grow(m_scene.positions, vertices);
        grow(m_scene.uvs, vertices);
        grow(m_scene.normals, vertices);
        grow(m_scene.triangles, triangles);
        grow(m_scene.triangleMaterial, triangles);
        grow(m_scene.triangleNode, triangles);
    }

    // ---- KHR_lights_punctual ----

    void loadLight(int node_index, const tinygltf::Value& extension, const glm::dmat4& world) {
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

    LightType lightType(const tinygltf::Light& source, const std::string& field) const {
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
    glm::dvec3 lightColour(const tinygltf::Light& source, const std::string& field) const {
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
    void setLightStrength(PunctualLight& light, glm::dvec3 colour, const tinygltf::Light& source,
                          const std::string& field) const {
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
                     numberText(colour.x) + ", " + numberText(colour.y) + ", " +
                     numberText(colour.z) + ") is above " + numberText(kMaxEmission) +
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
    void setSpotCones(PunctualLight& light, const tinygltf::Light& source,
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
    bool placeLight(PunctualLight& light, const glm::dmat4& world, const std::string& node_field,
                    int light_index) {
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

    const tinygltf::Model& m_model;
    std::string m_file;
    MemoryBudget& m_budget;
    Scene m_scene;
    std::vector<int> m_image_slots;         // glTF image -> Scene::images index, -1 until decoded
    std::vector<glm::dmat4> m_world;        // per glTF node, valid for reachable nodes
    std::vector<bool> m_node_has_triangles; // per Scene::nodes entry
    int m_default_material = -1;
};

} // namespace

namespace {

// The GLB magic decides, whatever the extension; a .glb without it is reported as such by the
// container check.
bool isBinaryGltf(std::span<const uint8_t> bytes, const std::filesystem::path& name) {
    const bool has_magic = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    std::string extension = name.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return has_magic || extension == ".glb";
}

// Checks the JSON document before tinygltf sees it: nesting, the parsed size against the
// budget (charged), syntax, and every field gltf_input checks. Throws LoadError.
void checkJsonDocument(std::span<const uint8_t> text, uint64_t text_offset, const std::string& file,
                       const gltf::GlbChunks* glb, const gltf::AssetFolder& folder,
                       MemoryBudget& budget) {
    const uint64_t values = gltf::checkJsonNesting(text, text_offset, file);
    // Two parses hold the document (the check's, then tinygltf's with its Values); the first is
    // gone before the second, and some of tinygltf's stays in the model.
    const uint64_t document_bytes =
        values > UINT64_MAX / gltf::kJsonValueBytes ? UINT64_MAX : values * gltf::kJsonValueBytes;
    if (!budget.fits(document_bytes)) {
        throw LoadError{
            ErrorCode::OutOfRange,
            file + ": " +
                budget.refusal("the JSON document (" + std::to_string(values) + " values, parsed)",
                               document_bytes)};
    }
    budget.add(document_bytes);
    nlohmann::json document;
    try {
        document = nlohmann::json::parse(text.begin(), text.end());
    } catch (const nlohmann::json::exception& e) {
        throw LoadError{ErrorCode::InvalidArgument,
                        file + ": not valid JSON: " + std::string(e.what())};
    }
    gltf::checkDocument(document, file, glb, folder, budget);
}

// tinygltf's parse of the checked file, its buffers and images read through the folder rule and
// the budget; `warning` receives tinygltf's warnings. Throws LoadError.
tinygltf::Model parseModel(std::span<const uint8_t> bytes, std::span<const uint8_t> text,
                           bool binary, const gltf::AssetFolder& folder, MemoryBudget& budget,
                           const std::string& file, std::string& warning) {
    tinygltf::TinyGLTF parser;
    gltf::IoContext io{folder, budget, file, std::nullopt};
    gltf::installIoCallbacks(parser, io);
    tinygltf::Model model;
    std::string error;
    const bool parsed =
        binary ? parser.LoadBinaryFromMemory(&model, &error, &warning, bytes.data(),
                                             static_cast<unsigned int>(bytes.size()), folder.base())
               : parser.LoadASCIIFromString(&model, &error, &warning,
                                            reinterpret_cast<const char*>(text.data()),
                                            static_cast<unsigned int>(text.size()), folder.base());
    if (io.refusal) {
        // A file the rule refused, or an image refused before decoding: say why, rather
        // than tinygltf's "File not found" or nothing (it only warns about images).
        throw *io.refusal;
    }
    if (!parsed) {
        std::string message = trimmed(error);
        if (!trimmed(warning).empty()) {
            message += (message.empty() ? "" : "; ") + trimmed(warning);
        }
        throw LoadError{ErrorCode::InvalidArgument,
                        file + ": " + (message.empty() ? "tinygltf failed" : message)};
    }
    return model;
}

} // namespace

Result<Scene> loadGltfBytes(std::span<const uint8_t> bytes, const std::filesystem::path& name,
                            const LoadOptions& options) {
    const std::string file = name.string();
    try {
        MemoryBudget budget(options.maxMemoryBytes);
        if (!budget.fits(bytes.size())) {
            return makeError(ErrorCode::OutOfRange,
                             file + ": " + budget.refusal("the file", bytes.size()));
        }
        budget.add(bytes.size());
        if (bytes.size() > std::numeric_limits<unsigned int>::max()) {
            return makeError(ErrorCode::OutOfRange, file + ": larger than 4 GiB");
        }
        gltf::AssetFolder folder(name, options.assetRoots);
        if (!folder.unresolvedRoots().empty()) {
            return makeError(ErrorCode::Io, "LoadOptions::assetRoots: '" +
                                                folder.unresolvedRoots().front() +
                                                "' is not an existing folder");
        }
        const bool binary = isBinaryGltf(bytes, name);
        gltf::GlbChunks glb;
        std::span<const uint8_t> text = bytes;
        uint64_t text_offset = 0;
        if (binary) {
            glb = gltf::checkGlbContainer(bytes, file);
            text = glb.json;
            text_offset = glb.jsonOffset;
        }
        checkJsonDocument(text, text_offset, file, binary ? &glb : nullptr, folder, budget);
        std::string warning;
        const tinygltf::Model model =
            parseModel(bytes, text, binary, folder, budget, file, warning);
        GltfLoader loader(model, file, budget);
        Result<Scene> scene = loader.load(options.sceneIndex, xxhash64(bytes), warning);
        if (scene) {
            applyUnitScale(scene.value(), options.scale);
            if (std::string w = implausibleSizeWarning(scene.value(), file); !w.empty()) {
                scene.value().warnings.push_back(std::move(w));
            }
        }
        return scene;
    } catch (const LoadError& e) {
        return makeError(e.code, e.message);
    } catch (const std::exception& e) {
        return makeError(ErrorCode::InvalidArgument, file + ": " + e.what());
    }
}

Result<Scene> loadGltf(const std::filesystem::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
        return makeError(ErrorCode::Io, file + ": no such file");
    }
    // The budget here only bounds the read; loadGltfBytes charges the bytes again.
    MemoryBudget read_budget(options.maxMemoryBytes);
    Result<std::vector<uint8_t>> bytes = gltf::readRegularFile(path, file, read_budget);
    if (!bytes) {
        return bytes.error();
    }
    return loadGltfBytes(bytes.value(), path, options);
}

} // namespace probekit::baker
