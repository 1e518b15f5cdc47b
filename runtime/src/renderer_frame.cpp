// One frame: the size-dependent targets, the frame uniforms and the dynamic GI's set, and the
// commands of the G-buffer pass, the shading passes and the readback copies.
#include <algorithm>
#include <array>
#include <cstring>

#include "renderer_internal.hpp"

namespace probekit::runtime {

void Renderer::Impl::destroyTargets() {
    const VkDevice d = device();
    if (framebuffer != VK_NULL_HANDLE) {
        vkDestroyFramebuffer(d, framebuffer, nullptr);
        framebuffer = VK_NULL_HANDLE;
    }
    for (Image* image : {&position, &normal, &albedo, &emission, &id, &depth, &color}) {
        detail::destroy(d, *image);
    }
    detail::destroy(d, readback);
    detail::destroy(d, lightMask);
    width = height = 0;
}

// The shading set points at the current targets, the frame set at the light mask.
void Renderer::Impl::writeShadeSet() {
    const VkDescriptorImageInfo images[kShadeImages] = {
        {VK_NULL_HANDLE, position.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, normal.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, albedo.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, emission.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, id.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, color.view, VK_IMAGE_LAYOUT_GENERAL}};
    std::array<VkWriteDescriptorSet, kShadeImages + 1> writes{};
    // The last write: the light mask, in the G-buffer pass's frame set.
    for (uint32_t i = 0; i < kShadeImages; ++i) {
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = shadeSet;
        writes[i].dstBinding = i + 1;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
        writes[i].pImageInfo = &images[i];
    }
    const VkDescriptorBufferInfo mask_info{lightMask.buffer, 0, VK_WHOLE_SIZE};
    VkWriteDescriptorSet& mask_write = writes[kShadeImages];
    mask_write.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
    mask_write.dstSet = frameSet;
    mask_write.dstBinding = PK_LIGHT_MASK_BINDING;
    mask_write.descriptorCount = 1;
    mask_write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    mask_write.pBufferInfo = &mask_info;
    vkUpdateDescriptorSets(device(), uint32_t(writes.size()), writes.data(), 0, nullptr);
}

Result<void> Renderer::Impl::createTargets(uint32_t w, uint32_t h) {
    destroyTargets();
    const VkExtent3D extent{w, h, 1};
    const VkImageUsageFlags gbuffer_usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT |
                                            VK_IMAGE_USAGE_STORAGE_BIT |
                                            VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    struct Target {
        Image* image;
        VkFormat format;
        VkImageUsageFlags usage;
        VkImageAspectFlags aspect;
    };
    const Target targets[] = {
        {&position, kPositionFormat, gbuffer_usage, VK_IMAGE_ASPECT_COLOR_BIT},
        {&normal, kNormalFormat, gbuffer_usage, VK_IMAGE_ASPECT_COLOR_BIT},
        {&albedo, kAlbedoFormat, gbuffer_usage, VK_IMAGE_ASPECT_COLOR_BIT},
        {&emission, kEmissionFormat, gbuffer_usage, VK_IMAGE_ASPECT_COLOR_BIT},
        {&id, kIdFormat, gbuffer_usage, VK_IMAGE_ASPECT_COLOR_BIT},
        {&depth, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
         VK_IMAGE_ASPECT_DEPTH_BIT},
        {&color, kColorFormat, VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
         VK_IMAGE_ASPECT_COLOR_BIT},
    };
    for (const Target& t : targets) {
        Result<Image> image =
            detail::createImage(*context, VK_IMAGE_TYPE_2D, t.format, extent, t.usage, t.aspect);
        if (!image) {
            return image.error();
        }
        *t.image = image.value();
    }
    const VkImageView attachments[] = {position.view, normal.view, albedo.view,
                                       emission.view, id.view,     depth.view};
    const VkFramebufferCreateInfo fb{.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                     .renderPass = renderPass,
                                     .attachmentCount = kAttachments,
                                     .pAttachments = attachments,
                                     .width = w,
                                     .height = h,
                                     .layers = 1};
    PK_VK_TRY(vkCreateFramebuffer(device(), &fb, nullptr, &framebuffer));

    Result<Buffer> buffer =
        detail::createBuffer(*context, VkDeviceSize(w) * h * 3 * sizeof(glm::vec4),
                             VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
    if (!buffer) {
        return buffer.error();
    }
    readback = buffer.value();
    Result<Buffer> mask = detail::createBuffer(*context, VkDeviceSize(w) * h * sizeof(uint32_t),
                                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    if (!mask) {
        return mask.error();
    }
    lightMask = mask.value();

    writeShadeSet();
    width = w;
    height = h;
    return {};
}

namespace {

gpu::PkLightGpu packLight(const PunctualLight& light) {
    gpu::PkLightGpu out{};
    out.position = glm::vec4(light.position, light.range);
    out.direction = glm::vec4(light.direction, light.innerConeCos);
    out.intensity = glm::vec4(light.intensity, light.outerConeCos);
    const uint32_t type = light.type == LightType::Point  ? PK_LIGHT_POINT
                          : light.type == LightType::Spot ? PK_LIGHT_SPOT
                                                          : PK_LIGHT_DIRECTIONAL;
    out.info = glm::uvec4(type, 0u, 0u, 0u);
    return out;
}

// Whether the view is one of the debug views shade.comp's PK_PROBE_VIEWS variant draws.
bool isProbeView(RenderView view) {
    return view == RenderView::Probes || view == RenderView::Validity || view == RenderView::Leak;
}

} // namespace

void Renderer::Impl::writeLightMask(const FrameSettings& settings) {
    uint32_t* masks = static_cast<uint32_t*>(lightMask.mapped);
    const size_t pixels = size_t(settings.width) * settings.height;
    if (settings.lightVisibility.empty()) {
        std::fill(masks, masks + pixels, ~0u);
    } else {
        std::memcpy(masks, settings.lightVisibility.data(), pixels * sizeof(uint32_t));
    }
}

gpu::PkFrameGpu Renderer::Impl::frameUniformsFor(const FrameSettings& settings, bool gi) const {
    gpu::PkFrameGpu frame{};
    const Camera& cam = settings.camera;
    frame.viewProjection = viewProjection(settings);
    frame.eye = glm::vec4(cam.eye, 1.0f);
    const CameraBasis basis = cameraBasis(cam, float(settings.width) / float(settings.height));
    frame.cameraRight = glm::vec4(basis.right, 0.0f);
    frame.cameraUp = glm::vec4(basis.up, 0.0f);
    frame.cameraForward = glm::vec4(basis.forward, 0.0f);
    frame.environment = environment;
    frame.environmentInfo = glm::uvec4(environmentType, 0u, 0u, 0u);
    uint32_t flags = 0;
    if (gi && !settings.bakedLight) {
        flags |= PK_FRAME_NO_BAKED;
    }
    if (gi && settings.giShadowSun) {
        flags |= PK_FRAME_GI_DIRECTIONAL;
    }
    frame.info = glm::uvec4(uint32_t(settings.view), uint32_t(settings.lights.size()),
                            settings.directLight ? 1u : 0u, flags);
    frame.size = glm::uvec4(settings.width, settings.height, 0u, 0u);
    for (size_t i = 0; i < settings.lights.size(); ++i) {
        frame.lights[i] = packLight(settings.lights[i]);
    }
    return frame;
}

void Renderer::Impl::recordFrameUniforms(VkCommandBuffer cmd, const gpu::PkFrameGpu& frame) {
    VkBufferMemoryBarrier uniform_barrier{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
    uniform_barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    uniform_barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    uniform_barrier.buffer = frameUniforms.buffer;
    uniform_barrier.size = VK_WHOLE_SIZE;
    uniform_barrier.srcAccessMask = VK_ACCESS_UNIFORM_READ_BIT;
    uniform_barrier.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                         0, nullptr, 1, &uniform_barrier, 0, nullptr);
    vkCmdUpdateBuffer(cmd, frameUniforms.buffer, 0, sizeof(frame), &frame);
    uniform_barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    uniform_barrier.dstAccessMask = VK_ACCESS_UNIFORM_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0,
                         0, nullptr, 1, &uniform_barrier, 0, nullptr);
}

void Renderer::Impl::recordGBufferPass(VkCommandBuffer cmd, const FrameSettings& settings,
                                       uint32_t instance_count) {
    // Pass 1: G-buffer.
    VkClearValue clears[kAttachments]{};
    clears[kColorTargets].depthStencil = {1.0f, 0};
    VkRenderPassBeginInfo begin{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    begin.renderPass = renderPass;
    begin.framebuffer = framebuffer;
    begin.renderArea = {{0, 0}, {settings.width, settings.height}};
    begin.clearValueCount = kAttachments;
    begin.pClearValues = clears;
    vkCmdBeginRenderPass(cmd, &begin, VK_SUBPASS_CONTENTS_INLINE);
    const VkViewport viewport{0.0f, 0.0f, float(settings.width), float(settings.height),
                              0.0f, 1.0f};
    const VkRect2D scissor{{0, 0}, {settings.width, settings.height}};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, gbufferPipelineLayout, 0, 1,
                            &frameSet, 0, nullptr);
    auto bindTexture = [&](size_t texture) {
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, gbufferPipelineLayout, 1, 1,
                                &textures[texture].set, 0, nullptr);
    };
    // The environment first, without depth, in the views whose output is radiance.
    const bool radiance_view =
        settings.view == RenderView::Shaded || settings.view == RenderView::Probes;
    if (settings.showEnvironment && radiance_view && environmentType != PK_ENV_NONE) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, backgroundPipeline);
        bindTexture(kEnvironmentTexture);
        vkCmdDraw(cmd, 3, 1, 0, 0);
    }
    const VkDeviceSize zero = 0;
    if (indexCount > 0 && settings.view != RenderView::Validity) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, meshPipeline);
        vkCmdBindVertexBuffers(cmd, 0, 1, &vertices.buffer, &zero);
        vkCmdBindIndexBuffer(cmd, indices.buffer, 0, VK_INDEX_TYPE_UINT32);
        for (const DrawRun& run : runs) {
            bindTexture(run.texture);
            vkCmdDrawIndexed(cmd, run.indexCount, 1, run.firstIndex, 0, 0);
        }
    }
    if (instance_count > 0) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, probePipeline);
        bindTexture(kWhiteTexture);
        const VkBuffer buffers[2] = {sphere.buffer, instances.buffer};
        const VkDeviceSize offsets[2] = {0, 0};
        vkCmdBindVertexBuffers(cmd, 0, 2, buffers, offsets);
        vkCmdDraw(cmd, sphereVertices, instance_count, 0, 0);
    }
    vkCmdEndRenderPass(cmd);
}

