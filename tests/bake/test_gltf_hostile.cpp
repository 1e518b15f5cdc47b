// glTF input written to hurt (issue 17): nesting deep enough to overflow a recursive parser,
// URIs that reach outside the scene's folder or name FIFOs, counts that amplify a small file into
// gigabytes, damaged GLB containers, glTF 1.0 and 3.0, values that overflow a float, fields of
// the wrong JSON kind, node cycles. Every file is written here, into a temporary folder; each
// case asserts the exact reason the loader gives, naming the file and the field.
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "gltf_test_support.hpp"
#include "probekit/baker/scene.hpp"

using namespace probekit;
using namespace probekit::baker;
using namespace probekit::test;

namespace {

// The quad document (one triangle of kQuad's first three corners) as a .gltf with an embedded
// buffer, after `edit` (which sees the buffer too).
fs::path quadFile(const TempDir& dir, const std::string& name,
                  const std::function<void(json&)>& edit = {}) {
    const fs::path file = quadDocument(4, nullptr).writeEmbedded(dir / name);
    if (edit) {
        json doc = json::parse(readText(file));
        edit(doc);
        writeText(file, doc.dump(1));
    }
    return file;
}

// The error loadGltf gives, or a note that it loaded.
std::string loadError(const fs::path& file, const LoadOptions& options = {}) {
    const Result<Scene> scene = loadGltf(file, options);
    return scene.ok() ? "(loaded)" : scene.error().message;
}

// `file: what`, the form of every message.
std::string at(const fs::path& file, const std::string& what) {
    return file.string() + ": " + what;
}

std::string canonicalString(const fs::path& path) {
    return fs::canonical(path).string();
}

// A GLB from its parts, each of which a case may damage.
struct GlbParts {
    uint32_t version = 2;
    std::optional<uint32_t> length; // default: the true total
    std::string json;
    std::optional<uint32_t> jsonLength;
    uint32_t jsonType = 0x4E4F534A;
    std::vector<uint8_t> bin;
    std::optional<uint32_t> binLength;
    uint32_t binType = 0x004E4942;
};

std::vector<uint8_t> glbBytes(const GlbParts& parts) {
    std::vector<uint8_t> out;
    auto le32 = [&](uint32_t v) {
        for (int shift = 0; shift < 32; shift += 8) {
            out.push_back(static_cast<uint8_t>(v >> shift));
        }
    };
    const size_t total =
        12 + 8 + parts.json.size() + (parts.bin.empty() ? 0 : 8 + parts.bin.size());
    out.insert(out.end(), {'g', 'l', 'T', 'F'});
    le32(parts.version);
    le32(parts.length.value_or(static_cast<uint32_t>(total)));
    le32(parts.jsonLength.value_or(static_cast<uint32_t>(parts.json.size())));
    le32(parts.jsonType);
    out.insert(out.end(), parts.json.begin(), parts.json.end());
    if (!parts.bin.empty()) {
        le32(parts.binLength.value_or(static_cast<uint32_t>(parts.bin.size())));
        le32(parts.binType);
        out.insert(out.end(), parts.bin.begin(), parts.bin.end());
    }
    return out;
}

// The quad (4 float3 positions, no indices) as GLB parts: JSON padded to 4 bytes, 48-byte BIN.
GlbParts quadGlb() {
    std::vector<float> positions;
    for (const glm::vec3& p : kQuad) {
        positions.insert(positions.end(), {p.x, p.y, p.z});
    }
    GlbParts parts;
    parts.bin.resize(positions.size() * sizeof(float));
    std::memcpy(parts.bin.data(), positions.data(), parts.bin.size());
    json doc = {{"asset", {{"version", "2.0"}}},
                {"buffers", {{{"byteLength", parts.bin.size()}}}},
                {"bufferViews", {{{"buffer", 0}, {"byteLength", parts.bin.size()}}}},
                {"accessors",
                 {{{"bufferView", 0}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}}}},
                {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}}}}}}},
                {"nodes", {{{"mesh", 0}}}},
                {"scenes", {{{"nodes", {0}}}}}};
    parts.json = doc.dump();
    while (parts.json.size() % 4 != 0) {
        parts.json += ' ';
    }
    return parts;
}

// A PNG whose header says width x height; its pixel data is absent, which only matters if the
// loader decodes it (the limits refuse it from the header alone).
std::vector<uint8_t> pngHeaderOnly(uint32_t width, uint32_t height) {
    std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    std::vector<uint8_t> header;
    appendBe32(header, width);
    appendBe32(header, height);
    header.insert(header.end(), {8, 6, 0, 0, 0}); // 8-bit RGBA
    appendPngChunk(png, "IHDR", header);
    appendPngChunk(png, "IEND", {});
    return png;
}

// The quad with images[0] (used as base colour texture) at `uri`.
void addTexture(json& doc, const std::string& uri) {
    doc["images"] = {{{"uri", uri}}};
    doc["textures"] = {{{"source", 0}}};
    doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
    doc["meshes"][0]["primitives"][0]["material"] = 0;
}

// The quad plus node 1 carrying KHR_lights_punctual light `node_light` of `lights`.
void addLight(json& doc, const json& light, const json& node_light = 0) {
    doc["extensionsUsed"] = {"KHR_lights_punctual"};
    doc["extensions"]["KHR_lights_punctual"]["lights"] = {light};
    doc["nodes"].push_back({{"translation", {0, 0, 1}},
                            {"extensions", {{"KHR_lights_punctual", {{"light", node_light}}}}}});
    doc["scenes"][0]["nodes"].push_back(1);
}

// The quad file whose mesh is instead `count` VEC3 positions backed by nothing but one sparse
// value (accessors[1]), instanced by `instances` nodes.
fs::path sparseInstances(const TempDir& dir, const std::string& name, uint32_t count,
                         int instances = 16) {
    return quadFile(dir, name, [&](json& d) {
        d["accessors"].push_back({{"componentType", 5126},
                                  {"count", count},
                                  {"type", "VEC3"},
                                  {"sparse",
                                   {{"count", 1},
                                    {"indices", {{"bufferView", 0}, {"componentType", 5121}}},
                                    {"values", {{"bufferView", 0}}}}}});
        d["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", 1}}}}}}}};
        d["nodes"] = json::array();
        for (int i = 0; i < instances; ++i) {
            d["nodes"].push_back({{"mesh", 0}});
            d["scenes"][0]["nodes"][i] = i;
        }
    });
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Item 2: nesting

