#include "probekit/runtime/renderer.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/packing.hpp>

#include "probekit/runtime/dynamic_gi.hpp"
#include "render_layout.h"
#include "vk_util.hpp"

namespace probekit::runtime {

using detail::Buffer;
using detail::Image;

namespace {

constexpr VkFormat kPositionFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kNormalFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
// Albedo (in [0, 1]) and emission need no more than half precision.
constexpr VkFormat kAlbedoFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kEmissionFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kIdFormat = VK_FORMAT_R32_UINT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
constexpr VkFormat kColorFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
// Base-colour textures and the lat-long environment: half precision (2^-11 relative, below what
// an 8-bit texture or a preview needs) halves their memory, and linear filtering of it is
// required of every device.
constexpr VkFormat kTextureFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
// G-buffer colour targets (position, normal, albedo, emission, id), then depth.
constexpr uint32_t kColorTargets = 5;
constexpr uint32_t kAttachments = kColorTargets + 1;
// Storage images of the shading pass: the colour targets and the output.
constexpr uint32_t kShadeImages = kColorTargets + 1;
constexpr uint32_t kShadeGroup = 8; // local_size of shade.comp
// Timestamps: before the G-buffer pass, between the passes, after shading.
constexpr uint32_t kTimestamps = 3;

static_assert(uint32_t(RenderView::Shaded) == PK_VIEW_SHADED &&
              uint32_t(RenderView::Irradiance) == PK_VIEW_IRRADIANCE &&
              uint32_t(RenderView::Probes) == PK_VIEW_PROBES &&
              uint32_t(RenderView::Validity) == PK_VIEW_VALIDITY &&
              uint32_t(RenderView::Leak) == PK_VIEW_LEAK &&
              uint32_t(RenderView::GiIrradiance) == PK_VIEW_GI &&
              uint32_t(RenderView::GiGeometry) == PK_VIEW_GI_GEOMETRY &&
              uint32_t(RenderView::GiAo) == PK_VIEW_GI_AO);
static_assert(kMaxGiCascades == PK_MAX_GI_CASCADES);

// gi_shade.comp's bindings: 0 frame uniforms, 1..3 G-buffer position, normal, albedo, 4 the
// output, 5 the GI uniforms, 6..9 the cascades' radiance, 10 the geometry volume.
constexpr uint32_t kGiBindings = 11;
VkDescriptorType giDescriptorType(uint32_t binding) {
    return binding == 0 || binding == 5 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER
           : binding <= 4               ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                        : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
}
static_assert(kMaxRenderLights == PK_MAX_LIGHTS);

// Per-instance data of a probe sphere (probe_sphere.vert locations 1 and 2).
struct ProbeInstance {
    glm::vec4 centerRadius;
    uint32_t id;
};
static_assert(sizeof(ProbeInstance) == 20);

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

} // namespace

Camera frameBounds(const grid::Aabb& bounds, float vertical_fov_deg, float aspect, glm::vec3 side) {
    side = glm::normalize(side);
    const glm::vec3 center = bounds.center();
    const glm::vec3 half = 0.5f * bounds.size();
    const float tan_half = std::tan(glm::radians(vertical_fov_deg) * 0.5f);
    Camera camera;
    // Seen from +-Y, +Y cannot be up: the top of the image is then the far side along Z.
    camera.up = std::abs(side.y) > 0.5f ? glm::vec3(0.0f, 0.0f, side.y > 0.0f ? -1.0f : 1.0f)
                                        : glm::vec3(0.0f, 1.0f, 0.0f);
    const glm::vec3 right = glm::normalize(glm::cross(-side, camera.up));
    const glm::vec3 up = glm::cross(right, -side);
    // The box's half extents across the image and towards the camera (support distances).
    const float across = glm::dot(glm::abs(right), half);
    const float upward = glm::dot(glm::abs(up), half);
    const float depth = glm::dot(glm::abs(side), half);
    // Distance from the near face at which the face fits both angles.
    const float fit = std::max(upward, across / std::max(aspect, 1e-6f)) / tan_half;
    const float margin = 1.1f;
    const float distance = depth + fit * margin;
    camera.verticalFovDeg = vertical_fov_deg;
    camera.target = center;
    camera.eye = center + side * distance;
    const float extent = glm::length(bounds.size());
    camera.nearPlane = std::max(1e-4f, 0.01f * distance);
    camera.farPlane = distance + 2.0f * extent + 1.0f;
    return camera;
}

namespace {

// The camera's basis scaled to the image plane at distance 1: a pixel's ray is forward +
// ndc.x right + ndc.y up (lookAtRH's axes, so the rays match the rasterised geometry).
struct CameraBasis {
    glm::vec3 right, up, forward;
};

CameraBasis cameraBasis(const Camera& camera, float aspect) {
    const glm::vec3 forward = glm::normalize(camera.target - camera.eye);
    const glm::vec3 right = glm::normalize(glm::cross(forward, camera.up));
    const glm::vec3 up = glm::cross(right, forward);
    const float tan_half = std::tan(glm::radians(camera.verticalFovDeg) * 0.5f);
    return {right * (tan_half * aspect), up * tan_half, forward};
}

} // namespace

glm::vec3 pixelDirection(const Camera& camera, uint32_t width, uint32_t height, glm::vec2 pixel) {
    const CameraBasis b = cameraBasis(camera, float(width) / float(height));
    const glm::vec2 ndc(2.0f * pixel.x / float(width) - 1.0f,
                        1.0f - 2.0f * pixel.y / float(height));
    return glm::normalize(b.forward + ndc.x * b.right + ndc.y * b.up);
}

uint32_t probeBudget(uint32_t width, uint32_t height) {
    return std::max<uint32_t>(1, uint32_t(uint64_t(width) * height / kProbePixels));
}

namespace {

// The first of setTextures's images in Renderer::Impl::textures (after white and environment).
constexpr size_t kWhiteTexture = 0;
constexpr size_t kEnvironmentTexture = 1;
constexpr size_t kUserTextures = 2;

struct Texture {
    Image image;
    VkDescriptorSet set = VK_NULL_HANDLE;
};

// indexCount indices from firstIndex, all sampling textures[texture].
struct DrawRun {
    uint32_t firstIndex = 0;
    uint32_t indexCount = 0;
    size_t texture = kWhiteTexture;
};

} // namespace

struct Renderer::Impl {
    GpuContext* context = nullptr;
    VkDescriptorSetLayout volumeLayout = VK_NULL_HANDLE;
    VkDescriptorSetLayout frameLayout = VK_NULL_HANDLE;   // G-buffer pass: frame uniforms
    VkDescriptorSetLayout shadeLayout = VK_NULL_HANDLE;   // shading: uniforms + G-buffer + output
    VkDescriptorSetLayout textureLayout = VK_NULL_HANDLE; // G-buffer pass: one sampled texture
    // The dynamic GI's shading pass (gi_shade.comp, after shade.comp): one set of the frame
    // uniforms, three G-buffer targets, the output, its uniforms, four cascades' radiance and
    // the geometry volume.
    VkDescriptorSetLayout giLayout = VK_NULL_HANDLE;
    VkPipelineLayout giShadePipelineLayout = VK_NULL_HANDLE;
    VkPipeline giShadePipeline = VK_NULL_HANDLE;
    VkDescriptorSet giSet = VK_NULL_HANDLE;
    Buffer giUniforms;
    VkPipelineLayout gbufferPipelineLayout = VK_NULL_HANDLE;
    VkPipelineLayout shadePipelineLayout = VK_NULL_HANDLE;
    VkRenderPass renderPass = VK_NULL_HANDLE;
    VkPipeline meshPipeline = VK_NULL_HANDLE;
    VkPipeline probePipeline = VK_NULL_HANDLE;
    VkPipeline backgroundPipeline = VK_NULL_HANDLE;
    // Shading pipelines by pk_visibility_mode (shaders/probe_volume.glsl): [0] specialised
    // PK_VISIBILITY_OFF, for sets without visibility (exactly the hardware-filtered code), [1]
    // visibilityMode, for sets with.
    VkPipeline shadePipeline[2] = {VK_NULL_HANDLE, VK_NULL_HANDLE};
    VkPipeline probeViewsPipeline[2] = {VK_NULL_HANDLE, VK_NULL_HANDLE};
    VkPipeline fetchOnlyPipeline[2] = {VK_NULL_HANDLE, VK_NULL_HANDLE};
    // PK_VISIBILITY_TAPS on CPU devices (which run both sides of uniform branches, so taps and
    // filtered fetches alike: lavapipe), PK_VISIBILITY_BRANCH elsewhere.
    uint32_t visibilityMode = PK_VISIBILITY_BRANCH;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet frameSet = VK_NULL_HANDLE;
    VkDescriptorSet shadeSet = VK_NULL_HANDLE;
    VkQueryPool queries = VK_NULL_HANDLE;
    Buffer frameUniforms;
    Buffer vertices;
    Buffer indices;
    uint32_t indexCount = 0;
    Buffer sphere;
    uint32_t sphereVertices = 0;
    Buffer instances;
    ProbeStats probeStats; // of the last probes or validity frame
    // Textures: [0] 1 x 1 white (untextured triangles, probe spheres), [1] the environment's
    // lat-long (or a white placeholder), then setTextures's images from kUserTextures on; each
    // with its own descriptor set from `texturePool`.
    VkSampler sampler = VK_NULL_HANDLE;
    VkDescriptorPool texturePool = VK_NULL_HANDLE;
    std::vector<Texture> textures;
    // Mesh triangles drawn in runs of one texture (setMeshes sorts them).
    std::vector<DrawRun> runs;
    uint32_t environmentType = PK_ENV_NONE;
    glm::vec4 environment{0.0f}; // PkFrameGpu.environment
    // Size-dependent targets.
    uint32_t width = 0;
    uint32_t height = 0;
    Image position, normal, albedo, emission, id, depth, color;
    VkFramebuffer framebuffer = VK_NULL_HANDLE;
    Buffer readback; // color, position, normal one after the other

