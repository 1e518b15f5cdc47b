// The renderer's render pass, descriptor set and pipeline layouts, and every pipeline: the
// G-buffer pipelines (meshes, probe spheres, background) and the shading variants.
#include <array>
#include <cstddef>
#include <span>
#include <utility>

#include "renderer_internal.hpp"

namespace probekit::runtime {

namespace {

// What both kinds of pipeline creation report on failure (one message, as before the pipelines
// were created one function each).
constexpr const char* kPipelineCalls = "vkCreateGraphicsPipelines/vkCreateComputePipelines";

// The renderer's shader modules, alive only while its pipelines are created.
class ShaderModules {
public:
    enum Index : size_t {
        GBufferVert,
        ProbeSphereVert,
        GBufferFrag,
        BackgroundVert,
        BackgroundFrag,
        Shade,
        ShadeProbeViews,
        ShadeFetchOnly,
        ShadeGi,
        kCount
    };

    explicit ShaderModules(VkDevice device) : m_device(device) {}
    ShaderModules(const ShaderModules&) = delete;
    ShaderModules& operator=(const ShaderModules&) = delete;
    ~ShaderModules() {
        for (VkShaderModule m : m_modules) {
            if (m != VK_NULL_HANDLE) {
                vkDestroyShaderModule(m_device, m, nullptr);
            }
        }
    }

    Result<void> load() {
        const std::span<const uint32_t> codes[kCount] = {
            detail::spirv::gbufferVert(),         detail::spirv::probeSphereVert(),
            detail::spirv::gbufferFrag(),         detail::spirv::backgroundVert(),
            detail::spirv::backgroundFrag(),      detail::spirv::shadeComp(),
            detail::spirv::shadeProbeViewsComp(), detail::spirv::shadeFetchOnlyComp(),
            detail::spirv::shadeGiComp()};
        for (size_t i = 0; i < kCount; ++i) {
            Result<VkShaderModule> module = detail::createShaderModule(m_device, codes[i]);
            if (!module) {
                return module.error();
            }
            m_modules[i] = module.value();
        }
        return {};
    }