TEST(GltfHostile, NestingBeyond512LevelsIsRefusedBeforeParsing) {
    TempDir dir;
    // The root object is level 1, so extras of n nested arrays reach level n + 1.
    auto nested = [&](const std::string& name, size_t arrays) {
        const fs::path file = quadFile(dir, name);
        std::string text = readText(file);
        while (text.back() != '}') {
            text.pop_back();
        }
        text.pop_back(); // the root's closing brace
        writeText(file, text + ",\"extras\":" + std::string(arrays, '[') +
                            std::string(arrays, ']') + "}");
        return file;
    };
    const fs::path deep = nested("deep.gltf", 20000);
    const std::string deep_text = readText(deep);
    // The 512th bracket of extras opens level 513.
    const size_t level_513 = deep_text.find('[', deep_text.find("extras")) + 511;
    EXPECT_EQ(loadError(deep),
              at(deep, "JSON arrays and objects nest 20001 levels deep (level 513 opens at byte " +
                           std::to_string(level_513) +
                           "), more than the limit of 512 (a glTF nests about 8; the limit keeps "
                           "the parser's recursion within its stack)"));
    EXPECT_TRUE(loadGltf(nested("at_limit.gltf", 511)).ok()) << loadError(dir / "at_limit.gltf");
    EXPECT_TRUE(contains(loadError(nested("over_limit.gltf", 512)), "nest 513 levels deep"));
    // Brackets inside strings, escaped quotes included, are not nesting.
    const fs::path strings = quadFile(dir, "strings.gltf", [](json& d) {
        d["extras"] = std::string(30000, '[') + "\\\"" + std::string(30000, '{');
    });
    EXPECT_TRUE(loadGltf(strings).ok()) << loadError(strings);

    // In a GLB the JSON chunk is scanned; offsets count from the start of the file.
    GlbParts parts = quadGlb();
    while (parts.json.back() == ' ') {
        parts.json.pop_back();
    }
    parts.json.pop_back(); // the root's closing brace
    parts.json += ",\"extras\":" + std::string(1000, '[') + std::string(1000, ']') + "}";
    while (parts.json.size() % 4 != 0) {
        parts.json += ' ';
    }
    const fs::path glb = dir / "deep.glb";
    const std::vector<uint8_t> bytes = glbBytes(parts);
    writeBytes(glb, bytes.data(), bytes.size());
    EXPECT_EQ(
        loadError(glb),
        at(glb, "JSON arrays and objects nest 1001 levels deep (level 513 opens at byte " +
                    std::to_string(20 + parts.json.find('[', parts.json.find("extras")) + 511) +
                    "), more than the limit of 512 (a glTF nests about 8; the limit keeps "
                    "the parser's recursion within its stack)"));
}

// ---------------------------------------------------------------------------------------------
// Items 6 and 7: which files a URI may name

TEST(GltfHostile, UrisReachOnlyRegularFilesUnderTheSceneFolder) {
    TempDir dir;
    // dir/secret.bin lies outside the scene folder dir/scene; its bytes and size must not show.
    const std::string secret = "SECRET-CONTENTS-" + std::string(1000, 'x');
    writeText(dir / "secret.bin", secret);
    fs::create_directories(dir / "scene");
    const std::string folder = canonicalString(dir / "scene");
    const std::string outside = "resolves outside the scene's folder " + folder +
                                "; probekit reads only regular files under it and under the "
                                "folders of LoadOptions::assetRoots (--asset-root)";
    auto bufferAt = [&](const std::string& name, const std::string& uri) {
        return quadFile(dir, "scene/" + name, [&](json& d) {
            d["buffers"] = {{{"byteLength", 48}, {"uri", uri}}};
        });
    };

    const fs::path dotdot = bufferAt("dotdot.gltf", "../secret.bin");
    EXPECT_EQ(loadError(dotdot), at(dotdot, "buffers[0].uri '../secret.bin' " + outside));
    const fs::path passwd = bufferAt("passwd.gltf", "../../../../../../../../etc/passwd");
    EXPECT_EQ(loadError(passwd),
              at(passwd, "buffers[0].uri '../../../../../../../../etc/passwd' " + outside));
    // Percent-encoding is decoded (as tinygltf does) before the rule applies.
    const fs::path encoded = bufferAt("encoded.gltf", "%2e%2e/secret.bin");
    EXPECT_EQ(loadError(encoded), at(encoded, "buffers[0].uri '%2e%2e/secret.bin' " + outside));
    // A link inside the folder that points out is judged by its target.
    fs::create_symlink(dir / "secret.bin", dir / "scene/link.bin");
    const fs::path link = bufferAt("link.gltf", "link.bin");
    EXPECT_EQ(loadError(link), at(link, "buffers[0].uri 'link.bin' " + outside));
    // A path outside that does not exist gets the same answer: no existence oracle.
    const fs::path nowhere = bufferAt("nowhere.gltf", "../no-such-file.bin");
    EXPECT_EQ(loadError(nowhere), at(nowhere, "buffers[0].uri '../no-such-file.bin' " + outside));
    // A decoded NUL would cut the path short where the file is opened.
    const fs::path nul = bufferAt("nul.gltf", "inside.bin%00../secret.bin");
    EXPECT_EQ(loadError(nul), at(nul, "buffers[0].uri 'inside.bin%00../secret.bin' holds a NUL "
                                      "byte"));
    for (const fs::path& file : {dotdot, encoded, link}) {
        const std::string message = loadError(file);
        EXPECT_FALSE(contains(message, "SECRET")) << message;
        EXPECT_FALSE(contains(message, std::to_string(secret.size()))) << message;
    }

    // Absolute URIs are refused even when they point inside the folder.
    const std::string absolute_inside = (dir / "scene/inside.bin").string();
    writeText(absolute_inside, std::string(48, '\0'));
    const fs::path absolute = bufferAt("absolute.gltf", absolute_inside);
    EXPECT_EQ(loadError(absolute),
              at(absolute, "buffers[0].uri '" + absolute_inside +
                               "' is an absolute path; probekit reads only paths relative to the "
                               "scene's folder"));
    const fs::path etc = bufferAt("etc.gltf", "/etc/passwd");
    EXPECT_EQ(loadError(etc), at(etc, "buffers[0].uri '/etc/passwd' is an absolute path; probekit "
                                      "reads only paths relative to the scene's folder"));

    // Only regular files: a FIFO (opening it would block), the folder itself, a subfolder.
    ASSERT_EQ(::mkfifo((dir / "scene/fifo").c_str(), 0600), 0);
    const fs::path fifo = bufferAt("fifo.gltf", "fifo");
    EXPECT_EQ(loadError(fifo), at(fifo, "buffers[0].uri 'fifo' names a FIFO, not a regular file"));
    const fs::path dot = bufferAt("dot.gltf", ".");
    EXPECT_EQ(loadError(dot), at(dot, "buffers[0].uri '.' names a directory, not a regular file"));
    const fs::path fifo_image =
        quadFile(dir, "scene/fifo_image.gltf", [](json& d) { addTexture(d, "fifo"); });
    EXPECT_EQ(loadError(fifo_image),
              at(fifo_image, "images[0].uri 'fifo' names a FIFO, not a regular file"));
    const fs::path outside_image =
        quadFile(dir, "scene/outside_image.gltf", [](json& d) { addTexture(d, "../secret.bin"); });
    EXPECT_EQ(loadError(outside_image),
              at(outside_image, "images[0].uri '../secret.bin' " + outside));

    // A file inside, named relatively, still loads.
    GltfBuilder builder = quadDocument(4, nullptr);
    fs::create_directories(dir / "scene/sub");
    const fs::path inside = builder.writeExternal(dir / "scene/sub/quad.gltf");
    EXPECT_TRUE(loadGltf(inside).ok()) << loadError(inside);
}

