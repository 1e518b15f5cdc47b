#include "probekit/runtime/renderer.hpp"

#include <array>
#include <cstring>
#include <string>
#include <utility>

#include <glm/geometric.hpp>

#include "renderer_internal.hpp"

namespace probekit::runtime {

namespace {

// An icosahedron subdivided once: 80 triangles, round enough for a probe and cheap enough for
// 32^3 of them on a CPU rasteriser.
std::vector<glm::vec3> unitSphereTriangles() {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    const std::array<glm::vec3, 12> v = {
        glm::vec3(-1, t, 0), glm::vec3(1, t, 0), glm::vec3(-1, -t, 0), glm::vec3(1, -t, 0),
        glm::vec3(0, -1, t), glm::vec3(0, 1, t), glm::vec3(0, -1, -t), glm::vec3(0, 1, -t),
        glm::vec3(t, 0, -1), glm::vec3(t, 0, 1), glm::vec3(-t, 0, -1), glm::vec3(-t, 0, 1)};
    const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                              {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                              {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                              {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    std::vector<glm::vec3> out;
    for (const auto& f : faces) {
        const glm::vec3 a = glm::normalize(v[size_t(f[0])]);
        const glm::vec3 b = glm::normalize(v[size_t(f[1])]);
        const glm::vec3 c = glm::normalize(v[size_t(f[2])]);
        const glm::vec3 ab = glm::normalize(a + b);
        const glm::vec3 bc = glm::normalize(b + c);
        const glm::vec3 ca = glm::normalize(c + a);
        for (const glm::vec3& p : {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca}) {
            out.push_back(p);
        }
    }
    return out;
}

} // namespace

Renderer::Impl::~Impl() {
    if (context == nullptr) {
        return;
    }
    const VkDevice d = device();
    vkQueueWaitIdle(context->queue());
    destroyTargets();
    for (Buffer* b : {&frameUniforms, &vertices, &indices, &sphere, &instances}) {
        detail::destroy(d, *b);
    }
    for (Texture& t : textures) {
        destroyTexture(t);
    }
    if (sampler != VK_NULL_HANDLE) {
        vkDestroySampler(d, sampler, nullptr);
    }
    if (texturePool != VK_NULL_HANDLE) {
        vkDestroyDescriptorPool(d, texturePool, nullptr);
    }
    destroy(d, giUniforms);
    for (VkPipeline p : {meshPipeline, probePipeline, backgroundPipeline, shadePipeline[0],
                         shadePipeline[1], probeViewsPipeline[0], probeViewsPipeline[1],
                         fetchOnlyPipeline[0], fetchOnlyPipeline[1], giShadePipeline}) {
        if (p != VK_NULL_HANDLE) {
            vkDestroyPipeline(d, p, nullptr);
        }
    }
    for (VkPipelineLayout l : {gbufferPipelineLayout, shadePipelineLayout, giShadePipelineLayout}) {
        if (l != VK_NULL_HANDLE) {
            vkDestroyPipelineLayout(d, l, nullptr);
        }
    }
    for (VkDescriptorSetLayout l :
         {volumeLayout, frameLayout, shadeLayout, textureLayout, giLayout}) {
        if (l != VK_NULL_HANDLE) {
            vkDestroyDescriptorSetLayout(d, l, nullptr);
        }
    }
    if (renderPass != VK_NULL_HANDLE) {
        vkDestroyRenderPass(d, renderPass, nullptr);
    }
    if (pool != VK_NULL_HANDLE) {
        vkDestroyDescriptorPool(d, pool, nullptr);
    }
    if (queries != VK_NULL_HANDLE) {
        vkDestroyQueryPool(d, queries, nullptr);
    }
}

Renderer::Renderer(std::unique_ptr<Impl> impl) : m_impl(std::move(impl)) {}
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;
Renderer::~Renderer() = default;

Result<Renderer> Renderer::create(GpuContext& context) {
    auto impl = std::make_unique<Impl>();
    impl->context = &context;
    const VkDevice d = context.device();
    impl->visibilityMode = context.deviceInfo().type == VK_PHYSICAL_DEVICE_TYPE_CPU
                               ? PK_VISIBILITY_TAPS
                               : PK_VISIBILITY_BRANCH;
    PK_TRY(impl->createPipelines());

    const VkDescriptorPoolSize sizes[3] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 4},
                                           {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, kShadeImages + 4},
                                           {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 6}};
    VkDescriptorPoolCreateInfo pool{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool.maxSets = 3;
    pool.poolSizeCount = 3;
    pool.pPoolSizes = sizes;
    PK_VK_TRY(vkCreateDescriptorPool(d, &pool, nullptr, &impl->pool));
    const VkDescriptorSetLayout layouts[2] = {impl->frameLayout, impl->shadeLayout};
    VkDescriptorSet sets[2];
    VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocate.descriptorPool = impl->pool;
    allocate.descriptorSetCount = 2;
    allocate.pSetLayouts = layouts;
    PK_VK_TRY(vkAllocateDescriptorSets(d, &allocate, sets));
    impl->frameSet = sets[0];
    impl->shadeSet = sets[1];
    allocate.descriptorSetCount = 1;
    allocate.pSetLayouts = &impl->giLayout;
    PK_VK_TRY(vkAllocateDescriptorSets(d, &allocate, &impl->giSet));
    Result<Buffer> gi_uniforms = detail::createBuffer(context, sizeof(gpu::PkGiGpu),
                                                      VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
    if (!gi_uniforms) {
        return gi_uniforms.error();
    }
    impl->giUniforms = gi_uniforms.value();

    Result<Buffer> uniforms = detail::createBuffer(
        context, sizeof(gpu::PkFrameGpu),
        VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
    if (!uniforms) {
        return uniforms.error();
    }
    impl->frameUniforms = uniforms.value();
    const VkDescriptorBufferInfo buffer{impl->frameUniforms.buffer, 0, sizeof(gpu::PkFrameGpu)};
    std::array<VkWriteDescriptorSet, 2> writes{};
    for (uint32_t i = 0; i < 2; ++i) {
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = sets[i];
        writes[i].dstBinding = 0;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
        writes[i].pBufferInfo = &buffer;
    }
    vkUpdateDescriptorSets(d, 2, writes.data(), 0, nullptr);

    const std::vector<glm::vec3> sphere = unitSphereTriangles();
    Result<Buffer> sphere_buffer = detail::createBuffer(context, sphere.size() * sizeof(glm::vec3),
                                                        VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
    if (!sphere_buffer) {
        return sphere_buffer.error();
    }
    impl->sphere = sphere_buffer.value();
    std::memcpy(impl->sphere.mapped, sphere.data(), sphere.size() * sizeof(glm::vec3));
    impl->sphereVertices = uint32_t(sphere.size());

    VkQueryPoolCreateInfo query{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    query.queryType = VK_QUERY_TYPE_TIMESTAMP;
    query.queryCount = kTimestamps;
    PK_VK_TRY(vkCreateQueryPool(d, &query, nullptr, &impl->queries));
    PK_TRY(impl->createTextureResources());
    return Renderer(std::move(impl));
}

Result<Frame> Renderer::render(GpuVolumeSet& volumes, const FrameSettings& settings) {
    Impl& impl = *m_impl;
    const uint32_t max_size = impl.context->limits().maxImageDimension2D;
    if (settings.width < 1 || settings.height < 1 || settings.width > max_size ||
        settings.height > max_size) {
        return makeError(ErrorCode::OutOfRange, "renderer: image size " +
                                                    std::to_string(settings.width) + "x" +
                                                    std::to_string(settings.height) +
                                                    " is outside 1.." + std::to_string(max_size));
    }
    if (settings.lights.size() > kMaxRenderLights) {
        return makeError(ErrorCode::OutOfRange,
                         "renderer: " + std::to_string(settings.lights.size()) +
                             " lights, at most " + std::to_string(kMaxRenderLights));
    }
    const size_t pixels = size_t(settings.width) * settings.height;
    if (!settings.lightVisibility.empty() && settings.lightVisibility.size() != pixels) {
        return makeError(ErrorCode::InvalidArgument,
                         "renderer: " + std::to_string(settings.lightVisibility.size()) +
                             " light masks for " + std::to_string(pixels) + " pixels");
    }
    const Camera& cam = settings.camera;
    if (!(cam.nearPlane > 0.0f) || !(cam.farPlane > cam.nearPlane) ||
        !(cam.verticalFovDeg > 0.0f && cam.verticalFovDeg < 180.0f) ||
        glm::length(glm::cross(cam.target - cam.eye, cam.up)) == 0.0f) {
        return makeError(ErrorCode::InvalidArgument,
                         "renderer: degenerate camera (near/far, field of view, or eye, target "
                         "and up on one line)");
    }
    if (impl.width != settings.width || impl.height != settings.height) {
        PK_TRY(impl.context->waitIdle());
        PK_TRY(impl.createTargets(settings.width, settings.height));
    }
    // The previous frame is finished (render waits for each), so the mask is free to write.
    impl.writeLightMask(settings);
    const bool gi_view = settings.view == RenderView::GiIrradiance ||
                         settings.view == RenderView::GiGeometry ||
                         settings.view == RenderView::GiAo;
    if (gi_view && !settings.dynamicGi) {
        return makeError(ErrorCode::InvalidArgument,
                         "renderer: the dynamic GI views need FrameSettings::dynamicGi");
    }
    if (settings.dynamicGi) {
        PK_TRY(impl.writeGiSet(*settings.dynamicGi, settings));
    }
    uint32_t instance_count = 0;
    impl.probeStats = {};
    if (settings.view == RenderView::Probes || settings.view == RenderView::Validity) {
        PK_TRY(impl.writeInstances(volumes, settings, instance_count));
    }

    PK_TRY(impl.context->submitAndWait(
        [&](VkCommandBuffer cmd) { impl.record(cmd, volumes, settings, instance_count); }));

    Frame frame;
    frame.width = settings.width;
    frame.height = settings.height;
    frame.probes = impl.probeStats;
    if (impl.context->timestampPeriodNs() > 0.0) {
        uint64_t ticks[kTimestamps];
        PK_VK_TRY(vkGetQueryPoolResults(impl.device(), impl.queries, 0, kTimestamps, sizeof(ticks),
                                        ticks, sizeof(uint64_t),
                                        VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
        const double ms = impl.context->timestampPeriodNs() * 1e-6;
        frame.timings.gbufferMs = double(ticks[1] - ticks[0]) * ms;
        frame.timings.shadeMs = double(ticks[2] - ticks[1]) * ms;
    }
    const auto* data = static_cast<const glm::vec4*>(impl.readback.mapped);
    if (settings.readbackColor) {
        frame.color.assign(data, data + pixels);
    }
    if (settings.readbackGBuffer) {
        frame.position.assign(data + pixels, data + 2 * pixels);
        frame.normal.assign(data + 2 * pixels, data + 3 * pixels);
    }
    return frame;
}

} // namespace probekit::runtime
