// glTF materials -> Scene::materials, and the base colour and emissive textures they use ->
// Scene::images (linear floats). Part of GltfLoader (gltf_loader.hpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "scene/gltf_loader.hpp"

namespace probekit::baker::gltf {

namespace {

// The exact sRGB EOTF (IEC 61966-2-1), not a gamma-2.2 approximation: glTF defines base colour
// and emissive textures as sRGB-encoded.
double srgbToLinear(double encoded) {
    return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

} // namespace

uint32_t GltfLoader::defaultMaterial() {
    if (m_default_material < 0) {
        // glTF's default material: base colour 1, no emission.
        Material material;
        material.name = "(glTF default material)";
        m_default_material = static_cast<int>(m_scene.materials.size());
        m_scene.materials.push_back(material);
    }
    return static_cast<uint32_t>(m_default_material);
}

void GltfLoader::loadMaterials() {
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
        material.baseColorTexture = loadTexture(source.pbrMetallicRoughness.baseColorTexture,
                                                field + ".pbrMetallicRoughness.baseColorTexture");
        material.emissiveTexture = loadTexture(source.emissiveTexture, field + ".emissiveTexture");
        m_scene.materials.push_back(std::move(material));
    }
}

// Scene::images index of a base colour / emissive texture, or -1 when there is none or it
// cannot be used (with a warning).
int GltfLoader::loadTexture(const tinygltf::TextureInfo& info, const std::string& field) {
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
int GltfLoader::decodeImage(int gltf_index) {
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
        fail(ErrorCode::InconsistentSize, field +
                                              ": decoded pixel data has an unexpected layout (" +
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

} // namespace probekit::baker::gltf
