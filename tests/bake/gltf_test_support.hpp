// glTF test files written by the tests themselves: temporary folders, a document builder that
// writes .gltf (embedded or external buffer) and .glb, and a minimal PNG encoder, so each
// expected number is known exactly (used by test_scene.cpp and test_gltf_hostile.cpp).
#pragma once

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "probekit/baker/scene.hpp"

namespace probekit::test {

namespace fs = std::filesystem;
using nlohmann::json;

// ---------------------------------------------------------------------------------------------
// Files

class TempDir {
public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        m_path =
            fs::temp_directory_path() / ("probekit_scene_" + std::string(info->test_suite_name()) +
                                         "_" + info->name() + "_" + std::to_string(::getpid()));
        fs::remove_all(m_path);
        fs::create_directories(m_path);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(m_path, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    fs::path operator/(const std::string& name) const { return m_path / name; }

private:
    fs::path m_path;
};

inline void writeBytes(const fs::path& path, const void* data, size_t size) {
    std::ofstream out(path, std::ios::binary);
    out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
}

inline void writeText(const fs::path& path, const std::string& text) {
    writeBytes(path, text.data(), text.size());
}

inline std::vector<uint8_t> readBytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline std::string readText(const fs::path& path) {
    const std::vector<uint8_t> bytes = readBytes(path);
    return std::string(bytes.begin(), bytes.end());
}

inline std::string base64(const std::vector<uint8_t>& bytes) {
    static constexpr char kAlphabet[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
        const uint32_t b0 = bytes[i];
        const uint32_t b1 = i + 1 < bytes.size() ? bytes[i + 1] : 0;
        const uint32_t b2 = i + 2 < bytes.size() ? bytes[i + 2] : 0;
        const uint32_t triple = (b0 << 16) | (b1 << 8) | b2;
        out += kAlphabet[(triple >> 18) & 63];
        out += kAlphabet[(triple >> 12) & 63];
        out += i + 1 < bytes.size() ? kAlphabet[(triple >> 6) & 63] : '=';
        out += i + 2 < bytes.size() ? kAlphabet[triple & 63] : '=';
    }
    return out;
}

// A minimal PNG encoder (RGBA, 8 or 16 bits, zlib "stored" blocks), so the texture tests know
// every encoded value exactly without an image library in the test.
inline uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc = 0) {
    crc = ~crc;
    for (size_t i = 0; i < size; ++i) {
        crc ^= data[i];
        for (int k = 0; k < 8; ++k) {
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
        }
    }
    return ~crc;
}

inline void appendBe32(std::vector<uint8_t>& out, uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) {
        out.push_back(static_cast<uint8_t>(v >> shift));
    }
}

inline void appendPngChunk(std::vector<uint8_t>& png, const char* type,
                           const std::vector<uint8_t>& data) {
    appendBe32(png, static_cast<uint32_t>(data.size()));
    std::vector<uint8_t> typed(type, type + 4);
    typed.insert(typed.end(), data.begin(), data.end());
    png.insert(png.end(), typed.begin(), typed.end());
    appendBe32(png, crc32(typed.data(), typed.size()));
}

inline std::vector<uint8_t> encodePng(uint32_t width, uint32_t height, int bits,
                                      const std::vector<uint16_t>& rgba) {
    std::vector<uint8_t> raw;
    for (uint32_t y = 0; y < height; ++y) {
        raw.push_back(0); // filter: none
        for (uint32_t i = 0; i < width * 4; ++i) {
            const uint16_t v = rgba[y * width * 4 + i];
            if (bits == 16) {
                raw.push_back(static_cast<uint8_t>(v >> 8));
            }
            raw.push_back(static_cast<uint8_t>(v & 0xFF));
        }
    }
    std::vector<uint8_t> zlib = {0x78, 0x01};
    for (size_t offset = 0; offset < raw.size() || offset == 0; offset += 65535) {
        const size_t n = std::min<size_t>(65535, raw.size() - offset);
        zlib.push_back(offset + n >= raw.size() ? 1 : 0);
        zlib.push_back(static_cast<uint8_t>(n & 0xFF));
        zlib.push_back(static_cast<uint8_t>(n >> 8));
        zlib.push_back(static_cast<uint8_t>(~n & 0xFF));
        zlib.push_back(static_cast<uint8_t>((~n >> 8) & 0xFF));
        zlib.insert(zlib.end(), raw.begin() + offset, raw.begin() + offset + n);
        if (raw.empty()) {
            break;
        }
    }
    uint32_t a = 1, b = 0;
    for (const uint8_t byte : raw) {
        a = (a + byte) % 65521;
        b = (b + a) % 65521;
    }
    appendBe32(zlib, (b << 16) | a);

    std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    std::vector<uint8_t> header;
    appendBe32(header, width);
    appendBe32(header, height);
    header.insert(header.end(), {static_cast<uint8_t>(bits), 6, 0, 0, 0}); // RGBA
    appendPngChunk(png, "IHDR", header);
    appendPngChunk(png, "IDAT", zlib);
    appendPngChunk(png, "IEND", {});
    return png;
}

// ---------------------------------------------------------------------------------------------
// glTF documents

// Builds a glTF document and its single binary buffer, then writes it as .gltf with an embedded
// data: URI, as .gltf + external .bin, or as .glb.
class GltfBuilder {
public:
    GltfBuilder() { m_doc = {{"asset", {{"version", "2.0"}}}}; }

    json& doc() { return m_doc; }

