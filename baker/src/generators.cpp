#include "probekit/baker/generators.hpp"

#include <cmath>
#include <cstring>
#include <numbers>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include "probekit/formats/pvol.hpp"

namespace probekit::baker {
namespace {

using Json = nlohmann::json;

struct MaterialSpec {
    std::string name;
    glm::vec3 albedo;
    glm::vec3 emission{0.0f}; // radiance, W/(sr m^2)
};

struct QuadMesh {
    int material = 0;
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> indices;

    // Adds a planar quad a-b-c-d (in order around its edge).
    void quad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
        const uint32_t base = uint32_t(positions.size());
        positions.insert(positions.end(), {a, b, c, d});
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
};

struct PointLightSpec {
    glm::vec3 position;
    glm::vec3 color;
    float intensity; // W/sr
};

struct DirectionalLightSpec {
    glm::vec3 direction; // unit vector the light travels along
    glm::vec3 color;
    float intensity; // W/m^2 on a surface facing the light
};

struct SceneSpec {
    std::vector<MaterialSpec> materials;
    std::vector<QuadMesh> meshes;
    std::vector<PointLightSpec> lights;
    std::vector<DirectionalLightSpec> suns;
};

SceneSpec cornell() {
    SceneSpec s;
    s.materials = {{"white", glm::vec3(0.73f)},
                   {"red", glm::vec3(0.63f, 0.065f, 0.05f)},
                   {"green", glm::vec3(0.14f, 0.45f, 0.091f)},
                   {"light", glm::vec3(0.78f), glm::vec3(17.0f, 12.0f, 4.0f)}};
    // Published Cornell box data, millimetres.
    auto mm = [](float x, float y, float z) { return glm::vec3(x, y, z) * 0.001f; };
    QuadMesh white{0, {}, {}}, red{1, {}, {}}, green{2, {}, {}}, light{3, {}, {}};
    white.quad(mm(552.8f, 0, 0), mm(0, 0, 0), mm(0, 0, 559.2f), mm(549.6f, 0, 559.2f)); // floor
    white.quad(mm(556.0f, 548.8f, 0), mm(556.0f, 548.8f, 559.2f), mm(0, 548.8f, 559.2f),
               mm(0, 548.8f, 0)); // ceiling
    white.quad(mm(549.6f, 0, 559.2f), mm(0, 0, 559.2f), mm(0, 548.8f, 559.2f),
               mm(556.0f, 548.8f, 559.2f)); // back wall
    green.quad(mm(0, 0, 559.2f), mm(0, 0, 0), mm(0, 548.8f, 0),
               mm(0, 548.8f, 559.2f)); // right wall
    red.quad(mm(552.8f, 0, 0), mm(549.6f, 0, 559.2f), mm(556.0f, 548.8f, 559.2f),
             mm(556.0f, 548.8f, 0)); // left wall
    // Short block.
    white.quad(mm(130, 165, 65), mm(82, 165, 225), mm(240, 165, 272), mm(290, 165, 114));
    white.quad(mm(290, 0, 114), mm(290, 165, 114), mm(240, 165, 272), mm(240, 0, 272));
    white.quad(mm(130, 0, 65), mm(130, 165, 65), mm(290, 165, 114), mm(290, 0, 114));
    white.quad(mm(82, 0, 225), mm(82, 165, 225), mm(130, 165, 65), mm(130, 0, 65));
    white.quad(mm(240, 0, 272), mm(240, 165, 272), mm(82, 165, 225), mm(82, 0, 225));
    // Tall block.
    white.quad(mm(423, 330, 247), mm(265, 330, 296), mm(314, 330, 456), mm(472, 330, 406));
    white.quad(mm(423, 0, 247), mm(423, 330, 247), mm(472, 330, 406), mm(472, 0, 406));
    white.quad(mm(472, 0, 406), mm(472, 330, 406), mm(314, 330, 456), mm(314, 0, 456));
    white.quad(mm(314, 0, 456), mm(314, 330, 456), mm(265, 330, 296), mm(265, 0, 296));
    white.quad(mm(265, 0, 296), mm(265, 330, 296), mm(423, 330, 247), mm(423, 0, 247));
    // The light: 1 mm below the ceiling so it does not coincide with it.
    light.quad(mm(343, 547.8f, 227), mm(343, 547.8f, 332), mm(213, 547.8f, 332),
               mm(213, 547.8f, 227));
    s.meshes = {white, red, green, light};
    return s;
}

SceneSpec thinWall() {
    SceneSpec s;
    s.materials = {{"wall", glm::vec3(0.6f)}};
    QuadMesh m{0, {}, {}};
    const float h = 2.5f;
    const float t = 0.025f; // half the wall thickness
    // Outer shell: floor, ceiling and four walls of the 8 m x 4 m footprint.
    m.box(glm::vec3(-4.0f, -0.1f, -2.0f), glm::vec3(4.0f, 0.0f, 2.0f));
    m.box(glm::vec3(-4.0f, h, -2.0f), glm::vec3(4.0f, h + 0.1f, 2.0f));
    m.box(glm::vec3(-4.1f, 0.0f, -2.0f), glm::vec3(-4.0f, h, 2.0f));
    m.box(glm::vec3(4.0f, 0.0f, -2.0f), glm::vec3(4.1f, h, 2.0f));
    m.box(glm::vec3(-4.0f, 0.0f, -2.1f), glm::vec3(4.0f, h, -2.0f));
    m.box(glm::vec3(-4.0f, 0.0f, 2.0f), glm::vec3(4.0f, h, 2.1f));
    // The dividing wall, 5 cm thick, with a doorway from z = 1.2 to 2.0 below y = 2.0.
    m.box(glm::vec3(-t, 0.0f, -2.0f), glm::vec3(t, h, 1.2f));
    m.box(glm::vec3(-t, 2.0f, 1.2f), glm::vec3(t, h, 2.0f));
    s.meshes = {m};
    s.lights = {{glm::vec3(-2.0f, 1.8f, -1.0f), glm::vec3(1.0f), 20.0f}};
    return s;
}

SceneSpec courtyard() {
    SceneSpec s;
    s.materials = {{"paving", glm::vec3(0.45f, 0.42f, 0.38f)},
                   {"plaster", glm::vec3(0.6f)},
                   {"terracotta", glm::vec3(0.66f, 0.3f, 0.18f)},
                   {"sage", glm::vec3(0.35f, 0.55f, 0.35f)},
                   {"marble", glm::vec3(0.75f, 0.74f, 0.7f)}};
    QuadMesh paving{0, {}, {}}, plaster{1, {}, {}}, terracotta{2, {}, {}}, sage{3, {}, {}},
        marble{4, {}, {}};
    const float half = 8.0f; // the open interior spans -8..8 in x and z
    const float wall = 0.2f; // wall thickness, outside the interior
    const float height = 6.0f;
    // Paving slab under everything, and four walls standing on it: every piece a closed box,
    // so a probe inside one sees only back faces.
    paving.box(glm::vec3(-half - wall, -0.1f, -half - wall),
               glm::vec3(half + wall, 0.0f, half + wall));
    plaster.box(glm::vec3(-half - wall, 0.0f, -half - wall),
                glm::vec3(half + wall, height, -half)); // -z, behind the colonnade
    plaster.box(glm::vec3(-half - wall, 0.0f, half), glm::vec3(half + wall, height, half + wall));
    terracotta.box(glm::vec3(half, 0.0f, -half), glm::vec3(half + wall, height, half)); // +x
    sage.box(glm::vec3(-half - wall, 0.0f, -half), glm::vec3(-half, height, half));     // -x
    // Colonnade along the -z wall: a walkway 2.5 m deep under a roof slab whose underside is
    // 3.5 m up, carried by eight 0.4 m square columns 2 m apart, flush with the roof's edge.
    const float walk_edge = -half + 2.5f;
    const float roof = 3.5f;
    marble.box(glm::vec3(-half, roof, -half), glm::vec3(half, roof + 0.25f, walk_edge));
    for (int i = 0; i < 8; ++i) {
        const float x = -7.0f + 2.0f * float(i);
        marble.box(glm::vec3(x - 0.2f, 0.0f, walk_edge - 0.4f),
                   glm::vec3(x + 0.2f, roof, walk_edge));
    }
    // A fountain in the middle: a low basin plinth and a pedestal on it.
    marble.box(glm::vec3(-1.4f, 0.0f, -1.4f), glm::vec3(1.4f, 0.5f, 1.4f));
    marble.box(glm::vec3(-0.3f, 0.5f, -0.3f), glm::vec3(0.3f, 1.2f, 0.3f));
    s.meshes = {paving, plaster, terracotta, sage, marble};
    // The sun 50 degrees above the horizon, shining from the open +z side (30 degrees towards
    // +x), so the columns' shadows fall into the walkway while the roof shades its back.
    const float elevation = 50.0f * std::numbers::pi_v<float> / 180.0f;
    const float azimuth = 30.0f * std::numbers::pi_v<float> / 180.0f;
    const glm::vec3 to_sun(std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                           std::cos(azimuth) * std::cos(elevation));
    s.suns = {{-to_sun, glm::vec3(1.0f, 0.95f, 0.85f), 3.0f}};
    return s;
}

// The glTF node rotation (x, y, z, w) that turns the light's local -Z into unit `direction`:
// the half-way quaternion (1 + a.d, a x d) normalised, a = -Z (never opposite to `direction`
// here: the suns shine downwards, never along +Z exactly).
Json rotationFromMinusZ(glm::vec3 direction) {
    const glm::vec3 a(0.0f, 0.0f, -1.0f);
    const glm::vec3 axis = glm::cross(a, direction);
    const float w = 1.0f + glm::dot(a, direction);
    const float norm = std::sqrt(glm::dot(axis, axis) + w * w);
    return {axis.x / norm, axis.y / norm, axis.z / norm, w / norm};
}

Json buildGltf(const SceneSpec& s, const std::string& bin_name, std::vector<uint8_t>& bin) {
    Json j;
    j["asset"] = {{"version", "2.0"}, {"generator", "probekit " PROBEKIT_VERSION_STRING}};
    j["scene"] = 0;
    j["scenes"] = Json::array({{{"nodes", Json::array()}}});
    j["nodes"] = Json::array();
    j["meshes"] = Json::array();
    j["accessors"] = Json::array();
    j["bufferViews"] = Json::array();
    j["materials"] = Json::array();
    bool uses_strength = false;
    for (const MaterialSpec& m : s.materials) {
        Json jm = {{"name", m.name},
                   {"doubleSided", true},
                   {"pbrMetallicRoughness",
                    {{"baseColorFactor", {m.albedo.x, m.albedo.y, m.albedo.z, 1.0f}},
                     {"metallicFactor", 0.0f},
                     {"roughnessFactor", 1.0f}}}};
        const float peak = std::max({m.emission.x, m.emission.y, m.emission.z});
        if (peak > 0.0f) {
            // emissiveFactor is limited to [0, 1]: the peak goes into emissive_strength.
            jm["emissiveFactor"] = {m.emission.x / peak, m.emission.y / peak, m.emission.z / peak};
            jm["extensions"]["KHR_materials_emissive_strength"] = {{"emissiveStrength", peak}};
            uses_strength = true;
        }
        j["materials"].push_back(jm);
    }
    auto append = [&bin](const void* data, size_t bytes) {
        const size_t offset = bin.size();
        bin.resize(offset + bytes);
        std::memcpy(bin.data() + offset, data, bytes);
        return offset;
    };
    for (size_t mi = 0; mi < s.meshes.size(); ++mi) {
        const QuadMesh& mesh = s.meshes[mi];
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (const glm::vec3& p : mesh.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        const size_t pos_offset =
            append(mesh.positions.data(), mesh.positions.size() * sizeof(glm::vec3));
        const size_t idx_offset =
            append(mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t));
        const size_t view = j["bufferViews"].size();
        j["bufferViews"].push_back({{"buffer", 0},
                                    {"byteOffset", pos_offset},
                                    {"byteLength", mesh.positions.size() * sizeof(glm::vec3)},
                                    {"target", 34962}});
        j["bufferViews"].push_back({{"buffer", 0},
                                    {"byteOffset", idx_offset},
                                    {"byteLength", mesh.indices.size() * sizeof(uint32_t)},
                                    {"target", 34963}});
        const size_t acc = j["accessors"].size();
        j["accessors"].push_back({{"bufferView", view},
                                  {"componentType", 5126},
                                  {"count", mesh.positions.size()},
                                  {"type", "VEC3"},
                                  {"min", {lo.x, lo.y, lo.z}},
                                  {"max", {hi.x, hi.y, hi.z}}});
        j["accessors"].push_back({{"bufferView", view + 1},
                                  {"componentType", 5125},
                                  {"count", mesh.indices.size()},
                                  {"type", "SCALAR"}});
        j["meshes"].push_back({{"name", s.materials[mesh.material].name},
                               {"primitives",
                                {{{"attributes", {{"POSITION", acc}}},
                                  {"indices", acc + 1},
                                  {"material", mesh.material},
                                  {"mode", 4}}}}});
        j["scenes"][0]["nodes"].push_back(j["nodes"].size());
        j["nodes"].push_back({{"name", s.materials[mesh.material].name}, {"mesh", mi}});
    }
    if (!s.lights.empty() || !s.suns.empty()) {
        Json lights = Json::array();
        auto add_light_node = [&j, &lights](Json light, Json node) {
            node["name"] = "light" + std::to_string(lights.size());
            node["extensions"]["KHR_lights_punctual"] = {{"light", lights.size()}};
            lights.push_back(std::move(light));
            j["scenes"][0]["nodes"].push_back(j["nodes"].size());
            j["nodes"].push_back(std::move(node));
        };
        for (const PointLightSpec& l : s.lights) {
            add_light_node({{"type", "point"},
                            {"color", {l.color.x, l.color.y, l.color.z}},
                            {"intensity", l.intensity}},
                           {{"translation", {l.position.x, l.position.y, l.position.z}}});
        }
        for (const DirectionalLightSpec& l : s.suns) {
            add_light_node({{"type", "directional"},
                            {"color", {l.color.x, l.color.y, l.color.z}},
                            {"intensity", l.intensity}},
                           {{"rotation", rotationFromMinusZ(l.direction)}});
        }
        j["extensions"]["KHR_lights_punctual"] = {{"lights", lights}};
        j["extensionsUsed"].push_back("KHR_lights_punctual");
    }
    if (uses_strength) {
        j["extensionsUsed"].push_back("KHR_materials_emissive_strength");
    }
    j["buffers"] = Json::array({{{"uri", bin_name}, {"byteLength", bin.size()}}});
    return j;
}

} // namespace

std::vector<std::string> generatedSceneNames() {
    return {"cornell", "thin-wall", "courtyard", "courtyard-overcast"};
}

Result<void> writeGeneratedScene(const std::string& name, const std::filesystem::path& path) {
    SceneSpec spec;
    if (name == "cornell") {
        spec = cornell();
    } else if (name == "thin-wall") {
        spec = thinWall();
    } else if (name == "courtyard") {
        spec = courtyard();
    } else if (name == "courtyard-overcast") {
        spec = courtyard();
        spec.suns.clear(); // lit by the bake's sky alone
    } else {
        return makeError(ErrorCode::InvalidArgument,
                         "unknown scene '" + name +
                             "' (known: cornell, thin-wall, courtyard, courtyard-overcast)");
    }
    std::filesystem::path bin_path = path;
    bin_path.replace_extension(".bin");
    std::vector<uint8_t> bin;
    const Json gltf = buildGltf(spec, bin_path.filename().string(), bin);
    // The buffer first: a reader never sees a .gltf whose .bin is missing or stale.
    if (auto w = writeFileAtomic(bin_path, bin); !w) {
        return w;
    }
    return writeFileAtomic(path, std::string_view(gltf.dump(1)));
}

} // namespace probekit::baker