void Renderer::Impl::recordShadingPass(VkCommandBuffer cmd, GpuVolumeSet& volumes,
                                       const FrameSettings& settings, bool probe_views, bool gi) {
    // Pass 2: shading. The output image's previous contents are not needed (UNDEFINED); the
    // previous frame's copy from it finishes first.
    detail::imageBarrier(cmd, color.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                         VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT);
    // The debug views' variant (shade.comp's PK_PROBE_VIEWS): probe_views (isProbeView).
    // The visibility path only where the set needs it: without, the plain filtered code.
    const size_t visibility = volumes.anyVisibility() ? 1 : 0;
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE,
                      settings.fetchOnly ? fetchOnlyPipeline[visibility]
                      : probe_views      ? probeViewsPipeline[visibility]
                                         : shadePipeline[visibility]);
    const VkDescriptorSet sets[2] = {volumes.descriptorSet(), shadeSet};
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadePipelineLayout, 0, 2, sets, 0,
                            nullptr);
    vkCmdDispatch(cmd, (settings.width + kShadeGroup - 1) / kShadeGroup,
                  (settings.height + kShadeGroup - 1) / kShadeGroup, 1);
    if (gi) {
        // The GI pass reads and rewrites what the shading pass wrote.
        detail::imageBarrier(cmd, color.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_GENERAL,
                             VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                             VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                             VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, giShadePipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, giShadePipelineLayout, 0, 1,
                                &giSet, 0, nullptr);
        vkCmdDispatch(cmd, (settings.width + kShadeGroup - 1) / kShadeGroup,
                      (settings.height + kShadeGroup - 1) / kShadeGroup, 1);
    }
}