TEST(GltfHostile, AMissingUriIsNotLookedUpInTheWorkingDirectory) {
    TempDir dir;
    fs::create_directories(dir / "cwd");
    fs::create_directories(dir / "scene");
    // The right bytes for the buffer, but in the working directory, not beside the scene.
    GltfBuilder builder = quadDocument(4, nullptr);
    const fs::path external = builder.writeExternal(dir / "cwd/quad.gltf");
    const fs::path file = dir / "scene/quad.gltf";
    fs::copy_file(external, file);
    const fs::path previous = fs::current_path();
    fs::current_path(dir / "cwd");
    const std::string message = loadError(file);
    fs::current_path(previous);
    EXPECT_EQ(message, at(file, "buffers[0].uri 'quad.bin': no such file in " +
                                    canonicalString(dir / "scene")));
}

// A URI is a path with percent-escapes (RFC 3986): '+' is itself, as every exporter means it,
// though tinygltf's decoder takes it for a space (issue 31, class 7: refused as "no such
// file"). The loader reads the file the URI names, and lists it in Scene::files.
TEST(GltfHostile, APlusInAUriIsAPlusAndPercentEscapesAreDecoded) {
    TempDir dir;
    GltfBuilder builder = quadDocument(4, nullptr);
    const fs::path plus = builder.writeExternal(dir / "a+b.gltf");
    Result<baker::Scene> loaded = loadGltf(plus);
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    ASSERT_EQ(loaded.value().files.size(), 2u);
    EXPECT_EQ(loaded.value().files[0], plus);
    EXPECT_EQ(loaded.value().files[1].filename(), "a+b.bin");
    // "%20" is a space; a file named with a '+' where the URI has a space is not read.
    const fs::path spaced = builder.writeExternal(dir / "c d.gltf");
    json doc = json::parse(readText(spaced));
    doc["buffers"][0]["uri"] = "c%20d.bin";
    writeText(dir / "escaped.gltf", doc.dump());
    EXPECT_TRUE(loadGltf(dir / "escaped.gltf").ok()) << loadError(dir / "escaped.gltf");
    fs::rename(dir / "c d.bin", dir / "c+d.bin");
    EXPECT_EQ(loadError(dir / "escaped.gltf"),
              at(dir / "escaped.gltf",
                 "buffers[0].uri 'c%20d.bin': no such file in " + canonicalString(dir / ".")));
}

TEST(GltfHostile, AssetRootsAllowMoreFoldersButNeverAbsoluteUris) {
    TempDir dir;
    fs::create_directories(dir / "scene");
    fs::create_directories(dir / "shared");
    GltfBuilder builder = quadDocument(4, nullptr);
    builder.writeExternal(dir / "shared/quad.gltf"); // writes shared/quad.bin
    const fs::path file = quadFile(dir, "scene/quad.gltf", [](json& d) {
        d["buffers"] = {{{"byteLength", 48}, {"uri", "../shared/quad.bin"}}};
    });
    EXPECT_TRUE(contains(loadError(file), "resolves outside the scene's folder"));
    LoadOptions options;
    options.assetRoots = {dir / "shared"};
    const Result<Scene> scene = loadGltf(file, options);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    EXPECT_EQ(scene.value().triangles.size(), 1u);

    const std::string absolute_uri = canonicalString(dir / "shared/quad.bin");
    const fs::path absolute = quadFile(dir, "scene/absolute.gltf", [&](json& d) {
        d["buffers"] = {{{"byteLength", 48}, {"uri", absolute_uri}}};
    });
    EXPECT_TRUE(contains(loadError(absolute, options), "is an absolute path"))
        << loadError(absolute);

    options.assetRoots = {dir / "no-such-folder"};
    EXPECT_EQ(loadError(file, options), "LoadOptions::assetRoots: '" +
                                            (dir / "no-such-folder").string() +
                                            "' is not an existing folder");
}

// ---------------------------------------------------------------------------------------------
// Item 12: memory