    ~Impl();
    VkDevice device() const { return context->device(); }
    void destroyTargets();
    Result<void> createTargets(uint32_t w, uint32_t h);
    // Render pass, layouts and every pipeline, one function each.
    Result<void> createPipelines();
    Result<void> createRenderPass();
    Result<void> createLayouts();
    Result<void> createMeshPipeline(VkShaderModule vertex, VkShaderModule fragment);
    Result<void> createProbePipeline(VkShaderModule vertex, VkShaderModule fragment);
    Result<void> createGBufferPipeline(VkShaderModule vertex, VkShaderModule fragment,
                                       const VkPipelineVertexInputStateCreateInfo& input,
                                       bool depth_tested, VkPipeline& pipeline);
    Result<void> createTextureResources();
    // Points set 2 at the dynamic GI's buffers and fills its uniforms (no frame in flight).
    Result<void> writeGiSet(const GiShadingInputs& gi, const FrameSettings& settings);
    // Uploads `image` (linear RGBA) as textures[index], creating its descriptor set.
    Result<void> uploadTexture(const RgbaImage& image, size_t index);
    void destroyTexture(Texture& texture);
    Result<void> writeInstances(const GpuVolumeSet& volumes, const FrameSettings& settings,
                                uint32_t& count);
    // One frame's commands, in the steps below.
    void record(VkCommandBuffer cmd, GpuVolumeSet& volumes, const FrameSettings& settings,
                uint32_t instance_count);
    // The frame's uniforms for `settings` (gi: the dynamic GI's pass runs).
    gpu::PkFrameGpu frameUniformsFor(const FrameSettings& settings, bool gi) const;
    // Frame uniforms, captured in the command buffer: `frame` copied into the uniform buffer
    // between barriers against earlier reads and for the passes' reads.
    void recordFrameUniforms(VkCommandBuffer cmd, const gpu::PkFrameGpu& frame);
    // Pass 1: the environment, the meshes and the probe spheres into the G-buffer.
    void recordGBufferPass(VkCommandBuffer cmd, const FrameSettings& settings,
                           uint32_t instance_count);
    // Pass 2: the shading compute pass, then the dynamic GI's when `gi`.
    void recordShadingPass(VkCommandBuffer cmd, GpuVolumeSet& volumes,
                           const FrameSettings& settings, bool probe_views, bool gi);
    // The copies of the output (and the G-buffer's position and normal) to the readback buffer.
    void recordReadback(VkCommandBuffer cmd, const FrameSettings& settings);
};

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
    width = height = 0;
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
    VkFramebufferCreateInfo fb{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    fb.renderPass = renderPass;
    fb.attachmentCount = kAttachments;
    fb.pAttachments = attachments;
    fb.width = w;
    fb.height = h;
    fb.layers = 1;
    PK_VK_TRY(vkCreateFramebuffer(device(), &fb, nullptr, &framebuffer));

    Result<Buffer> buffer =
        detail::createBuffer(*context, VkDeviceSize(w) * h * 3 * sizeof(glm::vec4),
                             VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
    if (!buffer) {
        return buffer.error();
    }
    readback = buffer.value();

    // The shading set points at the new images.
    const VkDescriptorImageInfo images[kShadeImages] = {
        {VK_NULL_HANDLE, position.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, normal.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, albedo.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, emission.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, id.view, VK_IMAGE_LAYOUT_GENERAL},
        {VK_NULL_HANDLE, color.view, VK_IMAGE_LAYOUT_GENERAL}};
    std::array<VkWriteDescriptorSet, kShadeImages> writes{};
    for (uint32_t i = 0; i < kShadeImages; ++i) {
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = shadeSet;
        writes[i].dstBinding = i + 1;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
        writes[i].pImageInfo = &images[i];
    }
    vkUpdateDescriptorSets(device(), uint32_t(writes.size()), writes.data(), 0, nullptr);
    width = w;
    height = h;
    return {};
}

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
    // G-buffer pass: the frame uniforms alone.
    const VkDescriptorSetLayoutBinding frame_binding{
        0, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1,
        VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
    PK_TRY(detail::createDescriptorSetLayout(device(), {&frame_binding, 1}, frameLayout));
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

namespace {

// A probe the probes and validity views may draw: world position, radius before decimation,
// G-buffer id (render_layout.h), lattice coordinates (decimation keeps every stride-th).
struct ProbeCandidate {
    glm::vec3 world;
    float radius;
    uint32_t id;
    glm::uvec3 lattice;
    bool valid;
};

// Calls visit(candidate) for every probe of every volume: dense volumes' probes at their grid
// coordinates, bricked volumes' brick probe k at its finest-level lattice position (radius 0.15
// x the brick's own probe spacing); `fixed_radius` > 0 replaces the radius.
template <class Visit>
Result<void> forEachProbe(const GpuVolumeSet& volumes, float fixed_radius, const Visit& visit) {
    auto radiusOf = [&](glm::vec3 spacing) {
        return fixed_radius > 0.0f ? fixed_radius
                                   : 0.15f * std::min(spacing.x, std::min(spacing.y, spacing.z));
    };
    for (size_t s = 0; s < volumes.size(); ++s) {
        const VolumeDesc& desc = volumes.desc(s);
        const std::vector<uint8_t>& validity = volumes.validity(s);
        const uint32_t slot = uint32_t(s) << 3u;
        const grid::GridLayout& layout = desc.grid;
        if (desc.layout != VolumeLayout::Bricked) {
            const float radius = radiusOf(layout.spacing());
            for (size_t i = 0; i < layout.probeCount(); ++i) {
                const glm::uvec3 c = layout.probeCoords(i);
                const bool valid = validity[i] == kProbeValid;
                const uint32_t id = PK_KIND_PROBE | (uint32_t(valid) << 2u) | slot | (c.x << 8u) |
                                    (c.y << 16u) | (c.z << 24u);
                visit(ProbeCandidate{layout.probeWorld(c), radius, id, c, valid});
            }
            continue;
        }
        const brick::BrickLayout& bricks = desc.bricks;
        if (desc.probeCount() >= (size_t(1) << 24)) {
            return makeError(ErrorCode::OutOfRange,
                             "renderer: volume \"" + desc.name + "\" has " +
                                 std::to_string(desc.probeCount()) +
                                 " probes; the probe views show at most 2^24 per bricked volume");
        }
        const grid::Aabb& box = layout.bounds();
        const glm::uvec3 cells = brick::finestCells(layout.resolution(), bricks.maxLevel);
        // Lattice step (finest level): a finest cell holds 3 probe intervals.
        const glm::vec3 lattice_step = box.size() / (3.0f * glm::vec3(cells));
        for (size_t b = 0; b < bricks.bricks.size(); ++b) {
            const brick::Brick& br = bricks.bricks[b];
            const float radius = radiusOf(lattice_step * float(1u << (bricks.maxLevel - br.level)));
            for (uint32_t k = 0; k < brick::kBrickProbeCount; ++k) {
                const size_t probe = b * brick::kBrickProbeCount + k;
                const glm::uvec3 lattice = brick::latticeCoord(
                    br, glm::uvec3(k % 4, (k / 4) % 4, k / 16), bricks.maxLevel);
                const glm::vec3 at = box.min + glm::vec3(lattice) * lattice_step;
                const bool valid = validity[probe] == kProbeValid;
                const uint32_t id = PK_KIND_PROBE | (uint32_t(valid) << 2u) | slot |
                                    (uint32_t(br.level) << 6u) | (uint32_t(probe) << 8u);
                visit(ProbeCandidate{layout.frame().toWorld(at), radius, id, lattice, valid});
            }
        }
    }
    return {};
}

// Where a probe sphere lands in the image (probeBudget's visibility rule).
class ProbeProjector {
public:
    ProbeProjector(const FrameSettings& settings, const glm::mat4& view_projection)
        : m_viewProjection(view_projection), m_eye(settings.camera.eye),
          m_forward(glm::normalize(settings.camera.target - settings.camera.eye)),
          m_near(settings.camera.nearPlane), m_width(float(settings.width)),
          m_height(float(settings.height)),
          m_pixelsPerUnit(float(settings.height) * 0.5f /
                          std::tan(glm::radians(settings.camera.verticalFovDeg) * 0.5f)) {}

    // The sphere's distance along the view axis when it is in front of the near plane and
    // overlaps the image, else 0.
    float depthInView(glm::vec3 center, float radius) const {
        const float depth = glm::dot(center - m_eye, m_forward);
        if (!(depth > m_near)) {
            return 0.0f;
        }
        const glm::vec4 clip = m_viewProjection * glm::vec4(center, 1.0f);
        const float margin = radius * m_pixelsPerUnit / depth;
        const float x = (clip.x / clip.w * 0.5f + 0.5f) * m_width;
        const float y = (clip.y / clip.w * 0.5f + 0.5f) * m_height;
        const bool inside =
            x > -margin && x < m_width + margin && y > -margin && y < m_height + margin;
        return inside ? depth : 0.0f;
    }
    // World radius that is `pixels` on screen at `depth`.
    float worldRadius(float pixels, float depth) const { return pixels * depth / m_pixelsPerUnit; }

private:
    glm::mat4 m_viewProjection;
    glm::vec3 m_eye, m_forward;
    float m_near, m_width, m_height, m_pixelsPerUnit;
};

// How coarse a sub-grid a probe belongs to: the largest k with every lattice coordinate a
// multiple of 2^k (0 counts as a multiple of all); invalid probes in the validity view rank
// above every sub-grid, so they are the last to go.
constexpr uint32_t kProbeRanks = 32;
uint32_t probeRank(const ProbeCandidate& p, bool keep_invalid) {
    if (keep_invalid && !p.valid) {
        return kProbeRanks - 1;
    }
    auto zeros = [](uint32_t v) {
        return v == 0 ? kProbeRanks - 2 : uint32_t(std::countr_zero(v));
    };
    return std::min({zeros(p.lattice.x), zeros(p.lattice.y), zeros(p.lattice.z), kProbeRanks - 2});
}

glm::mat4 viewProjection(const FrameSettings& settings) {
    const Camera& cam = settings.camera;
    const glm::mat4 view = glm::lookAtRH(cam.eye, cam.target, cam.up);
    glm::mat4 projection = glm::perspectiveRH_ZO(glm::radians(cam.verticalFovDeg),
                                                 float(settings.width) / float(settings.height),
                                                 cam.nearPlane, cam.farPlane);
    projection[1][1] *= -1.0f; // Vulkan's clip space has +y down: row 0 is the image top
    return projection * view;
}

} // namespace

Result<void> Renderer::Impl::writeInstances(const GpuVolumeSet& volumes,
                                            const FrameSettings& settings, uint32_t& count) {
    // probeBudget's rule, in two passes over the probes (5 M of them fit no list): count the
    // visible ones by rank, pick the smallest stride 2^k that fits the budget, then write those.
    const ProbeProjector projector(settings, viewProjection(settings));
    const bool keep_invalid = settings.view == RenderView::Validity;
    ProbeStats stats;
    stats.budget = probeBudget(settings.width, settings.height);
    std::array<uint64_t, kProbeRanks> by_rank{};
    PK_TRY(forEachProbe(volumes, settings.probeRadius, [&](const ProbeCandidate& p) {
        ++stats.total;
        if (projector.depthInView(p.world, p.radius) > 0.0f) {
            ++by_rank[probeRank(p, keep_invalid)];
        }
    }));
    uint32_t rank = kProbeRanks - 1;
    uint64_t kept = by_rank[rank];
    while (rank > 0 && kept + by_rank[rank - 1] <= stats.budget) {
        kept += by_rank[--rank];
    }
    for (uint64_t n : by_rank) {
        stats.inView += n;
    }
    // The sub-grid's spacing scales the spheres, up to the coarsest sub-grid the lattice has
    // (ranks above it hold only probes at coordinate 0, or the validity view's invalid ones).
    uint32_t coarsest = 0;
    for (uint32_t r = 0; r + 2 < kProbeRanks; ++r) {
        coarsest = by_rank[r] > 0 ? r : coarsest;
    }
    const uint32_t stride_log2 = std::min(rank, coarsest);
    stats.stride = 1u << stride_log2;
    std::vector<ProbeInstance> list;
    list.reserve(std::min<uint64_t>(kept, stats.budget));
    PK_TRY(forEachProbe(volumes, settings.probeRadius, [&](const ProbeCandidate& p) {
        if (list.size() >= stats.budget || probeRank(p, keep_invalid) < rank) {
            return;
        }
        const float distance = projector.depthInView(p.world, p.radius);
        if (distance > 0.0f) {
            const float radius = std::max(p.radius * float(stats.stride),
                                          projector.worldRadius(kMinProbeRadiusPixels, distance));
            list.push_back({glm::vec4(p.world, radius), p.id});
        }
    }));
    stats.drawn = list.size();
    probeStats = stats;
    const VkDeviceSize bytes = list.size() * sizeof(ProbeInstance);
    if (instances.size < bytes) {
        // Earlier frames are complete (render waits for each), so the old buffer is free.
        detail::destroy(device(), instances);
        Result<Buffer> buffer =
            detail::createBuffer(*context, bytes, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
        if (!buffer) {
            return buffer.error();
        }
        instances = buffer.value();
    }
    if (bytes > 0) {
        std::memcpy(instances.mapped, list.data(), bytes);
    }
    count = uint32_t(list.size());
    return {};
}

namespace {

// Whether the view is one of the debug views shade.comp's PK_PROBE_VIEWS variant draws.
bool isProbeView(RenderView view) {
    return view == RenderView::Probes || view == RenderView::Validity || view == RenderView::Leak;
}

} // namespace

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
                                           {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 5}};
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

Result<void> Renderer::Impl::createTextureResources() {
    VkSamplerCreateInfo info{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    info.magFilter = VK_FILTER_LINEAR;
    info.minFilter = VK_FILTER_LINEAR;
    info.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
    info.addressModeU = VK_SAMPLER_ADDRESS_MODE_REPEAT;
    info.addressModeV = VK_SAMPLER_ADDRESS_MODE_REPEAT;
    info.addressModeW = VK_SAMPLER_ADDRESS_MODE_REPEAT;
    info.maxLod = 0.0f;
    PK_VK_TRY(vkCreateSampler(device(), &info, nullptr, &sampler));
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
    Result<Buffer> v = detail::createBuffer(*impl.context, vertices.size_bytes(),
                                            VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
    if (!v) {
        return v.error();
    }
    impl.vertices = v.value();
    std::memcpy(impl.vertices.mapped, vertices.data(), vertices.size_bytes());
    Result<Buffer> i = detail::createBuffer(*impl.context, indices.size_bytes(),
                                            VK_BUFFER_USAGE_INDEX_BUFFER_BIT, true);
    if (!i) {
        return i.error();
    }
    impl.indices = i.value();
    std::memcpy(impl.indices.mapped, sorted.data(), indices.size_bytes());
    impl.indexCount = uint32_t(indices.size());
    return {};
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
    const size_t pixels = size_t(settings.width) * settings.height;
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