void Renderer::Impl::recordReadback(VkCommandBuffer cmd, const FrameSettings& settings) {
    // Readback copies.
    const VkDeviceSize image_bytes = VkDeviceSize(settings.width) * settings.height * 16;
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {settings.width, settings.height, 1};
    // Each copied image goes to TRANSFER_SRC_OPTIMAL once the shading pass is done with it;
    // the next frame starts every target from UNDEFINED again.
    if (settings.readbackColor) {
        detail::imageBarrier(cmd, color.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_GENERAL,
                             VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                             VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                             VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        vkCmdCopyImageToBuffer(cmd, color.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                               readback.buffer, 1, &region);
    }
    if (settings.readbackGBuffer) {
        const Image* targets[2] = {&position, &normal};
        for (size_t k = 0; k < 2; ++k) {
            detail::imageBarrier(cmd, targets[k]->image, VK_IMAGE_ASPECT_COLOR_BIT,
                                 VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                 VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                     VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                                 VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                                 VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
            region.bufferOffset = (k + 1) * image_bytes;
            vkCmdCopyImageToBuffer(cmd, targets[k]->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                   readback.buffer, 1, &region);
        }
    }
    VkMemoryBarrier host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                         &host, 0, nullptr, 0, nullptr);
}

void Renderer::Impl::record(VkCommandBuffer cmd, GpuVolumeSet& volumes,
                            const FrameSettings& settings, uint32_t instance_count) {
    const bool timed = context->timestampPeriodNs() > 0.0;
    if (timed) {
        vkCmdResetQueryPool(cmd, queries, 0, kTimestamps);
    }
    volumes.recordUniformUpdate(cmd);
    const bool probe_views = isProbeView(settings.view);
    const bool gi = settings.dynamicGi && !settings.fetchOnly && !probe_views;
    recordFrameUniforms(cmd, frameUniformsFor(settings, gi));
    if (timed) {
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, 0);
    }
    recordGBufferPass(cmd, settings, instance_count);
    if (timed) {
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, 1);
    }
    recordShadingPass(cmd, volumes, settings, probe_views, gi);
    if (timed) {
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, 2);
    }
    recordReadback(cmd, settings);
}