TEST(GltfHostile, ASparseAccessorCannotAmplifyBeyondTheMemoryLimit) {
    TempDir dir;
    // 2^24 VEC3 positions backed by nothing but one sparse value, instanced by 16 nodes: a
    // 2 KB file whose instances expand to 16 x (2^24 x 32 + 5592405 x 20) bytes of scene
    // arrays. The sum is refused before the first instance is built (before the up-front sum,
    // the first copies were built and held first: 1.9 GB, 12 s with 21 instances at 4 GiB).
    const fs::path file = sparseInstances(dir, "sparse.gltf", 1 << 24);
    LoadOptions options;
    options.maxMemoryBytes = 128ull << 20;
    const std::string message = loadError(file, options);
    EXPECT_TRUE(contains(message, at(file, "adding every mesh instance to the scene (268435456 "
                                           "vertices and 89478480 triangles; the most from "
                                           "meshes[0], used by 16 nodes) needs 10379504192 "
                                           "bytes; with ")))
        << message;
    EXPECT_TRUE(contains(message, " bytes already loaded that exceeds the memory limit of "
                                  "134217728 bytes (LoadOptions::maxMemoryBytes; probekit bake: "
                                  "max_memory_mb)"))
        << message;
}

TEST(GltfHostile, TheSceneItselfIsChargedAsItGrows) {
    TempDir dir;
    // 2^20 vertices (one sparse value) per instance: 12 MiB of positions, and beyond them
    // 1048576 x (12 world position + 4 remap) bytes + 1048576 / 8 + 1 finite flags + 349525 x 12
    // corners while the instance loads, and 1048576 x (12 + 8 + 12) + 349525 x (12 + 4 + 4)
    // bytes of Scene arrays for the first instance.
    // One instance: its scene arrays (40544932 bytes) pass the up-front sum at 64 MiB and are
    // reserved; the primitive's work arrays (21102589 bytes) on top of them do not fit.
    const fs::path one = sparseInstances(dir, "one_instance.gltf", 1 << 20, 1);
    LoadOptions options;
    options.maxMemoryBytes = 64ull << 20;
    EXPECT_TRUE(contains(loadError(one, options),
                         at(one, "meshes[0].primitives[0] (1048576 vertices, 349525 triangles, "
                                 "expanded and added to the scene) needs 21102589 bytes; with ")))
        << loadError(one, options);
    // Five instances (202724660 bytes up front) pass the sum at 256 MiB. The arrays are
    // reserved at that sum before the first instance, so they hold exactly it when the scene
    // is loaded: grown instance by instance, they doubled past it and a later instance was
    // refused (the up-front check missed the growth).
    const fs::path five = sparseInstances(dir, "instances.gltf", 1 << 20, 5);
    options.maxMemoryBytes = 256ull << 20;
    const Result<Scene> loaded = loadGltf(five, options);
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    const Scene& s = loaded.value();
    const auto held = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    EXPECT_EQ(held(s.positions) + held(s.uvs) + held(s.normals) + held(s.triangles) +
                  held(s.triangleMaterial) + held(s.triangleNode),
              5u * 40544932u);
    // Seven (283814524 bytes) are refused by the sum, before any instance is built.
    const fs::path seven = sparseInstances(dir, "seven.gltf", 1 << 20, 7);
    EXPECT_TRUE(contains(loadError(seven, options),
                         at(seven, "adding every mesh instance to the scene (7340032 vertices and "
                                   "2446675 triangles; the most from meshes[0], used by 7 nodes) "
                                   "needs 283814524 bytes; with ")))
        << loadError(seven, options);

    // sceneBytes counts the arrays' storage: the quad's primitive reserves its 4 vertices and
    // 1 triangle; one material, one node.
    const Result<Scene> scene = loadGltf(quadFile(dir, "one.gltf"));
    ASSERT_TRUE(scene.ok());
    EXPECT_EQ(sceneBytes(scene.value()),
              4u * (12u + 8u + 12u) + 1u * (12u + 4u + 4u) + sizeof(Material) + sizeof(SceneNode));
}

TEST(GltfHostile, ImagesAreMeasuredFromTheirHeaderBeforeDecoding) {
    TempDir dir;
    // 12000 x 12000 pixels in a few dozen bytes: refused by the pixel limit at any budget.
    const std::vector<uint8_t> huge = pngHeaderOnly(12000, 12000);
    writeBytes(dir / "huge.png", huge.data(), huge.size());
    const fs::path big = quadFile(dir, "big.gltf", [](json& d) { addTexture(d, "huge.png"); });
    EXPECT_EQ(loadError(big),
              at(big, "images[0] 'huge.png' is 12000 x 12000 pixels, more than the limit of "
                      "67108864 (8192 x 8192)"));

    // 1024 x 1024 is within the pixel limit but not within a 16 MiB budget: stb's 4 MiB buffer,
    // tinygltf's 4 MiB copy and the baker's 16 MiB of float texels.
    const std::vector<uint8_t> medium = pngHeaderOnly(1024, 1024);
    const fs::path embedded = quadFile(dir, "medium.gltf", [&](json& d) {
        addTexture(d, "data:image/png;base64," + base64(medium));
    });
    LoadOptions options;
    options.maxMemoryBytes = 16ull << 20;
    const std::string message = loadError(embedded, options);
    EXPECT_TRUE(contains(message, at(embedded, "images[0] (data: URI) (1024 x 1024 pixels, "
                                               "decoded) needs 25165824 bytes; with ")))
        << message;
    EXPECT_TRUE(contains(message, "exceeds the memory limit of 16777216 bytes")) << message;
}

// A texture whose "source" is a PNG fallback beside a WebP (EXT_texture_webp) or KTX2
// (KHR_texture_basisu) source, as the glTF extensions specify, loads with the PNG; the other
// image is never decoded (issue 31, class 7: refused as not an image). An image the decoder
// cannot read where a material needs it is named by its URI.
TEST(GltfHostile, ATextureWithAPngFallbackBesideWebpOrKtx2Loads) {
    TempDir dir;
    const std::vector<uint8_t> png = encodePng(1, 1, 8, {255, 255, 255, 255});
    writeBytes(dir / "white.png", png.data(), png.size());
    writeText(dir / "white.webp", "RIFF\x10\0\0\0WEBPVP8 not decoded here");
    writeText(dir / "white.ktx2", "\xabKTX 20\xbb\r\n\x1a\n not decoded here");
    for (const char* extension : {"EXT_texture_webp", "KHR_texture_basisu"}) {
        SCOPED_TRACE(extension);
        const std::string other =
            std::string(extension) == "EXT_texture_webp" ? "white.webp" : "white.ktx2";
        const fs::path file = quadFile(dir, "fallback.gltf", [&](json& d) {
            addTexture(d, "white.png");
            d["images"].push_back({{"uri", other}});
            d["textures"][0]["extensions"] = {{extension, {{"source", 1}}}};
            d["extensionsUsed"] = {extension};
        });
        const Result<Scene> scene = loadGltf(file);
        ASSERT_TRUE(scene.ok()) << scene.error().message;
        ASSERT_EQ(scene.value().images.size(), 1u);
        EXPECT_EQ(scene.value().images[0].width, 1u);
    }
    const fs::path webp_only =
        quadFile(dir, "webp.gltf", [](json& d) { addTexture(d, "white.webp"); });
    EXPECT_EQ(loadError(webp_only), at(webp_only, "images[0] 'white.webp' is not an image the "
                                                  "decoder reads (PNG or JPEG)"));
}

