#include "probekit/runtime/point_sampler.hpp"

#include <array>
#include <cstring>
#include <string>

#include <glm/vec4.hpp>

#include "vk_util.hpp"

namespace probekit::runtime {

using detail::Buffer;

namespace {
constexpr uint32_t kGroupSize = 64; // local_size_x of irradiance_points.comp
} // namespace

struct GpuPointSampler::Impl {
    GpuContext* context = nullptr;
    VkDescriptorSetLayout volumeLayout = VK_NULL_HANDLE;
    VkDescriptorSetLayout ioLayout = VK_NULL_HANDLE;
    VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet ioSet = VK_NULL_HANDLE;
    Buffer points;  // host-visible: 2 vec4 per point
    Buffer results; // host-visible: 1 vec4 per point

    ~Impl();
    Result<void> reserve(size_t count);
};

GpuPointSampler::Impl::~Impl() {
    if (context == nullptr) {
        return;
    }
    const VkDevice d = context->device();
    vkQueueWaitIdle(context->queue());
    detail::destroy(d, points);
    detail::destroy(d, results);
    if (pool != VK_NULL_HANDLE) {
        vkDestroyDescriptorPool(d, pool, nullptr);
    }
    if (pipeline != VK_NULL_HANDLE) {
        vkDestroyPipeline(d, pipeline, nullptr);
    }
    if (pipelineLayout != VK_NULL_HANDLE) {
        vkDestroyPipelineLayout(d, pipelineLayout, nullptr);
    }
    for (VkDescriptorSetLayout layout : {volumeLayout, ioLayout}) {
        if (layout != VK_NULL_HANDLE) {
            vkDestroyDescriptorSetLayout(d, layout, nullptr);
        }
    }
}

Result<void> GpuPointSampler::Impl::reserve(size_t count) {
    const VkDeviceSize point_bytes = VkDeviceSize(count) * 2 * sizeof(glm::vec4);
    if (points.size >= point_bytes) {
        return {};
    }
    const VkDevice d = context->device();
    detail::destroy(d, points);
    detail::destroy(d, results);
    Result<Buffer> p =
        detail::createBuffer(*context, point_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    if (!p) {
        return p.error();
    }
    points = p.value();
    Result<Buffer> r =
        detail::createBuffer(*context, point_bytes / 2, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    if (!r) {
        return r.error();
    }
    results = r.value();
    const VkDescriptorBufferInfo infos[2] = {{points.buffer, 0, VK_WHOLE_SIZE},
                                             {results.buffer, 0, VK_WHOLE_SIZE}};
    std::array<VkWriteDescriptorSet, 2> writes{};
    for (uint32_t i = 0; i < 2; ++i) {
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = ioSet;
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(d, 2, writes.data(), 0, nullptr);
    return {};
}

GpuPointSampler::GpuPointSampler(std::unique_ptr<Impl> impl) : m_impl(std::move(impl)) {}
GpuPointSampler::GpuPointSampler(GpuPointSampler&&) noexcept = default;
GpuPointSampler& GpuPointSampler::operator=(GpuPointSampler&&) noexcept = default;
GpuPointSampler::~GpuPointSampler() = default;

Result<GpuPointSampler> GpuPointSampler::create(GpuContext& context) {
    auto impl = std::make_unique<Impl>();
    impl->context = &context;
    const VkDevice d = context.device();

    Result<VkDescriptorSetLayout> volume_layout = createVolumeSetLayout(context);
    if (!volume_layout) {
        return volume_layout.error();
    }
    impl->volumeLayout = volume_layout.value();
    std::array<VkDescriptorSetLayoutBinding, 2> bindings{};
    for (uint32_t i = 0; i < 2; ++i) {
        bindings[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT,
                       nullptr};
    }
    VkDescriptorSetLayoutCreateInfo io{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    io.bindingCount = 2;
    io.pBindings = bindings.data();
    PK_VK_TRY(vkCreateDescriptorSetLayout(d, &io, nullptr, &impl->ioLayout));

    const VkDescriptorSetLayout layouts[2] = {impl->volumeLayout, impl->ioLayout};
    const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(uint32_t)};
    VkPipelineLayoutCreateInfo pipeline_layout{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pipeline_layout.setLayoutCount = 2;
    pipeline_layout.pSetLayouts = layouts;
    pipeline_layout.pushConstantRangeCount = 1;
    pipeline_layout.pPushConstantRanges = &push;
    PK_VK_TRY(vkCreatePipelineLayout(d, &pipeline_layout, nullptr, &impl->pipelineLayout));

    Result<VkShaderModule> module =
        detail::createShaderModule(d, detail::spirv::irradiancePointsComp());
    if (!module) {
        return module.error();
    }
    VkComputePipelineCreateInfo pipeline{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    pipeline.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    pipeline.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    pipeline.stage.module = module.value();
    pipeline.stage.pName = "main";
    pipeline.layout = impl->pipelineLayout;
    const VkResult r =
        vkCreateComputePipelines(d, VK_NULL_HANDLE, 1, &pipeline, nullptr, &impl->pipeline);
    vkDestroyShaderModule(d, module.value(), nullptr);
    if (r != VK_SUCCESS) {
        return detail::vulkanError("vkCreateComputePipelines (irradiance_points.comp)", r);
    }

    const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2};
    VkDescriptorPoolCreateInfo pool{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool.maxSets = 1;
    pool.poolSizeCount = 1;
    pool.pPoolSizes = &size;
    PK_VK_TRY(vkCreateDescriptorPool(d, &pool, nullptr, &impl->pool));
    VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocate.descriptorPool = impl->pool;
    allocate.descriptorSetCount = 1;
    allocate.pSetLayouts = &impl->ioLayout;
    PK_VK_TRY(vkAllocateDescriptorSets(d, &allocate, &impl->ioSet));
    return GpuPointSampler(std::move(impl));
}

Result<std::vector<glm::vec3>> GpuPointSampler::irradiance(GpuVolumeSet& volumes,
                                                           std::span<const glm::vec3> positions,
                                                           std::span<const glm::vec3> normals) {
    // The staging loop below reads normals[i] for every position.
    if (positions.size() != normals.size()) {
        return makeError(ErrorCode::InvalidArgument,
                         "GpuPointSampler::irradiance: " + std::to_string(positions.size()) +
                             " positions but " + std::to_string(normals.size()) +
                             " normals (one normal per position)");
    }
    std::vector<glm::vec3> out;
    if (positions.empty()) {
        return out;
    }
    Impl& impl = *m_impl;
    // Earlier dispatches may still read the buffers reserve() replaces.
    PK_TRY(impl.context->waitIdle());
    PK_TRY(impl.reserve(positions.size()));
    auto* points = static_cast<glm::vec4*>(impl.points.mapped);
    for (size_t i = 0; i < positions.size(); ++i) {
        points[2 * i] = glm::vec4(positions[i], 1.0f);
        points[2 * i + 1] = glm::vec4(normals[i], 0.0f);
    }
    const auto count = uint32_t(positions.size());
    PK_TRY(impl.context->submitAndWait([&](VkCommandBuffer cmd) {
        volumes.recordUniformUpdate(cmd);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, impl.pipeline);
        const VkDescriptorSet sets[2] = {volumes.descriptorSet(), impl.ioSet};
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, impl.pipelineLayout, 0, 2,
                                sets, 0, nullptr);
        vkCmdPushConstants(cmd, impl.pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(count),
                           &count);
        vkCmdDispatch(cmd, (count + kGroupSize - 1) / kGroupSize, 1, 1);
        // The host reads the results after the fence.
        VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
        barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                             0, 1, &barrier, 0, nullptr, 0, nullptr);
    }));
    const auto* results = static_cast<const glm::vec4*>(impl.results.mapped);
    out.resize(positions.size());
    for (size_t i = 0; i < out.size(); ++i) {
        out[i] = glm::vec3(results[i]);
    }
    return out;
}

} // namespace probekit::runtime
