// What the application hands the renderer: textures (as half-float images with their descriptor
// sets), the environment (a constant or a lat-long texture), and meshes (in runs of one texture).
#include <algorithm>
#include <cstring>
#include <string>

#include <glm/gtc/packing.hpp>

#include "renderer_internal.hpp"

namespace probekit::runtime {

Result<void> Renderer::Impl::createTextureResources() {
    PK_TRY(detail::createLinearSampler(device(), VK_SAMPLER_ADDRESS_MODE_REPEAT, sampler));
    const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                                    uint32_t(kUserTextures + kMaxRenderTextures)};
    VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool_info.flags = VK_DESCRIPTOR_POOL_CREATE_FREE_DESCRIPTOR_SET_BIT;
    pool_info.maxSets = uint32_t(kUserTextures + kMaxRenderTextures);
    pool_info.poolSizeCount = 1;
    pool_info.pPoolSizes = &size;
    PK_VK_TRY(vkCreateDescriptorPool(device(), &pool_info, nullptr, &texturePool));
    // White: untextured triangles and probe spheres keep their albedo factor; it also stands in
    // for the environment map until setEnvironment uploads one.
    const RgbaImage white{1, 1, {glm::vec4(1.0f)}};
    textures.resize(kUserTextures);
    PK_TRY(uploadTexture(white, kWhiteTexture));
    return uploadTexture(white, kEnvironmentTexture);
}

void Renderer::Impl::destroyTexture(Texture& texture) {
    if (texture.set != VK_NULL_HANDLE) {
        vkFreeDescriptorSets(device(), texturePool, 1, &texture.set);
        texture.set = VK_NULL_HANDLE;
    }
    detail::destroy(device(), texture.image);
}