TEST(GltfHostile, BufferSizesAreCheckedAgainstTheirDataAndTheBudget) {
    TempDir dir;
    const fs::path huge = quadFile(
        dir, "huge.gltf", [](json& d) { d["buffers"][0]["byteLength"] = uint64_t(1) << 40; });
    // 48 bytes are 64 base64 characters.
    EXPECT_EQ(loadError(huge), at(huge, "buffers[0].byteLength 1099511627776 is more than its "
                                        "data: URI holds (at most 48 bytes)"));
    // Files larger than the budget are refused before they are read: the scene file, and an
    // external buffer (1 MiB against 512 KiB).
    const fs::path scene = quadFile(dir, "scene.gltf");
    LoadOptions options;
    options.maxMemoryBytes = 100;
    EXPECT_TRUE(loadError(scene, options)
                    .starts_with(scene.string() + " needs " + std::to_string(fs::file_size(scene)) +
                                 " bytes; with 0 bytes already loaded"))
        << loadError(scene, options);
    const std::vector<uint8_t> big(1 << 20, 0);
    writeBytes(dir / "big.bin", big.data(), big.size());
    const fs::path external = quadFile(dir, "external.gltf", [](json& d) {
        d["buffers"] = {{{"byteLength", 1 << 20}, {"uri", "big.bin"}}};
    });
    options.maxMemoryBytes = 512 << 10;
    const std::string message = loadError(external, options);
    EXPECT_TRUE(contains(message, at(external, "URI 'big.bin' needs 1048576 bytes; with ")))
        << message;
    EXPECT_TRUE(loadGltf(external).ok()) << loadError(external);
}

// ---------------------------------------------------------------------------------------------
// Items 14 and 15: versions, containers, extensions, kinds, values

TEST(GltfHostile, OnlyGltf2IsRead) {
    TempDir dir;
    const fs::path v1 = dir / "v1.gltf";
    writeText(v1, R"({"asset": {"version": "1.0"}, "scene": "defaultScene",
                      "scenes": {"defaultScene": {"nodes": []}}, "meshes": {}})");
    EXPECT_EQ(loadError(v1), at(v1, "asset.version '1.0': this is a glTF 1.0 file, which probekit "
                                    "does not read (it reads glTF 2.x; re-export the scene as "
                                    "glTF 2.0)"));
    const fs::path v3 = quadFile(dir, "v3.gltf", [](json& d) { d["asset"]["version"] = "3.0"; });
    EXPECT_EQ(loadError(v3), at(v3, "asset.version '3.0': probekit reads glTF 2.x only"));
    const fs::path min21 =
        quadFile(dir, "min21.gltf", [](json& d) { d["asset"]["minVersion"] = "2.1"; });
    EXPECT_EQ(loadError(min21), at(min21, "asset.minVersion '2.1': the file needs a loader of "
                                          "that glTF version; probekit implements glTF 2.0"));
    // A later minor version without minVersion is meant to load (glTF's forward compatibility).
    const fs::path v21 = quadFile(dir, "v21.gltf", [](json& d) { d["asset"]["version"] = "2.1"; });
    EXPECT_TRUE(loadGltf(v21).ok()) << loadError(v21);

    GlbParts parts = quadGlb();
    parts.version = 1;
    const fs::path glb1 = dir / "v1.glb";
    std::vector<uint8_t> bytes = glbBytes(parts);
    writeBytes(glb1, bytes.data(), bytes.size());
    EXPECT_EQ(loadError(glb1), at(glb1, "GLB byte 4: container version 1 is glTF 1.0 "
                                        "(KHR_binary_glTF), which probekit does not read; it "
                                        "reads glTF 2.x (container version 2)"));
}