    template <class T>
    int addView(const std::vector<T>& values) {
        while (m_bin.size() % 4 != 0) {
            m_bin.push_back(0);
        }
        const size_t offset = m_bin.size();
        const auto* bytes = reinterpret_cast<const uint8_t*>(values.data());
        m_bin.insert(m_bin.end(), bytes, bytes + values.size() * sizeof(T));
        m_doc["bufferViews"].push_back(
            {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", values.size() * sizeof(T)}});
        return static_cast<int>(m_doc["bufferViews"].size()) - 1;
    }

    int addAccessor(const json& accessor) {
        m_doc["accessors"].push_back(accessor);
        return static_cast<int>(m_doc["accessors"].size()) - 1;
    }

    int addPositions(const std::vector<glm::vec3>& positions) {
        std::vector<float> flat;
        for (const glm::vec3& p : positions) {
            flat.insert(flat.end(), {p.x, p.y, p.z});
        }
        return addAccessor({{"bufferView", addView(flat)},
                            {"componentType", 5126},
                            {"count", positions.size()},
                            {"type", "VEC3"}});
    }

    int addUvs(const std::vector<glm::vec2>& uvs) {
        std::vector<float> flat;
        for (const glm::vec2& uv : uvs) {
            flat.insert(flat.end(), {uv.x, uv.y});
        }
        return addAccessor({{"bufferView", addView(flat)},
                            {"componentType", 5126},
                            {"count", uvs.size()},
                            {"type", "VEC2"}});
    }

    template <class T>
    int addIndices(const std::vector<T>& indices, int component_type) {
        return addAccessor({{"bufferView", addView(indices)},
                            {"componentType", component_type},
                            {"count", indices.size()},
                            {"type", "SCALAR"}});
    }

    int addMesh(const json& primitives) {
        m_doc["meshes"].push_back({{"primitives", primitives}});
        return static_cast<int>(m_doc["meshes"].size()) - 1;
    }

    int addNode(const json& node) {
        m_doc["nodes"].push_back(node);
        return static_cast<int>(m_doc["nodes"].size()) - 1;
    }

    int addMaterial(const json& material) {
        m_doc["materials"].push_back(material);
        return static_cast<int>(m_doc["materials"].size()) - 1;
    }

    void setScene(const std::vector<int>& roots) {
        m_doc["scenes"] = json::array({{{"nodes", roots}}});
        m_doc["scene"] = 0;
    }

    fs::path writeEmbedded(const fs::path& path) const {
        json doc = m_doc;
        if (!m_bin.empty()) {
            doc["buffers"] =
                json::array({{{"byteLength", m_bin.size()},
                              {"uri", "data:application/octet-stream;base64," + base64(m_bin)}}});
        }
        writeText(path, doc.dump(1));
        return path;
    }

    fs::path writeExternal(const fs::path& path) const {
        json doc = m_doc;
        const fs::path bin = fs::path(path).replace_extension(".bin");
        doc["buffers"] =
            json::array({{{"byteLength", m_bin.size()}, {"uri", bin.filename().string()}}});
        writeText(path, doc.dump(1));
        writeBytes(bin, m_bin.data(), m_bin.size());
        return path;
    }

    // GLB container, built by hand from the glTF 2.0 specification (section 4.4).
    fs::path writeGlb(const fs::path& path) const {
        json doc = m_doc;
        doc["buffers"] = json::array({{{"byteLength", m_bin.size()}}});
        std::string text = doc.dump();
        while (text.size() % 4 != 0) {
            text += ' ';
        }
        std::vector<uint8_t> bin = m_bin;
        while (bin.size() % 4 != 0) {
            bin.push_back(0);
        }
        std::vector<uint8_t> glb;
        auto le32 = [&](uint32_t v) {
            for (int shift = 0; shift < 32; shift += 8) {
                glb.push_back(static_cast<uint8_t>(v >> shift));
            }
        };
        glb.insert(glb.end(), {'g', 'l', 'T', 'F'});
        le32(2);
        le32(static_cast<uint32_t>(12 + 8 + text.size() + 8 + bin.size()));
        le32(static_cast<uint32_t>(text.size()));
        le32(0x4E4F534A); // "JSON"
        glb.insert(glb.end(), text.begin(), text.end());
        le32(static_cast<uint32_t>(bin.size()));
        le32(0x004E4942); // "BIN\0"
        glb.insert(glb.end(), bin.begin(), bin.end());
        writeBytes(path, glb.data(), glb.size());
        return path;
    }

private:
    json m_doc;
    std::vector<uint8_t> m_bin;
};

// The unit quad in z = 0: corners 0 (0,0), 1 (1,0), 2 (1,1), 3 (0,1), triangles (0,1,2),
// (0,2,3), counter-clockwise seen from +Z.
inline const std::vector<glm::vec3> kQuad = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};

inline bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

inline bool anyWarningContains(const baker::Scene& scene,
                               std::initializer_list<std::string> parts) {
    return std::any_of(scene.warnings.begin(), scene.warnings.end(), [&](const std::string& w) {
        return std::all_of(parts.begin(), parts.end(),
                           [&](const std::string& part) { return contains(w, part); });
    });
}

// A one-node, one-primitive quad document with the given index data (or none).
inline GltfBuilder quadDocument(int mode, const json& indices_accessor_or_null,
                                const std::vector<glm::vec3>& positions = kQuad) {
    GltfBuilder builder;
    json primitive = {{"attributes", {{"POSITION", builder.addPositions(positions)}}},
                      {"mode", mode}};
    if (!indices_accessor_or_null.is_null()) {
        primitive["indices"] = builder.addAccessor(indices_accessor_or_null);
    }
    builder.setScene({builder.addNode({{"mesh", builder.addMesh(json::array({primitive}))}})});
    return builder;
}

} // namespace probekit::test