Result<void> Renderer::Impl::uploadTexture(const RgbaImage& image, size_t index) {
    Texture& texture = textures[index];
    destroyTexture(texture);
    const VkExtent3D extent{image.width, image.height, 1};
    Result<Image> created = detail::createImage(
        *context, VK_IMAGE_TYPE_2D, kTextureFormat, extent,
        VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
    if (!created) {
        return created.error();
    }
    texture.image = created.value();
    // Binary16 texels, finite: radiance beyond the largest half is clamped to it.
    const size_t texels = size_t(image.width) * image.height;
    Result<Buffer> staging = detail::createBuffer(*context, texels * sizeof(uint64_t),
                                                  VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
    if (!staging) {
        return staging.error();
    }
    auto* out = static_cast<uint64_t*>(staging.value().mapped);
    for (size_t i = 0; i < texels; ++i) {
        out[i] =
            glm::packHalf4x16(glm::clamp(image.texels[i], -float(PK_HALF_MAX), float(PK_HALF_MAX)));
    }
    const Result<void> copied = context->submitAndWait([&](VkCommandBuffer cmd) {
        detail::imageBarrier(cmd, texture.image.image, VK_IMAGE_ASPECT_COLOR_BIT,
                             VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                             VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_ACCESS_TRANSFER_WRITE_BIT);
        VkBufferImageCopy region{};
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.imageExtent = extent;
        vkCmdCopyBufferToImage(cmd, staging.value().buffer, texture.image.image,
                               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
        detail::imageBarrier(cmd, texture.image.image, VK_IMAGE_ASPECT_COLOR_BIT,
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                             VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                             VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                             VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
    });
    detail::destroy(device(), staging.value());
    if (!copied) {
        return copied.error();
    }
    VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocate.descriptorPool = texturePool;
    allocate.descriptorSetCount = 1;
    allocate.pSetLayouts = &textureLayout;
    PK_VK_TRY(vkAllocateDescriptorSets(device(), &allocate, &texture.set));
    const VkDescriptorImageInfo image_info{sampler, texture.image.view,
                                           VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    write.dstSet = texture.set;
    write.descriptorCount = 1;
    write.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    write.pImageInfo = &image_info;
    vkUpdateDescriptorSets(device(), 1, &write, 0, nullptr);
    return {};
}

Result<void> Renderer::setTextures(std::span<const RgbaImage> images) {
    Impl& impl = *m_impl;
    if (images.size() > kMaxRenderTextures) {
        return makeError(ErrorCode::OutOfRange, "renderer: " + std::to_string(images.size()) +
                                                    " textures, at most " +
                                                    std::to_string(kMaxRenderTextures));
    }
    const uint32_t max_size = impl.context->limits().maxImageDimension2D;
    for (size_t i = 0; i < images.size(); ++i) {
        const RgbaImage& image = images[i];
        if (image.width < 1 || image.height < 1 || image.width > max_size ||
            image.height > max_size || image.texels.size() != size_t(image.width) * image.height) {
            return makeError(ErrorCode::OutOfRange,
                             "renderer: texture " + std::to_string(i) + " is " +
                                 std::to_string(image.width) + "x" + std::to_string(image.height) +
                                 " with " + std::to_string(image.texels.size()) +
                                 " texels; each side must be in 1.." + std::to_string(max_size));
        }
    }
    PK_TRY(setMeshes({}, {}));
    for (size_t i = kUserTextures; i < impl.textures.size(); ++i) {
        impl.destroyTexture(impl.textures[i]);
    }
    impl.textures.resize(kUserTextures + images.size());
    for (size_t i = 0; i < images.size(); ++i) {
        PK_TRY(impl.uploadTexture(images[i], kUserTextures + i));
    }
    return {};
}

Result<void> Renderer::setEnvironment(const Environment& environment) {
    Impl& impl = *m_impl;
    PK_TRY(impl.context->waitIdle());
    impl.environmentType = PK_ENV_NONE;
    impl.environment = glm::vec4(0.0f);
    if (environment.isBlack()) {
        return {};
    }
    if (environment.type == Environment::Type::Constant) {
        impl.environmentType = PK_ENV_CONSTANT;
        impl.environment = glm::vec4(environment.constant * environment.intensity, 0.0f);
        return {};
    }
    const uint32_t max_size = impl.context->limits().maxImageDimension2D;
    const RgbaImage& image = environment.image;
    if (image.width > max_size || image.height > max_size ||
        image.texels.size() != size_t(image.width) * image.height) {
        return makeError(ErrorCode::OutOfRange,
                         "renderer: environment " + environment.source + " is " +
                             std::to_string(image.width) + "x" + std::to_string(image.height) +
                             "; each side must be at most " + std::to_string(max_size));
    }
    PK_TRY(impl.uploadTexture(image, kEnvironmentTexture));
    impl.environmentType = PK_ENV_LATLONG;
    impl.environment =
        glm::vec4(glm::vec3(environment.intensity), glm::radians(environment.rotationDeg));
    return {};
}

namespace {

// A host-visible buffer for `usage` holding a copy of the `bytes` bytes at `data`.
Result<Buffer> filledBuffer(GpuContext& context, const void* data, size_t bytes,
                            VkBufferUsageFlags usage) {
    Result<Buffer> buffer = detail::createBuffer(context, bytes, usage, true);
    if (buffer) {
        std::memcpy(buffer.value().mapped, data, bytes);
    }
    return buffer;
}

} // namespace

Result<void> Renderer::setMeshes(std::span<const RenderVertex> vertices,
                                 std::span<const uint32_t> indices,
                                 std::span<const int32_t> triangle_textures) {
    if (indices.size() % 3 != 0) {
        return makeError(ErrorCode::OutOfRange, "renderer: " + std::to_string(indices.size()) +
                                                    " indices is not a whole number of triangles");
    }
    const size_t triangles = indices.size() / 3;
    const size_t texture_count = m_impl->textures.size() - kUserTextures;
    if (!triangle_textures.empty() && triangle_textures.size() != triangles) {
        return makeError(ErrorCode::OutOfRange,
                         "renderer: " + std::to_string(triangle_textures.size()) +
                             " triangle textures for " + std::to_string(triangles) + " triangles");
    }
    for (size_t t = 0; t < triangle_textures.size(); ++t) {
        if (triangle_textures[t] < -1 || triangle_textures[t] >= int64_t(texture_count)) {
            return makeError(ErrorCode::OutOfRange, "renderer: triangle " + std::to_string(t) +
                                                        " has texture " +
                                                        std::to_string(triangle_textures[t]) +
                                                        " of " + std::to_string(texture_count));
        }
    }
    for (size_t i = 0; i < indices.size(); ++i) {
        if (indices[i] >= vertices.size()) {
            return makeError(ErrorCode::OutOfRange,
                             "renderer: index " + std::to_string(i) + " = " +
                                 std::to_string(indices[i]) + " is past the " +
                                 std::to_string(vertices.size()) + " vertices");
        }
    }
    Impl& impl = *m_impl;
    PK_TRY(impl.context->waitIdle());
    const VkDevice d = impl.device();
    detail::destroy(d, impl.vertices);
    detail::destroy(d, impl.indices);
    impl.indexCount = 0;
    impl.runs.clear();
    if (indices.empty()) {
        return {};
    }
    // Triangles in runs of one texture (stable: in their given order within a run), so each run
    // is one draw with its texture bound.
    auto textureOf = [&](size_t t) {
        return triangle_textures.empty() || triangle_textures[t] < 0
                   ? kWhiteTexture
                   : kUserTextures + size_t(triangle_textures[t]);
    };
    std::vector<uint32_t> order(triangles);
    for (size_t t = 0; t < triangles; ++t) {
        order[t] = uint32_t(t);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t a, uint32_t b) { return textureOf(a) < textureOf(b); });
    std::vector<uint32_t> sorted(indices.size());
    for (size_t k = 0; k < triangles; ++k) {
        std::copy_n(indices.begin() + 3 * order[k], 3, sorted.begin() + 3 * k);
        const size_t texture = textureOf(order[k]);
        if (impl.runs.empty() || impl.runs.back().texture != texture) {
            impl.runs.push_back({uint32_t(3 * k), 0, texture});
        }
        impl.runs.back().indexCount += 3;
    }
    // Host-visible vertex data: simple, and read once per frame by a small renderer.
    Result<Buffer> v = filledBuffer(*impl.context, vertices.data(), vertices.size_bytes(),
                                    VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
    if (!v) {
        return v.error();
    }
    impl.vertices = v.value();
    Result<Buffer> i = filledBuffer(*impl.context, sorted.data(), indices.size_bytes(),
                                    VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
    if (!i) {
        return i.error();
    }
    impl.indices = i.value();
    impl.indexCount = uint32_t(indices.size());
    return {};
}

} // namespace probekit::runtime