TEST(GltfHostile, EachKindOfGlbDamageNamesItsByteOffset) {
    TempDir dir;
    const GlbParts good = quadGlb();
    const size_t size = glbBytes(good).size();
    const size_t bin_at = 20 + good.json.size();
    struct Case {
        std::string name;
        std::function<void(GlbParts&)> damage;
        std::string expected;
        std::function<void(std::vector<uint8_t>&)> cut = {}; // damage to the built bytes
    };
    const std::string file_size = "the file has " + std::to_string(size) + " bytes";
    const std::vector<Case> cases = {
        {"zero_length", [](GlbParts& p) { p.length = 0; },
         "GLB byte 8: total length 0, expected the file's size, " + std::to_string(size)},
        {"long_length", [&](GlbParts& p) { p.length = uint32_t(size + 100); },
         "GLB byte 8: total length " + std::to_string(size + 100) + " but " + file_size +
             ": the file is truncated"},
        {"truncated", [](GlbParts&) {},
         "GLB byte 8: total length " + std::to_string(size) + " but the file has " +
             std::to_string(size - 10) + " bytes: the file is truncated",
         [](std::vector<uint8_t>& b) { b.erase(b.end() - 10, b.end()); }},
        {"huge_bin", [](GlbParts& p) { p.binLength = 0xFFFFFFF0u; },
         "GLB byte " + std::to_string(bin_at) + ": chunk 1 length 4294967280 runs to byte " +
             std::to_string(bin_at + 8 + 0xFFFFFFF0ull) + ", past the end (" + file_size + ")"},
        {"huge_json", [](GlbParts& p) { p.jsonLength = 0xFFFFFFF0u; },
         "GLB byte 12: JSON chunk length 4294967280 runs to byte 4294967300, past the end (" +
             file_size + ")"},
        {"empty_json", [](GlbParts& p) { p.jsonLength = 0; },
         "GLB byte 12: JSON chunk length 0, expected the length of the JSON text"},
        {"bin_type", [](GlbParts& p) { p.binType = 0x12345678; },
         "GLB byte " + std::to_string(bin_at + 4) +
             ": second chunk type 0x12345678, expected BIN (0x004E4942)"},
        {"json_type", [](GlbParts& p) { p.jsonType = 0x4E4F534B; },
         "GLB byte 16: first chunk type 0x4E4F534B, expected JSON (0x4E4F534A)"},
        {"bin_unpadded", [](GlbParts& p) { p.binLength = 46; },
         "GLB byte " + std::to_string(bin_at) +
             ": chunk 1 (BIN) length 46, expected a positive multiple of 4 (chunks are padded to "
             "4 bytes; an empty BIN chunk is left out)"},
        {"version_3", [](GlbParts& p) { p.version = 3; },
         "GLB byte 4: container version 3, expected 2 (glTF 2.x)"},
        {"header_only", [](GlbParts&) {},
         "GLB header truncated: it needs 12 bytes, the file has 8 bytes",
         [](std::vector<uint8_t>& b) { b.resize(8); }},
    };
    for (const Case& c : cases) {
        GlbParts parts = good;
        c.damage(parts);
        std::vector<uint8_t> bytes = glbBytes(parts);
        if (c.cut) {
            c.cut(bytes);
        }
        const fs::path file = dir / (c.name + ".glb");
        writeBytes(file, bytes.data(), bytes.size());
        EXPECT_EQ(loadError(file), at(file, c.expected)) << c.name;
    }
    // The undamaged container loads.
    const std::vector<uint8_t> bytes = glbBytes(good);
    writeBytes(dir / "good.glb", bytes.data(), bytes.size());
    EXPECT_TRUE(loadGltf(dir / "good.glb").ok()) << loadError(dir / "good.glb");
}

TEST(GltfHostile, OnlyTheFirstBufferOfAGlbIsItsBinChunk) {
    TempDir dir;
    // A second buffer without a uri, its view read by the accessor: before, tinygltf handed it
    // the BIN chunk and the quad loaded from bytes the file never gave that buffer.
    GlbParts parts = quadGlb();
    json doc = json::parse(parts.json);
    doc["buffers"].push_back({{"byteLength", parts.bin.size()}});
    doc["bufferViews"][0]["buffer"] = 1;
    parts.json = doc.dump();
    while (parts.json.size() % 4 != 0) {
        parts.json += ' ';
    }
    const std::vector<uint8_t> bytes = glbBytes(parts);
    const fs::path file = dir / "second.glb";
    writeBytes(file, bytes.data(), bytes.size());
    EXPECT_EQ(loadError(file), at(file, "buffers[1] has no uri (in a GLB only buffers[0], the BIN "
                                        "chunk, may leave it out)"));
}

TEST(GltfHostile, AKeyGivenTwiceInOneObjectIsRefusedWithItsPath) {
    TempDir dir;
    const fs::path good = quadFile(dir, "good.gltf");
    ASSERT_TRUE(loadGltf(good).ok()) << loadError(good);
    const std::string text = readText(good);
    // Writes `text` with `insert` put just after the first `key` it holds.
    const auto repeated = [&](const std::string& name, const std::string& key,
                              const std::string& insert) {
        std::string edited = text;
        const size_t at_key = edited.find(key);
        EXPECT_NE(at_key, std::string::npos) << key;
        edited.insert(at_key + key.size(), insert);
        const fs::path file = dir / name;
        writeText(file, edited);
        return file;
    };
    // An empty array first and the real one after: readers that keep the last would load the
    // quad, readers that keep the first an empty scene. The file is refused either way.
    const fs::path views = repeated("views.gltf", "{", "\"bufferViews\": [],");
    EXPECT_EQ(loadError(views), at(views, "bufferViews: given twice (glTF 2.0 forbids a key "
                                          "repeated in one object; readers would keep only "
                                          "the last)"));
    // Inside an array element, the path names the element.
    const fs::path node =
        repeated("node.gltf", "\"nodes\"", ": [{\"mesh\": 0, \"mesh\": 0}], \"x\"");
    const std::string message = loadError(node);
    EXPECT_NE(message.find("nodes[0].mesh: given twice"), std::string::npos) << message;
    // The same key in two different objects is not a repeat.
    const fs::path names = quadFile(dir, "names.gltf", [](json& d) {
        d["nodes"][0]["name"] = "quad";
        d["meshes"][0]["name"] = "quad";
    });
    EXPECT_TRUE(loadGltf(names).ok()) << loadError(names);
}

