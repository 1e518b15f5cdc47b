// libFuzzer target: untrusted glTF / GLB bytes through tinygltf and the loader (loadGltfBytes),
// as `probekit bake` and `probekit info` load a scene. The scene's folder is an empty temporary
// one, so external URIs resolve to nothing (the file-access rule is tested in the bake suite);
// data: URIs and GLB chunks carry what the fuzzer makes. The loader's asset budget is lowered
// to 256 MiB so that an input predicted to need more is refused before it is allocated, well
// inside libFuzzer's memory limit.
//
// Beyond "no crash, no hang, no sanitizer report": a scene that loads has finite vertices
// inside its bounds, indices inside its vertex arrays, one material per triangle, and finite
// light and material values (what the integrators multiply).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <span>

#include "probekit/baker/scene.hpp"

namespace {

// Prints why the input is a failure, then aborts so libFuzzer saves it.
[[noreturn]] void fail(const char* why) {
    std::fprintf(stderr, "fuzz_gltf: %s\n", why);
    std::abort();
}

const std::filesystem::path& sceneFolder() {
    static const std::filesystem::path folder = [] {
        std::filesystem::path p = std::filesystem::temp_directory_path() / "probekit-fuzz-gltf";
        std::filesystem::create_directories(p);
        return p;
    }();
    return folder;
}

bool finite(glm::vec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void checkScene(const probekit::baker::Scene& scene) {
    const size_t vertices = scene.positions.size();
    if (scene.triangleMaterial.size() != scene.triangles.size()) {
        fail("triangles and their materials differ in count");
    }
    for (const glm::uvec3& t : scene.triangles) {
        if (t.x >= vertices || t.y >= vertices || t.z >= vertices) {
            fail("a triangle indexes past the vertex array");
        }
    }
    for (const uint32_t m : scene.triangleMaterial) {
        if (m >= scene.materials.size()) {
            fail("a triangle names a material that does not exist");
        }
    }
    const glm::vec3 slack = 1e-3f * (glm::abs(scene.bounds.min) + glm::abs(scene.bounds.max));
    for (const glm::vec3& p : scene.positions) {
        if (!finite(p)) {
            fail("a non-finite vertex reached the scene");
        }
        if (glm::any(glm::lessThan(p, scene.bounds.min - slack)) ||
            glm::any(glm::greaterThan(p, scene.bounds.max + slack))) {
            fail("a vertex lies outside the scene bounds");
        }
    }
    for (const probekit::PunctualLight& light : scene.lights) {
        if (!finite(light.intensity) || !finite(light.position) || !finite(light.direction)) {
            fail("a light with a non-finite intensity, position or direction was loaded");
        }
    }
    for (const probekit::baker::Material& material : scene.materials) {
        if (!finite(material.baseColor) || !finite(material.emission)) {
            fail("a material with a non-finite colour or emission was loaded");
        }
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    probekit::baker::LoadOptions options;
    options.maxMemoryBytes = 256ull << 20;
    // The name decides text or binary only through the GLB magic; both kinds reach the parser.
    const auto scene = probekit::baker::loadGltfBytes(std::span<const uint8_t>(data, size),
                                                      sceneFolder() / "fuzz.gltf", options);
    if (scene) {
        checkScene(scene.value());
    }
    return 0;
}