    VkShaderModule operator[](Index i) const { return m_modules[i]; }

private:
    VkDevice m_device;
    std::array<VkShaderModule, kCount> m_modules{};
};

// One shading pipeline: `module` with pk_visibility_mode specialised to `visibility_mode`.
Result<void> createShadePipeline(VkDevice d, VkShaderModule module, VkPipelineLayout layout,
                                 uint32_t visibility_mode, VkPipeline& pipeline) {
    const VkSpecializationMapEntry visibility_entry{PK_CONSTANT_VISIBILITY, 0, sizeof(uint32_t)};
    const VkSpecializationInfo specialization{1, &visibility_entry, sizeof(visibility_mode),
                                              &visibility_mode};
    VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    info.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    info.stage.module = module;
    info.stage.pName = "main";
    info.stage.pSpecializationInfo = &specialization;
    info.layout = layout;
    const VkResult r = vkCreateComputePipelines(d, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
    if (r != VK_SUCCESS) {
        return detail::vulkanError(kPipelineCalls, r);
    }
    return {};
}

// The G-buffer targets (colour, then depth), cleared; the colour targets are left in GENERAL for
// the shading pass's storage-image reads and the readback copies.
std::array<VkAttachmentDescription, kAttachments> gbufferAttachments() {
    std::array<VkAttachmentDescription, kAttachments> attachments{};
    const VkFormat formats[kAttachments] = {kPositionFormat, kNormalFormat, kAlbedoFormat,
                                            kEmissionFormat, kIdFormat,     kDepthFormat};
    for (uint32_t i = 0; i < kAttachments; ++i) {
        attachments[i].format = formats[i];
        attachments[i].samples = VK_SAMPLE_COUNT_1_BIT;
        attachments[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
        attachments[i].storeOp =
            i < kColorTargets ? VK_ATTACHMENT_STORE_OP_STORE : VK_ATTACHMENT_STORE_OP_DONT_CARE;
        attachments[i].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
        attachments[i].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
        attachments[i].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        attachments[i].finalLayout = i < kColorTargets
                                         ? VK_IMAGE_LAYOUT_GENERAL
                                         : VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    }
    return attachments;
}

// What orders the G-buffer pass against the shading pass and the readback copies, from one
// frame to the next.
std::array<VkSubpassDependency, 2> gbufferDependencies() {
    std::array<VkSubpassDependency, 2> dependencies{};
    // The previous frame's shading reads and readback copies finish before the targets are
    // cleared and drawn again (write-after-read), and its depth writes before depth is cleared.
    dependencies[0].srcSubpass = VK_SUBPASS_EXTERNAL;
    dependencies[0].dstSubpass = 0;
    dependencies[0].srcStageMask = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT |
                                   VK_PIPELINE_STAGE_TRANSFER_BIT |
                                   VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
    dependencies[0].srcAccessMask = VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
    dependencies[0].dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                   VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                   VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
    dependencies[0].dstAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT |
                                    VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                                    VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
    // The G-buffer is complete before the shading pass reads it or a copy reads it back.
    dependencies[1].srcSubpass = 0;
    dependencies[1].dstSubpass = VK_SUBPASS_EXTERNAL;
    dependencies[1].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    dependencies[1].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    dependencies[1].dstStageMask =
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
    dependencies[1].dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
    return dependencies;
}

} // namespace

Result<void> Renderer::Impl::createPipelines() {
    PK_TRY(createRenderPass());
    PK_TRY(createLayouts());
    ShaderModules modules(device());
    PK_TRY(modules.load());
    PK_TRY(createMeshPipeline(modules[ShaderModules::GBufferVert],
                              modules[ShaderModules::GBufferFrag]));
    PK_TRY(createProbePipeline(modules[ShaderModules::ProbeSphereVert],
                               modules[ShaderModules::GBufferFrag]));
    // The background: no vertex input (the shader makes its triangle), no depth test or write,
    // drawn before everything else.
    const VkPipelineVertexInputStateCreateInfo no_input{
        VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    PK_TRY(createGBufferPipeline(modules[ShaderModules::BackgroundVert],
                                 modules[ShaderModules::BackgroundFrag], no_input, false,
                                 backgroundPipeline));
    // Each shading variant twice: [0] without visibility, [1] with the device's mode.
    const std::pair<VkShaderModule, VkPipeline*> shading[3] = {
        {modules[ShaderModules::Shade], shadePipeline},
        {modules[ShaderModules::ShadeProbeViews], probeViewsPipeline},
        {modules[ShaderModules::ShadeFetchOnly], fetchOnlyPipeline}};
    for (const auto& [module, pipelines] : shading) {
        for (uint32_t enabled = 0; enabled < 2; ++enabled) {
            PK_TRY(createShadePipeline(device(), module, shadePipelineLayout,
                                       enabled ? visibilityMode : PK_VISIBILITY_OFF,
                                       pipelines[enabled]));
        }
    }
    // The GI pass reads no volume: its specialisation constant is unused.
    PK_TRY(createShadePipeline(device(), modules[ShaderModules::ShadeGi], giShadePipelineLayout,
                               PK_VISIBILITY_OFF, giShadePipeline));
    return {};
}

Result<void> Renderer::Impl::createRenderPass() {
    const std::array<VkAttachmentDescription, kAttachments> attachments = gbufferAttachments();
    const std::array<VkSubpassDependency, 2> dependencies = gbufferDependencies();
    VkAttachmentReference color_refs[kColorTargets];
    for (uint32_t i = 0; i < kColorTargets; ++i) {
        color_refs[i] = {i, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    }
    const VkAttachmentReference depth_ref{kColorTargets,
                                          VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
    VkSubpassDescription subpass{};
    subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
    subpass.colorAttachmentCount = kColorTargets;
    subpass.pColorAttachments = color_refs;
    subpass.pDepthStencilAttachment = &depth_ref;
    VkRenderPassCreateInfo pass{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
    pass.attachmentCount = uint32_t(attachments.size());
    pass.pAttachments = attachments.data();
    pass.subpassCount = 1;
    pass.pSubpasses = &subpass;
    pass.dependencyCount = uint32_t(dependencies.size());
    pass.pDependencies = dependencies.data();
    PK_VK_TRY(vkCreateRenderPass(device(), &pass, nullptr, &renderPass));
    return {};
}

Result<void> Renderer::Impl::createLayouts() {
    // G-buffer pass: the frame uniforms and the light mask (render_layout.h).
    const VkDescriptorSetLayoutBinding frame_bindings[2] = {
        {0, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1,
         VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
        {PK_LIGHT_MASK_BINDING, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
         nullptr}};
    PK_TRY(detail::createDescriptorSetLayout(device(), frame_bindings, frameLayout));
    // G-buffer pass, set 1: the draw's texture (base colour, or the environment's lat-long).
    const VkDescriptorSetLayoutBinding texture_binding{0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                                                       1, VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
    PK_TRY(detail::createDescriptorSetLayout(device(), {&texture_binding, 1}, textureLayout));
    // Shading pass: the frame uniforms, then the G-buffer targets and the output image.
    std::array<VkDescriptorSetLayoutBinding, 1 + kShadeImages> shade_bindings{};
    shade_bindings[0] = {0, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT,
                         nullptr};
    for (uint32_t i = 1; i <= kShadeImages; ++i) {
        shade_bindings[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT,
                             nullptr};
    }
    PK_TRY(detail::createDescriptorSetLayout(device(), shade_bindings, shadeLayout));
    Result<VkDescriptorSetLayout> volume_layout = createVolumeSetLayout(*context);
    if (!volume_layout) {
        return volume_layout.error();
    }
    volumeLayout = volume_layout.value();

    VkPipelineLayoutCreateInfo pipeline_layout{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    const VkDescriptorSetLayout gbuffer_sets[2] = {frameLayout, textureLayout};
    pipeline_layout.setLayoutCount = 2;
    pipeline_layout.pSetLayouts = gbuffer_sets;
    PK_VK_TRY(vkCreatePipelineLayout(device(), &pipeline_layout, nullptr, &gbufferPipelineLayout));
    const VkDescriptorSetLayout shade_sets[2] = {volumeLayout, shadeLayout};
    pipeline_layout.setLayoutCount = 2;
    pipeline_layout.pSetLayouts = shade_sets;
    PK_VK_TRY(vkCreatePipelineLayout(device(), &pipeline_layout, nullptr, &shadePipelineLayout));
    // The dynamic GI pass (gi_shade.comp's bindings 0..10).
    std::array<VkDescriptorSetLayoutBinding, kGiBindings> gi_bindings{};
    for (uint32_t i = 0; i < kGiBindings; ++i) {
        gi_bindings[i] = {i, giDescriptorType(i), 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
    }
    PK_TRY(detail::createDescriptorSetLayout(device(), gi_bindings, giLayout));
    pipeline_layout.setLayoutCount = 1;
    pipeline_layout.pSetLayouts = &giLayout;
    PK_VK_TRY(vkCreatePipelineLayout(device(), &pipeline_layout, nullptr, &giShadePipelineLayout));
    return {};
}

Result<void> Renderer::Impl::createMeshPipeline(VkShaderModule vertex, VkShaderModule fragment) {
    const VkVertexInputBindingDescription binding{0, sizeof(RenderVertex),
                                                  VK_VERTEX_INPUT_RATE_VERTEX};
    const VkVertexInputAttributeDescription attributes[5] = {
        {0, 0, VK_FORMAT_R32G32B32_SFLOAT, uint32_t(offsetof(RenderVertex, position))},
        {1, 0, VK_FORMAT_R32G32B32_SFLOAT, uint32_t(offsetof(RenderVertex, normal))},
        {2, 0, VK_FORMAT_R32G32B32_SFLOAT, uint32_t(offsetof(RenderVertex, albedo))},
        {3, 0, VK_FORMAT_R32G32B32_SFLOAT, uint32_t(offsetof(RenderVertex, emission))},
        {4, 0, VK_FORMAT_R32G32_SFLOAT, uint32_t(offsetof(RenderVertex, uv))}};
    VkPipelineVertexInputStateCreateInfo input{
        VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    input.vertexBindingDescriptionCount = 1;
    input.pVertexBindingDescriptions = &binding;
    input.vertexAttributeDescriptionCount = 5;
    input.pVertexAttributeDescriptions = attributes;
    return createGBufferPipeline(vertex, fragment, input, true, meshPipeline);
}

Result<void> Renderer::Impl::createProbePipeline(VkShaderModule vertex, VkShaderModule fragment) {
    // The unit sphere's vertices, then one ProbeInstance per sphere.
    const VkVertexInputBindingDescription bindings[2] = {
        {0, sizeof(glm::vec3), VK_VERTEX_INPUT_RATE_VERTEX},
        {1, sizeof(ProbeInstance), VK_VERTEX_INPUT_RATE_INSTANCE}};
    const VkVertexInputAttributeDescription attributes[3] = {
        {0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0},
        {1, 1, VK_FORMAT_R32G32B32A32_SFLOAT, uint32_t(offsetof(ProbeInstance, centerRadius))},
        {2, 1, VK_FORMAT_R32_UINT, uint32_t(offsetof(ProbeInstance, id))}};
    VkPipelineVertexInputStateCreateInfo input{
        VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    input.vertexBindingDescriptionCount = 2;
    input.pVertexBindingDescriptions = bindings;
    input.vertexAttributeDescriptionCount = 3;
    input.pVertexAttributeDescriptions = attributes;
    return createGBufferPipeline(vertex, fragment, input, true, probePipeline);
}

// The state the G-buffer pipelines (meshes, probe spheres, background) share; only the shaders,
// the vertex input and whether depth is tested and written differ.
Result<void>
Renderer::Impl::createGBufferPipeline(VkShaderModule vertex, VkShaderModule fragment,
                                      const VkPipelineVertexInputStateCreateInfo& input,
                                      bool depth_tested, VkPipeline& pipeline) {
    VkPipelineShaderStageCreateInfo stages[2]{};
    for (auto& s : stages) {
        s.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
        s.pName = "main";
    }
    stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
    stages[0].module = vertex;
    stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
    stages[1].module = fragment;
    VkPipelineInputAssemblyStateCreateInfo assembly{
        VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
    assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    VkPipelineViewportStateCreateInfo viewport{
        VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
    viewport.viewportCount = 1;
    viewport.scissorCount = 1;
    VkPipelineRasterizationStateCreateInfo raster{
        VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
    raster.polygonMode = VK_POLYGON_MODE_FILL;
    raster.cullMode = VK_CULL_MODE_NONE; // two-sided surfaces
    raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    raster.lineWidth = 1.0f;
    VkPipelineMultisampleStateCreateInfo multisample{
        VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
    multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
    VkPipelineDepthStencilStateCreateInfo depth_state{
        VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
    depth_state.depthTestEnable = depth_tested ? VK_TRUE : VK_FALSE;
    depth_state.depthWriteEnable = depth_tested ? VK_TRUE : VK_FALSE;
    depth_state.depthCompareOp = VK_COMPARE_OP_LESS;
    // Identical for every target (no independentBlend feature needed); the id target ignores
    // the components it does not have.
    std::array<VkPipelineColorBlendAttachmentState, kColorTargets> blend_attachments{};
    for (auto& b : blend_attachments) {
        b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                           VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    }
    VkPipelineColorBlendStateCreateInfo blend{
        VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
    blend.attachmentCount = uint32_t(blend_attachments.size());
    blend.pAttachments = blend_attachments.data();
    const VkDynamicState dynamic_states[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
    VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
    dynamic.dynamicStateCount = 2;
    dynamic.pDynamicStates = dynamic_states;

    VkGraphicsPipelineCreateInfo info{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
    info.stageCount = 2;
    info.pStages = stages;
    info.pVertexInputState = &input;
    info.pInputAssemblyState = &assembly;
    info.pViewportState = &viewport;
    info.pRasterizationState = &raster;
    info.pMultisampleState = &multisample;
    info.pDepthStencilState = &depth_state;
    info.pColorBlendState = &blend;
    info.pDynamicState = &dynamic;
    info.layout = gbufferPipelineLayout;
    info.renderPass = renderPass;
    info.subpass = 0;
    const VkResult r =
        vkCreateGraphicsPipelines(device(), VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
    if (r != VK_SUCCESS) {
        return detail::vulkanError(kPipelineCalls, r);
    }
    return {};
}

} // namespace probekit::runtime