TEST(GltfHostile, DracoIsNamedAsAnUnsupportedRequiredExtension) {
    TempDir dir;
    // Draco files carry accessors without bufferViews (the data is in the extension).
    auto draco = [](json& d) {
        d["extensionsUsed"] = {"KHR_draco_mesh_compression"};
        d["accessors"][0].erase("bufferView");
        d["accessors"].push_back({{"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}});
        json& primitive = d["meshes"][0]["primitives"][0];
        primitive["indices"] = 1;
        primitive["extensions"]["KHR_draco_mesh_compression"] = {{"bufferView", 0},
                                                                 {"attributes", {{"POSITION", 0}}}};
    };
    const fs::path required = quadFile(dir, "required.gltf", [&](json& d) {
        draco(d);
        d["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    });
    EXPECT_EQ(loadError(required),
              at(required, "extensionsRequired: unsupported required extension "
                           "KHR_draco_mesh_compression"));
    // Not required and no fallback: the primitive cannot be read, and the message says why.
    const fs::path optional = quadFile(dir, "optional.gltf", [&](json& d) {
        draco(d);
        d["meshes"][0]["primitives"][0].erase("indices");
    });
    EXPECT_EQ(loadError(optional),
              at(optional, "meshes[0].primitives[0] is compressed with KHR_draco_mesh_compression, "
                           "which probekit does not decode, and has no uncompressed fallback "
                           "(POSITION, accessors[0], has no bufferView)"));
    // Not required, with the uncompressed fallback glTF asks for: loaded, with a warning.
    const fs::path fallback = quadFile(dir, "fallback.gltf", [](json& d) {
        d["extensionsUsed"] = {"KHR_draco_mesh_compression"};
        d["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"] = {
            {"bufferView", 0}, {"attributes", {{"POSITION", 0}}}};
    });
    const Result<Scene> scene = loadGltf(fallback);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    EXPECT_EQ(scene.value().triangles.size(), 1u);
    EXPECT_TRUE(anyWarningContains(scene.value(), {"meshes[0].primitives[0] is compressed with "
                                                   "KHR_draco_mesh_compression"}));
}

TEST(GltfHostile, FieldsOfTheWrongJsonKindAreNamed) {
    TempDir dir;
    struct Case {
        std::string name;
        std::function<void(json&)> edit;
        std::string expected;
    };
    const std::vector<Case> cases = {
        {"primitives",
         [](json& d) {
             const json first = d["meshes"][0]["primitives"][0];
             d["meshes"][0]["primitives"] = first;
         },
         "meshes[0].primitives is an object, expected an array"},
        {"meshes",
         [](json& d) {
             d["meshes"] = {{"a", d["meshes"][0]}};
         },
         "meshes is an object, expected an array"},
        {"nodes", [](json& d) { d["nodes"] = "node"; }, "nodes is a string, expected an array"},
        {"children",
         [](json& d) {
             d["nodes"][0]["children"] = {{"first", 1}};
         },
         "nodes[0].children is an object, expected an array"},
        {"scene nodes", [](json& d) { d["scenes"][0]["nodes"] = 0; },
         "scenes[0].nodes is a number, expected an array"},
        {"attributes", [](json& d) { d["meshes"][0]["primitives"][0]["attributes"] = {0}; },
         "meshes[0].primitives[0].attributes is an array, expected an object"},
        {"mesh index", [](json& d) { d["nodes"][0]["mesh"] = 0.5; },
         "nodes[0].mesh 0.5 is not an index (an integer in 0..2147483647)"},
        {"wrapping index", [](json& d) { d["nodes"][0]["mesh"] = 4294967296ull; },
         "nodes[0].mesh 4294967296 is not an index (an integer in 0..2147483647)"},
        {"count", [](json& d) { d["accessors"][0]["count"] = -4; },
         "accessors[0].count -4 is not a non-negative integer"},
        {"byteOffset", [](json& d) { d["accessors"][0]["byteOffset"] = "0"; },
         "accessors[0].byteOffset is a string, expected a non-negative integer"},
        {"translation",
         [](json& d) {
             d["nodes"][0]["translation"] = {1, 2};
         },
         "nodes[0].translation has 2 values, expected 3"},
        {"base colour",
         [](json& d) {
             d["materials"] = {{{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5}}}}}};
             d["meshes"][0]["primitives"][0]["material"] = 0;
         },
         "materials[0].pbrMetallicRoughness.baseColorFactor has 2 values, expected 4"},
        {"emissive",
         [](json& d) {
             d["materials"] = {{{"emissiveFactor", {1, "1", 1}}}};
         },
         "materials[0].emissiveFactor[1] is a string, expected a number"},
        {"lights",
         [](json& d) {
             d["extensions"]["KHR_lights_punctual"]["lights"] = {{"type", "point"}};
         },
         "extensions.KHR_lights_punctual.lights is an object, expected an array"},
        {"view range", [](json& d) { d["bufferViews"][0]["byteOffset"] = 40; },
         "bufferViews[0] (byteOffset 40, byteLength 48) does not fit in buffers[0] (byteLength "
         "48)"},
        {"no asset", [](json& d) { d.erase("asset"); }, "asset is missing"},
        {"root", [](json& d) { d = json::array({d}); },
         "the document is an array, expected a JSON object"},
    };
    for (const Case& c : cases) {
        const fs::path file = quadFile(dir, "kind.gltf", c.edit);
        EXPECT_EQ(loadError(file), at(file, c.expected)) << c.name;
    }
}

TEST(GltfHostile, LightValuesAreCheckedAsTheFloatsTheyBecome) {
    TempDir dir;
    const std::string light = "extensions.KHR_lights_punctual.lights[0]";
    const fs::path intense = quadFile(dir, "intense.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 1e300}});
    });
    EXPECT_EQ(loadError(intense), at(intense, light + ".intensity 1e+300 x color (1, 1, 1) "
                                                      "overflows a 32-bit float"));
    const fs::path red = quadFile(dir, "red.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 1e30}, {"color", {1e10, 0, 0}}});
    });
    EXPECT_EQ(loadError(red), at(red, light + ".intensity 1e+30 x color (10000000000, 0, 0) "
                                              "overflows a 32-bit float"));
    // The light index is reported as written, not wrapped to an int.
    const fs::path index_text = dir / "index.gltf";
    std::string text = readText(quadFile(dir, "index.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 1}}, 123456789);
    }));
    text.replace(text.find("123456789"), 9, "10000000000");
    writeText(index_text, text);
    EXPECT_EQ(loadError(index_text),
              at(index_text, "nodes[1].extensions.KHR_lights_punctual.light 10000000000 is not an "
                             "index (an integer in 0..2147483647)"));
    text.replace(text.find("10000000000"), 11, "1e10");
    writeText(index_text, text);
    EXPECT_EQ(loadError(index_text),
              at(index_text, "nodes[1].extensions.KHR_lights_punctual.light 10000000000 is not an "
                             "index (an integer in 0..2147483647)"));

    // range: > 0 when present; absent is infinite (0 in PunctualLight).
    const fs::path zero = quadFile(dir, "zero.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 1}, {"range", 0}});
    });
    EXPECT_EQ(loadError(zero), at(zero, light + ".range 0 must be > 0 (absent: infinite)"));
    const fs::path absent = quadFile(dir, "absent.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 1}});
    });
    const Result<Scene> scene = loadGltf(absent);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    ASSERT_EQ(scene.value().lights.size(), 1u);
    EXPECT_EQ(scene.value().lights[0].range, 0.0f);

    const fs::path emissive = quadFile(dir, "emissive.gltf", [](json& d) {
        d["materials"] = {
            {{"emissiveFactor", {1, 0, 0}},
             {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 1e300}}}}}}};
        d["meshes"][0]["primitives"][0]["material"] = 0;
    });
    EXPECT_EQ(loadError(emissive),
              at(emissive, "materials[0].emissiveFactor[0] 1 x "
                           "KHR_materials_emissive_strength.emissiveStrength 1e+300 overflows a "
                           "32-bit float"));
    // Finite in float but beyond what the bake's float sums hold (a 3e38 light gave "volume
    // 'volume': probe 0 has a non-finite SH coefficient", naming neither file nor light).
    const fs::path float_max = quadFile(dir, "float_max.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 3e38}});
    });
    EXPECT_EQ(loadError(float_max),
              at(float_max, light + ".intensity 3e+38 x color (1, 1, 1) is above 1e+20, the "
                                    "brightest light probekit bakes (the sun is about 1.2e5 "
                                    "lux)"));
    const fs::path glowing = quadFile(dir, "glowing.gltf", [](json& d) {
        d["materials"] = {
            {{"emissiveFactor", {0, 0.5, 0}},
             {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 1e21}}}}}}};
        d["meshes"][0]["primitives"][0]["material"] = 0;
    });
    EXPECT_EQ(loadError(glowing),
              at(glowing, "materials[0].emissiveFactor[1] 0.5 x "
                          "KHR_materials_emissive_strength.emissiveStrength 1e+21 is above 1e+20 "
                          "W/(sr m^2), the brightest emission probekit bakes"));
    // At the bound, the light loads.
    const fs::path bright = quadFile(dir, "bright.gltf", [](json& d) {
        addLight(d, {{"type", "point"}, {"intensity", 1e20}});
    });
    EXPECT_TRUE(loadGltf(bright).ok());
}