Result<void> Renderer::Impl::writeGiSet(const GiShadingInputs& gi, const FrameSettings& settings) {
    if (gi.cascades < 1 || gi.cascades > kMaxGiCascades || gi.geometry == VK_NULL_HANDLE) {
        return makeError(ErrorCode::InvalidArgument,
                         "renderer: dynamic GI inputs without cascades or geometry");
    }
    gpu::PkGiGpu block{};
    for (uint32_t j = 0; j < gi.cascades; ++j) {
        const GiCascadePlacement& c = gi.placement[j];
        block.cascades[j].origin = glm::vec4(c.origin, c.cellSize);
        block.cascades[j].info = glm::uvec4(c.cells, 0u, 0u, 0u);
    }
    block.info = glm::uvec4(gi.cascades, uint32_t(gi.quality), 0u,
                            settings.directLight && settings.giShadowSun ? 1u : 0u);
    block.params = glm::vec4(gi.fadeCells, 0.0f, 0.0f, 0.0f);
    std::memcpy(giUniforms.mapped, &block, sizeof(block));
    std::array<VkDescriptorBufferInfo, kGiBindings> buffers{};
    std::array<VkDescriptorImageInfo, kGiBindings> images{};
    buffers[0] = {frameUniforms.buffer, 0, sizeof(gpu::PkFrameGpu)};
    images[1] = {VK_NULL_HANDLE, position.view, VK_IMAGE_LAYOUT_GENERAL};
    images[2] = {VK_NULL_HANDLE, normal.view, VK_IMAGE_LAYOUT_GENERAL};
    images[3] = {VK_NULL_HANDLE, albedo.view, VK_IMAGE_LAYOUT_GENERAL};
    images[4] = {VK_NULL_HANDLE, color.view, VK_IMAGE_LAYOUT_GENERAL};
    buffers[5] = {giUniforms.buffer, 0, sizeof(gpu::PkGiGpu)};
    for (uint32_t j = 0; j < kMaxGiCascades; ++j) {
        // Unused bindings point at the finest cascade: every descriptor must be valid.
        buffers[6 + j] = {gi.radiance[j < gi.cascades ? j : 0], 0, VK_WHOLE_SIZE};
    }
    buffers[10] = {gi.geometry, 0, VK_WHOLE_SIZE};
    std::array<VkWriteDescriptorSet, kGiBindings> writes{};
    for (uint32_t i = 0; i < kGiBindings; ++i) {
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = giSet;
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = giDescriptorType(i);
        if (writes[i].descriptorType == VK_DESCRIPTOR_TYPE_STORAGE_IMAGE) {
            writes[i].pImageInfo = &images[i];
        } else {
            writes[i].pBufferInfo = &buffers[i];
        }
    }
    vkUpdateDescriptorSets(device(), uint32_t(writes.size()), writes.data(), 0, nullptr);
    return {};
}

} // namespace probekit::runtime
