// Renderer::Impl and what the renderer's files share, each file one job (private to
// runtime/src/renderer*.cpp):
//   renderer.cpp            creation, destruction and Renderer::render
//   renderer_camera.cpp     cameras: framing a box, pixel rays, the view-projection matrix
//   renderer_pipelines.cpp  the render pass, descriptor and pipeline layouts, every pipeline
//   renderer_upload.cpp     what the application hands over: meshes, textures, the environment
//   renderer_probes.cpp     the probe spheres of the probes and validity views, and their budget
//   renderer_frame.cpp      the frame's targets, uniforms and GI set, and its commands
#pragma once

#include <cstdint>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "probekit/runtime/dynamic_gi.hpp"
#include "probekit/runtime/renderer.hpp"
#include "render_layout.h"
#include "vk_util.hpp"

namespace probekit::runtime {

using detail::Buffer;
using detail::Image;

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
inline VkDescriptorType giDescriptorType(uint32_t binding) {
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

// The camera's basis scaled to the image plane at distance 1: a pixel's ray is forward +
// ndc.x right + ndc.y up (lookAtRH's axes, so the rays match the rasterised geometry).
struct CameraBasis {
    glm::vec3 right, up, forward;
};
CameraBasis cameraBasis(const Camera& camera, float aspect);

// The camera's view and projection for the frame's size (Vulkan clip space).
glm::mat4 viewProjection(const FrameSettings& settings);

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
    Buffer readback;  // color, position, normal one after the other
    Buffer lightMask; // PK_LIGHT_MASK_BINDING (frame set): one uint per pixel, host-visible

    ~Impl();
    VkDevice device() const { return context->device(); }
    void destroyTargets();
    Result<void> createTargets(uint32_t w, uint32_t h);
    void writeShadeSet();
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
    // The light mask buffer for this frame (FrameSettings::lightVisibility, or all bits set).
    void writeLightMask(const FrameSettings& settings);
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

} // namespace probekit::runtime