TEST(GltfHostile, NodeCyclesAreErrorsWithOrWithoutScenes) {
    TempDir dir;
    auto cycle = [](json& d) {
        d["nodes"] = {
            {{"mesh", 0}}, {{"mesh", 0}, {"children", {2}}}, {{"mesh", 0}, {"children", {1}}}};
    };
    const std::string expected = "the node hierarchy has a cycle: node 1 -> node 2 -> node 1 "
                                 "(each listed in the children of the one before)";
    const fs::path without = quadFile(dir, "without.gltf", [&](json& d) {
        cycle(d);
        d.erase("scenes");
        d.erase("scene");
    });
    EXPECT_EQ(loadError(without), at(without, expected));
    // With a scene that does not reach the cycle, it is still an error.
    const fs::path with = quadFile(dir, "with.gltf", cycle);
    EXPECT_EQ(loadError(with), at(with, expected));
    const fs::path two_parents = quadFile(dir, "parents.gltf", [](json& d) {
        d["nodes"] = {{{"children", {2}}}, {{"children", {2}}}, {{"mesh", 0}}};
        d["scenes"][0]["nodes"] = {0, 1};
    });
    EXPECT_EQ(loadError(two_parents),
              at(two_parents, "node 2 is a child of both node 0 and node 1 (glTF nodes form "
                              "trees: one parent at most)"));
}

// ---------------------------------------------------------------------------------------------
// loadGltfBytes: the fuzzing entry point

TEST(GltfHostile, BytesInMemoryResolveUrisAgainstTheNamesFolder) {
    TempDir dir;
    GltfBuilder builder = quadDocument(4, nullptr);
    const fs::path file = builder.writeExternal(dir / "quad.gltf");
    const std::vector<uint8_t> bytes = readBytes(file);
    const Result<Scene> scene = loadGltfBytes(bytes, dir / "in-memory.gltf", {});
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    EXPECT_EQ(scene.value().triangles.size(), 1u);
    EXPECT_EQ(scene.value().source, (dir / "in-memory.gltf").string());
    const Result<Scene> elsewhere = loadGltfBytes(bytes, dir / "missing-folder/x.gltf", {});
    ASSERT_FALSE(elsewhere.ok());
    EXPECT_TRUE(contains(elsewhere.error().message, "quad.bin")) << elsewhere.error().message;
}

TEST(GltfHostile, MutatedFilesGiveErrorsNamingTheFileNeverCrashes) {
    TempDir dir;
    // Deterministic byte flips, insertions and cuts of a .gltf and a .glb that exercise every
    // section the loader reads; each must come back as a scene or an error naming the file.
    GltfBuilder builder = quadDocument(
        4, {{"bufferView", 1}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}});
    builder.addView(std::vector<uint16_t>{0, 1, 2, 0, 2, 3});
    addLight(builder.doc(), {{"type", "spot"}, {"intensity", 2}, {"range", 3}});
    builder.addMaterial({{"emissiveFactor", {1, 1, 1}}});
    builder.doc()["meshes"][0]["primitives"][0]["material"] = 0;
    const std::vector<std::vector<uint8_t>> seeds = {
        readBytes(builder.writeEmbedded(dir / "seed.gltf")),
        readBytes(builder.writeGlb(dir / "seed.glb"))};
    const std::vector<std::string> names = {"m.gltf", "m.glb"};
    std::mt19937 rng(17);
    LoadOptions options;
    options.maxMemoryBytes = 64ull << 20;
    size_t loaded = 0;
    for (int round = 0; round < 400; ++round) {
        const size_t which = size_t(round) % seeds.size();
        std::vector<uint8_t> bytes = seeds[which];
        const int edits = 1 + int(rng() % 4);
        for (int e = 0; e < edits && !bytes.empty(); ++e) {
            const size_t pos = rng() % bytes.size();
            switch (rng() % 4) {
            case 0:
                bytes[pos] = static_cast<uint8_t>(rng());
                break;
            case 1:
                bytes[pos] = static_cast<uint8_t>("[]{}\",:0123456789-e."[rng() % 20]);
                break;
            case 2:
                bytes.insert(bytes.begin() + long(pos), static_cast<uint8_t>(rng()));
                break;
            default:
                bytes.resize(pos);
                break;
            }
        }
        const fs::path name = dir / names[which];
        const Result<Scene> scene = loadGltfBytes(bytes, name, options);
        if (scene.ok()) {
            ++loaded;
        } else {
            EXPECT_TRUE(scene.error().message.starts_with(name.string()) ||
                        scene.error().message.starts_with("LoadOptions"))
                << scene.error().message;
        }
    }
    // Most mutations break the file; some (inside a name, a number) leave it loadable.
    EXPECT_LT(loaded, 400u);
}
