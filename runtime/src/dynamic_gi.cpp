#include "probekit/runtime/dynamic_gi.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

#include "gi_twin.hpp"
#include "vk_util.hpp"

namespace probekit::runtime {

using detail::Buffer;

namespace {

// Every gi_*.comp stage runs 64 invocations per workgroup (cells, geometry cells, triangles).
constexpr uint32_t kGroupSize = 64;
// Two timestamps per timed segment; at most 1 + 3 x 4 segments per cascade.
constexpr uint32_t kMaxQueries = 2 * kMaxGiCascades * (1 + 3 * 4);

// The push constants of every stage (gi_common.glsl PkGiPush).
struct GiPush {
    glm::vec4 originCellSize{0.0f};
    glm::ivec4 info{0};
    glm::vec4 extra{0.0f};
};
static_assert(sizeof(GiPush) == 48);

// std140 PkGiFrame (gi_surface.comp, gi_inject.comp): the lights and the border sky, shared by
// every cascade, written with vkCmdUpdateBuffer inside the recorded update so that an earlier
// submission still reading it is never overwritten from the host.
struct GiLightGpu {
    glm::vec4 position{0.0f};  // xyz, w range
    glm::vec4 direction{0.0f}; // xyz as given, w cos(inner cone)
    glm::vec4 intensity{0.0f}; // rgb, w cos(outer cone)
    glm::ivec4 info{0};        // x type
};
struct GiFrameGpu {
    GiLightGpu lights[kMaxGiLights];
    glm::ivec4 counts{0};
    glm::vec4 borderSky[24];
};
static_assert(sizeof(GiFrameGpu) == kMaxGiLights * 64 + 16 + 24 * 16);

// Descriptor bindings, one layout for every stage (each uses a subset).
enum Binding : uint32_t {
    kFrame = 0,
    kVertices,
    kIndices,
    kGeometry,
    kSurfaces,
    kFieldSrc, // inject writes it; propagate reads it
    kFieldDst, // propagate writes it
    kCrossing,
    kPartials,
    kScale,
    kPass,
    kRadiance,
    kKeep, // the transfers' keep factors (gi_keep.comp writes, gi_propagate.comp reads)
    kBindingCount
};

enum Pipeline : uint32_t {
    kPGeometry = 0,
    kPKeep,
    kPSurface,
    kPInject,
    kPPropagate,
    kPReduce,
    kPResolve
};
constexpr uint32_t kPipelineCount = 7;

enum class Stage { Occupancy, Inject, Propagate, Resolve };

// Every stage reads what the previous one (a dispatch or a fill) wrote: one global memory
// dependency between compute and transfer, in both directions.
void stageBarrier(VkCommandBuffer cmd) {
    VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                            VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT |
                            VK_ACCESS_UNIFORM_READ_BIT;
    const VkPipelineStageFlags stages =
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
    vkCmdPipelineBarrier(cmd, stages, stages, 0, 1, &barrier, 0, nullptr, 0, nullptr);
}

uint32_t groups(size_t invocations) {
    return uint32_t((invocations + kGroupSize - 1) / kGroupSize);
}

float maxAbs(glm::vec3 v) {
    return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

// Angle between two directions (radians), well conditioned for small angles.
float angleBetween(glm::vec3 a, glm::vec3 b) {
    const float la = glm::length(a);
    const float lb = glm::length(b);
    if (!(la > 0.0f) || !(lb > 0.0f)) {
        return la == lb ? 0.0f : float(sh::kPi);
    }
    a /= la;
    b /= lb;
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

// Whether `now` differs from `then` (what the cascade was last lit with) beyond the thresholds.
bool lightChanged(const PunctualLight& then, const PunctualLight& now,
                  const DynamicGiSettings& settings) {
    if (then.type != now.type) {
        return true;
    }
    if (now.type != LightType::Point &&
        angleBetween(then.direction, now.direction) > settings.angleThreshold) {
        return true;
    }
    if (now.type != LightType::Directional && glm::length(now.position - then.position) >
                                                  settings.positionThreshold * settings.cellSize) {
        return true;
    }
    // Colour: the largest change of a channel relative to the brightest channel.
    const float scale = maxAbs(then.intensity);
    const float change = maxAbs(now.intensity - then.intensity);
    if (scale > 0.0f ? change > settings.colourThreshold * scale : change > 0.0f) {
        return true;
    }
    if (std::abs(now.range - then.range) >
        settings.colourThreshold * std::max(std::abs(then.range), 1e-6f)) {
        return true;
    }
    if (now.type == LightType::Spot &&
        (std::abs(std::acos(std::clamp(now.innerConeCos, -1.0f, 1.0f)) -
                  std::acos(std::clamp(then.innerConeCos, -1.0f, 1.0f))) >
             settings.angleThreshold ||
         std::abs(std::acos(std::clamp(now.outerConeCos, -1.0f, 1.0f)) -
                  std::acos(std::clamp(then.outerConeCos, -1.0f, 1.0f))) >
             settings.angleThreshold)) {
        return true;
    }
    return false;
}

bool lightsChanged(const std::vector<PunctualLight>& then, const std::vector<PunctualLight>& now,
                   const DynamicGiSettings& settings) {
    if (then.size() != now.size()) {
        return true;
    }
    for (size_t i = 0; i < now.size(); ++i) {
        if (lightChanged(then[i], now[i], settings)) {
            return true;
        }
    }
    return false;
}

// The sky: the largest change of any coefficient and channel relative to the largest
// coefficient magnitude the cascade was lit with.
bool skyChanged(const sh::ShRgb& then, const sh::ShRgb& now, const DynamicGiSettings& settings) {
    float scale = 0.0f;
    float change = 0.0f;
    for (size_t k = 0; k < then.rgb.size(); ++k) {
        scale = std::max(scale, maxAbs(then.rgb[k]));
        change = std::max(change, maxAbs(now.rgb[k] - then.rgb[k]));
    }
    return scale > 0.0f ? change > settings.colourThreshold * scale : change > 0.0f;
}

bool samePlacement(const GiCascadePlacement& a, const GiCascadePlacement& b) {
    return a.origin == b.origin && a.cellSize == b.cellSize && a.cells == b.cells;
}

std::string checkSettings(const DynamicGiSettings& s) {
    if (s.cascades < 1 || s.cascades > kMaxGiCascades) {
        return "cascades " + std::to_string(s.cascades) + " outside 1..4";
    }
    if (s.resolution != 32 && s.resolution != 64) {
        return "resolution " + std::to_string(s.resolution) + " is neither 32 nor 64";
    }
    if (!(s.cellSize > 0.0f) || !std::isfinite(s.cellSize)) {
        return "cellSize must be a finite number > 0";
    }
    if (s.iterations < 1 || s.iterations > 256) {
        return "iterations " + std::to_string(s.iterations) + " outside 1..256";
    }
    if (s.bounces < 1 || s.bounces > 4) {
        return "bounces " + std::to_string(s.bounces) + " outside 1..4";
    }
    if (s.updateInterval < 1) {
        return "updateInterval must be >= 1";
    }
    if (!(s.fadeCells >= 0.0f) || !std::isfinite(s.fadeCells)) {
        return "fadeCells must be a finite number >= 0";
    }
    if (!(s.propagationWeight > 0.0f && s.propagationWeight <= 1.0f)) {
        return "propagationWeight outside (0, 1]";
    }
    if (s.quality != GiQuality::L1 && s.quality != GiQuality::L1Zonal) {
        return "unknown quality";
    }
    if (!std::isfinite(s.aheadFraction) || !(s.angleThreshold >= 0.0f) ||
        !(s.positionThreshold >= 0.0f) || !(s.colourThreshold >= 0.0f)) {
        return "aheadFraction must be finite and the thresholds >= 0";
    }
    return {};
}

} // namespace

std::vector<GiCascadePlacement> placeGiCascades(const DynamicGiSettings& settings, glm::vec3 camera,
                                                glm::vec3 forward) {
    std::vector<GiCascadePlacement> out;
    for (uint32_t k = 0; k < settings.cascades; ++k) {
        GiCascadePlacement p;
        p.cellSize = settings.cellSize * float(1u << k);
        p.cells = settings.resolution;
        const float width = float(p.cells) * p.cellSize;
        const glm::vec3 centre = camera + settings.aheadFraction * width * forward;
        // Snapped down to whole cells of this cascade counted from the world origin.
        p.origin = glm::floor((centre - 0.5f * width) / p.cellSize) * p.cellSize;
        out.push_back(p);
    }
    return out;
}

// One cascade's buffers (device-local) and state.
struct GiCascadeState {
    Buffer geometry;  // (n + 1)^3 x GiGeometryCell
    Buffer surfaces;  // (n + 1)^3 x 64 bytes (gi_surface.comp)
    Buffer fields[2]; // ping-pong intensity fields, GiField layout
    Buffer crossing;  // 18 planes of n^3 floats
    Buffer pass;      // this bounce's resolved radiance, read by the next bounce's surfaces
    Buffer radiance;  // the sum over bounces: what the shading pass samples
    Buffer partials;  // two vec4 per propagation workgroup
    Buffer scale;     // vec4: the flux-conserving clamp's scale for the next step
    Buffer keep;      // 30 planes (5 d + f) of n^3 floats: each transfer's keep factor
    // Set 0 reads fields[0] and writes fields[1]; set 1 the other way round.
    VkDescriptorSet sets[2] = {VK_NULL_HANDLE, VK_NULL_HANDLE};

    // The geometry volume's placement and the geometry version it was built from (0: never).
    GiCascadePlacement builtPlacement;
    uint64_t builtVersion = 0;
    // What the radiance was last computed with.
    bool updated = false;
    uint64_t lastFrame = 0;
    GiCascadePlacement litPlacement;
    std::vector<PunctualLight> litLights;
    sh::ShRgb litSky;
    uint64_t litTuning = 0;
};

struct DynamicGi::Impl {
    GpuContext* context = nullptr;
    DynamicGiSettings settings;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
    VkPipeline pipelines[kPipelineCount] = {};
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkQueryPool queries = VK_NULL_HANDLE;
    Buffer frame; // GiFrameGpu, device-local uniform
    Buffer vertices;
    Buffer indices;
    uint32_t vertexCount = 0;
    uint32_t triangleCount = 0;
    uint64_t cascadeBytes = 0; // every cascade's buffers (gpuBytes)
    uint64_t geometryVersion = 1;
    // Bumped by setTuning when the transport changes (iterations, bounces, weight).
    uint64_t tuningVersion = 1;
    std::vector<PunctualLight> lights;
    sh::ShRgb sky;
    glm::vec3 camera{0.0f};
    glm::vec3 forward{0.0f, 0.0f, -1.0f};
    std::array<GiCascadeState, kMaxGiCascades> cascades;

    // The timed segments of the last recorded update: stage and first of its two queries.
    std::vector<std::pair<Stage, uint32_t>> segments;
    uint32_t queryCount = 0;
    mutable bool timingsRead = false;
    mutable GiTimings cachedTimings;

    ~Impl();
    VkDevice device() const { return context->device(); }
    Result<void> createPipelines();
    Result<void> createCascade(GiCascadeState& c);
    void writeSets(GiCascadeState& c);
    Result<Buffer> hostBuffer(const void* data, size_t bytes);
    Result<std::vector<uint8_t>> readBack(const Buffer& buffer) const;
    GiFrameGpu frameData() const;
    void beginSegment(VkCommandBuffer cmd, Stage stage);
    void endSegment(VkCommandBuffer cmd);
    void dispatch(VkCommandBuffer cmd, Pipeline pipeline, VkDescriptorSet set, const GiPush& push,
                  uint32_t group_count, GiUpdateStats& stats);
    void recordCascade(VkCommandBuffer cmd, GiCascadeState& c, const GiCascadePlacement& placement,
                       bool rebuild_geometry, GiUpdateStats& stats);
};

DynamicGi::Impl::~Impl() {
    if (context == nullptr) {
        return;
    }
    const VkDevice d = device();
    vkQueueWaitIdle(context->queue());
    for (GiCascadeState& c : cascades) {
        for (Buffer* b : {&c.geometry, &c.surfaces, &c.fields[0], &c.fields[1], &c.crossing,
                          &c.pass, &c.radiance, &c.partials, &c.scale, &c.keep}) {
            detail::destroy(d, *b);
        }
    }
    detail::destroy(d, frame);
    detail::destroy(d, vertices);
    detail::destroy(d, indices);
    if (queries != VK_NULL_HANDLE) {
        vkDestroyQueryPool(d, queries, nullptr);
    }
    if (pool != VK_NULL_HANDLE) {
        vkDestroyDescriptorPool(d, pool, nullptr);
    }
    for (VkPipeline p : pipelines) {
        if (p != VK_NULL_HANDLE) {
            vkDestroyPipeline(d, p, nullptr);
        }
    }
    if (pipelineLayout != VK_NULL_HANDLE) {
        vkDestroyPipelineLayout(d, pipelineLayout, nullptr);
    }
    if (setLayout != VK_NULL_HANDLE) {
        vkDestroyDescriptorSetLayout(d, setLayout, nullptr);
    }
}

Result<void> DynamicGi::Impl::createPipelines() {
    const VkDevice d = device();
    std::array<VkDescriptorSetLayoutBinding, kBindingCount> bindings{};
    for (uint32_t i = 0; i < kBindingCount; ++i) {
        bindings[i] = {
            i, i == kFrame ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
            1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
    }
    PK_TRY(detail::createDescriptorSetLayout(d, bindings, setLayout));
    const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(GiPush)};
    VkPipelineLayoutCreateInfo layout{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    layout.setLayoutCount = 1;
    layout.pSetLayouts = &setLayout;
    layout.pushConstantRangeCount = 1;
    layout.pPushConstantRanges = &push;
    PK_VK_TRY(vkCreatePipelineLayout(d, &layout, nullptr, &pipelineLayout));

    const std::array<std::pair<std::span<const uint32_t>, const char*>, kPipelineCount> shaders = {{
        {detail::spirv::giGeometryComp(), "gi_geometry.comp"},
        {detail::spirv::giKeepComp(), "gi_keep.comp"},
        {detail::spirv::giSurfaceComp(), "gi_surface.comp"},
        {detail::spirv::giInjectComp(), "gi_inject.comp"},
        {detail::spirv::giPropagateComp(), "gi_propagate.comp"},
        {detail::spirv::giReduceComp(), "gi_reduce.comp"},
        {detail::spirv::giResolveComp(), "gi_resolve.comp"},
    }};
    for (uint32_t i = 0; i < kPipelineCount; ++i) {
        Result<VkShaderModule> module = detail::createShaderModule(d, shaders[i].first);
        if (!module) {
            return module.error();
        }
        VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
        info.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
        info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
        info.stage.module = module.value();
        info.stage.pName = "main";
        info.layout = pipelineLayout;
        const VkResult r =
            vkCreateComputePipelines(d, VK_NULL_HANDLE, 1, &info, nullptr, &pipelines[i]);
        vkDestroyShaderModule(d, module.value(), nullptr);
        if (r != VK_SUCCESS) {
            return detail::vulkanError(
                (std::string("vkCreateComputePipelines (") + shaders[i].second + ")").c_str(), r);
        }
    }
    return {};
}

Result<void> DynamicGi::Impl::createCascade(GiCascadeState& c) {
    const size_t n = settings.resolution;
    const size_t cells = n * n * n;
    const size_t geometry_cells = (n + 1) * (n + 1) * (n + 1);
    constexpr VkBufferUsageFlags kUsage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                          VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                          VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
    auto make = [&](Buffer& b, size_t bytes) -> Result<void> {
        Result<Buffer> r = detail::createBuffer(*context, VkDeviceSize(bytes), kUsage, false);
        if (!r) {
            return r.error();
        }
        b = r.value();
        cascadeBytes += bytes;
        return {};
    };
    PK_TRY(make(c.geometry, geometry_cells * sizeof(GiGeometryCell)));
    PK_TRY(make(c.surfaces, geometry_cells * 64));
    PK_TRY(make(c.fields[0], 12 * cells * sizeof(float)));
    PK_TRY(make(c.fields[1], 12 * cells * sizeof(float)));
    PK_TRY(make(c.crossing, 18 * cells * sizeof(float)));
    PK_TRY(make(c.pass, 12 * cells * sizeof(float)));
    PK_TRY(make(c.radiance, 12 * cells * sizeof(float)));
    PK_TRY(make(c.partials, 2 * groups(cells) * sizeof(glm::vec4)));
    PK_TRY(make(c.scale, sizeof(glm::vec4)));
    PK_TRY(make(c.keep, 30 * cells * sizeof(float)));
    const VkDescriptorSetLayout layouts[2] = {setLayout, setLayout};
    VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocate.descriptorPool = pool;
    allocate.descriptorSetCount = 2;
    allocate.pSetLayouts = layouts;
    PK_VK_TRY(vkAllocateDescriptorSets(device(), &allocate, c.sets));
    writeSets(c);
    return {};
}

void DynamicGi::Impl::writeSets(GiCascadeState& c) {
    for (int s = 0; s < 2; ++s) {
        const std::array<const Buffer*, kBindingCount> buffers = {
            &frame,       &vertices,        &indices,    &c.geometry, &c.surfaces,
            &c.fields[s], &c.fields[1 - s], &c.crossing, &c.partials, &c.scale,
            &c.pass,      &c.radiance,      &c.keep};
        std::array<VkDescriptorBufferInfo, kBindingCount> infos{};
        std::array<VkWriteDescriptorSet, kBindingCount> writes{};
        for (uint32_t i = 0; i < kBindingCount; ++i) {
            infos[i] = {buffers[i]->buffer, 0, VK_WHOLE_SIZE};
            writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
            writes[i].dstSet = c.sets[s];
            writes[i].dstBinding = i;
            writes[i].descriptorCount = 1;
            writes[i].descriptorType =
                i == kFrame ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
            writes[i].pBufferInfo = &infos[i];
        }
        vkUpdateDescriptorSets(device(), kBindingCount, writes.data(), 0, nullptr);
    }
}

Result<Buffer> DynamicGi::Impl::hostBuffer(const void* data, size_t bytes) {
    // Never empty (a zero-sized buffer is invalid); an empty mesh dispatches no triangles.
    Result<Buffer> b = detail::createBuffer(*context, VkDeviceSize(std::max<size_t>(bytes, 16)),
                                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    if (b && bytes > 0) {
        std::memcpy(b.value().mapped, data, bytes);
    }
    return b;
}

Result<std::vector<uint8_t>> DynamicGi::Impl::readBack(const Buffer& buffer) const {
    Result<Buffer> staging =
        detail::createBuffer(*context, buffer.size, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
    if (!staging) {
        return staging.error();
    }
    Buffer s = staging.value();
    const Result<void> r = context->submitAndWait([&](VkCommandBuffer cmd) {
        VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
        barrier.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
        vkCmdPipelineBarrier(
            cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
            VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &barrier, 0, nullptr, 0, nullptr);
        const VkBufferCopy copy{0, 0, buffer.size};
        vkCmdCopyBuffer(cmd, buffer.buffer, s.buffer, 1, &copy);
        barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                             &barrier, 0, nullptr, 0, nullptr);
    });
    std::vector<uint8_t> out;
    if (r) {
        const auto* bytes = static_cast<const uint8_t*>(s.mapped);
        out.assign(bytes, bytes + buffer.size);
    }
    detail::destroy(device(), s);
    if (!r) {
        return r.error();
    }
    return out;
}

GiFrameGpu DynamicGi::Impl::frameData() const {
    GiFrameGpu f{};
    for (size_t i = 0; i < lights.size(); ++i) {
        const PunctualLight& l = lights[i];
        f.lights[i].position = glm::vec4(l.position, l.range);
        f.lights[i].direction = glm::vec4(l.direction, l.innerConeCos);
        f.lights[i].intensity = glm::vec4(l.intensity, l.outerConeCos);
        f.lights[i].info = glm::ivec4(int(l.type), 0, 0, 0);
    }
    f.counts = glm::ivec4(int(lights.size()), 0, 0, 0);
    const auto border = giBorderSky(sky);
    for (int d = 0; d < 6; ++d) {
        for (int k = 0; k < 4; ++k) {
            f.borderSky[4 * d + k] = glm::vec4(border[size_t(d)][size_t(k)], 0.0f);
        }
    }
    return f;
}

void DynamicGi::Impl::beginSegment(VkCommandBuffer cmd, Stage stage) {
    if (queries == VK_NULL_HANDLE || queryCount + 2 > kMaxQueries) {
        return;
    }
    segments.emplace_back(stage, queryCount);
    // Bottom of pipe at both ends: a segment runs from the end of the work before it to the end
    // of its own, so the segments add up to the update.
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, queryCount);
    queryCount += 2;
}

void DynamicGi::Impl::endSegment(VkCommandBuffer cmd) {
    if (queries == VK_NULL_HANDLE || segments.empty()) {
        return;
    }
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries,
                        segments.back().second + 1);
}

void DynamicGi::Impl::dispatch(VkCommandBuffer cmd, Pipeline pipeline, VkDescriptorSet set,
                               const GiPush& push, uint32_t group_count, GiUpdateStats& stats) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelines[pipeline]);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout, 0, 1, &set, 0,
                            nullptr);
    vkCmdPushConstants(cmd, pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(GiPush), &push);
    vkCmdDispatch(cmd, group_count, 1, 1);
    ++stats.dispatches;
}

void DynamicGi::Impl::recordCascade(VkCommandBuffer cmd, GiCascadeState& c,
                                    const GiCascadePlacement& placement, bool rebuild_geometry,
                                    GiUpdateStats& stats) {
    const uint32_t n = placement.cells;
    const size_t cells = size_t(n) * n * n;
    const size_t geometry_cells = size_t(n + 1) * (n + 1) * (n + 1);
    GiPush push;
    push.originCellSize = glm::vec4(placement.origin, placement.cellSize);
    push.info = glm::ivec4(int(n), 0, 0, 0);
    push.extra = glm::vec4(settings.propagationWeight, 0.0f, 0.0f, 0.0f);

    if (rebuild_geometry) {
        beginSegment(cmd, Stage::Occupancy);
        vkCmdFillBuffer(cmd, c.geometry.buffer, 0, VK_WHOLE_SIZE, 0);
        stageBarrier(cmd);
        if (triangleCount > 0) {
            GiPush g = push;
            g.info.z = int(triangleCount);
            g.info.w = int(vertexCount);
            dispatch(cmd, kPGeometry, c.sets[0], g, groups(triangleCount), stats);
            stageBarrier(cmd);
        }
        // The keep factors depend on the geometry (and the fixed weight) alone.
        dispatch(cmd, kPKeep, c.sets[0], push, groups(cells), stats);
        stageBarrier(cmd);
        endSegment(cmd);
        stats.geometryRebuilt = true;
    }
    // Bounces accumulate into the radiance.
    vkCmdFillBuffer(cmd, c.radiance.buffer, 0, VK_WHOLE_SIZE, 0);
    const uint32_t cell_groups = groups(cells);
    for (uint32_t bounce = 0; bounce < settings.bounces; ++bounce) {
        beginSegment(cmd, Stage::Inject);
        // Each bounce's crossings start at 0 and its first step reads with scale 1.
        vkCmdFillBuffer(cmd, c.crossing.buffer, 0, VK_WHOLE_SIZE, 0);
        float one = 1.0f;
        uint32_t one_bits = 0;
        std::memcpy(&one_bits, &one, sizeof(one_bits));
        vkCmdFillBuffer(cmd, c.scale.buffer, 0, VK_WHOLE_SIZE, one_bits);
        GiPush s = push;
        s.info.y = bounce == 0 ? 0 : 1;
        dispatch(cmd, kPSurface, c.sets[0], s, groups(geometry_cells), stats);
        stageBarrier(cmd);
        GiPush inject = push;
        inject.info.y = bounce == 0 ? 1 : 0; // the border sky on the first bounce only
        dispatch(cmd, kPInject, c.sets[0], inject, cell_groups, stats); // writes fields[0]
        stageBarrier(cmd);
        endSegment(cmd);

        beginSegment(cmd, Stage::Propagate);
        GiPush reduce = push;
        reduce.info.z = int(cell_groups);
        for (uint32_t it = 0; it < settings.iterations; ++it) {
            dispatch(cmd, kPPropagate, c.sets[it % 2], push, cell_groups, stats);
            stageBarrier(cmd);
            // The last step's scale would only feed a step that does not run.
            if (it + 1 < settings.iterations) {
                dispatch(cmd, kPReduce, c.sets[0], reduce, 1, stats);
                stageBarrier(cmd);
            }
        }
        endSegment(cmd);

        beginSegment(cmd, Stage::Resolve);
        dispatch(cmd, kPResolve, c.sets[0], push, cell_groups, stats);
        stageBarrier(cmd);
        endSegment(cmd);
    }
    c.builtPlacement = placement;
}

DynamicGi::DynamicGi(std::unique_ptr<Impl> impl) : m_impl(std::move(impl)) {}
DynamicGi::DynamicGi(DynamicGi&&) noexcept = default;
DynamicGi& DynamicGi::operator=(DynamicGi&&) noexcept = default;
DynamicGi::~DynamicGi() = default;

Result<DynamicGi> DynamicGi::create(GpuContext& context, const DynamicGiSettings& settings) {
    if (const std::string problem = checkSettings(settings); !problem.empty()) {
        return makeError(ErrorCode::InvalidArgument, "DynamicGi::create: " + problem);
    }
    auto impl = std::make_unique<Impl>();
    impl->context = &context;
    impl->settings = settings;
    const VkDevice d = context.device();
    PK_TRY(impl->createPipelines());

    const std::array<VkDescriptorPoolSize, 2> sizes = {{
        {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 2 * kMaxGiCascades},
        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2 * kMaxGiCascades * (kBindingCount - 1)},
    }};
    VkDescriptorPoolCreateInfo pool{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool.maxSets = 2 * kMaxGiCascades;
    pool.poolSizeCount = uint32_t(sizes.size());
    pool.pPoolSizes = sizes.data();
    PK_VK_TRY(vkCreateDescriptorPool(d, &pool, nullptr, &impl->pool));

    if (context.timestampPeriodNs() > 0.0) {
        VkQueryPoolCreateInfo query{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        query.queryType = VK_QUERY_TYPE_TIMESTAMP;
        query.queryCount = kMaxQueries;
        PK_VK_TRY(vkCreateQueryPool(d, &query, nullptr, &impl->queries));
    }

    Result<Buffer> frame = detail::createBuffer(
        context, sizeof(GiFrameGpu),
        VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
    if (!frame) {
        return frame.error();
    }
    impl->frame = frame.value();
    for (Buffer* b : {&impl->vertices, &impl->indices}) {
        Result<Buffer> r = impl->hostBuffer(nullptr, 0);
        if (!r) {
            return r.error();
        }
        *b = r.value();
    }
    for (uint32_t k = 0; k < settings.cascades; ++k) {
        PK_TRY(impl->createCascade(impl->cascades[k]));
    }
    // Defined contents before the first update: no geometry, no light.
    PK_TRY(context.submitAndWait([&](VkCommandBuffer cmd) {
        for (uint32_t k = 0; k < settings.cascades; ++k) {
            vkCmdFillBuffer(cmd, impl->cascades[k].geometry.buffer, 0, VK_WHOLE_SIZE, 0);
            vkCmdFillBuffer(cmd, impl->cascades[k].radiance.buffer, 0, VK_WHOLE_SIZE, 0);
        }
        VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        barrier.dstAccessMask =
            VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1, &barrier, 0, nullptr, 0,
                             nullptr);
    }));
    for (uint32_t k = 0; k < settings.cascades; ++k) {
        impl->cascades[k].litPlacement = placeGiCascades(settings, impl->camera, impl->forward)[k];
    }
    return DynamicGi(std::move(impl));
}

Result<void> DynamicGi::setGeometry(std::span<const RenderVertex> vertices,
                                    std::span<const uint32_t> indices) {
    if (indices.size() % 3 != 0) {
        return makeError(ErrorCode::OutOfRange,
                         "DynamicGi::setGeometry: " + std::to_string(indices.size()) +
                             " indices, not a multiple of three");
    }
    for (size_t i = 0; i < indices.size(); ++i) {
        if (indices[i] >= vertices.size()) {
            return makeError(ErrorCode::OutOfRange,
                             "DynamicGi::setGeometry: index " + std::to_string(i) + " is " +
                                 std::to_string(indices[i]) + ", past the " +
                                 std::to_string(vertices.size()) + " vertices");
        }
    }
    Impl& impl = *m_impl;
    // Earlier updates may still read the buffers replaced here (geometry changes are rare, so
    // a wait is cheaper than keeping old buffers alive per frame in flight).
    PK_TRY(impl.context->waitIdle());
    Result<Buffer> v = impl.hostBuffer(vertices.data(), vertices.size_bytes());
    if (!v) {
        return v.error();
    }
    Result<Buffer> i = impl.hostBuffer(indices.data(), indices.size_bytes());
    if (!i) {
        Buffer vb = v.value();
        detail::destroy(impl.device(), vb);
        return i.error();
    }
    detail::destroy(impl.device(), impl.vertices);
    detail::destroy(impl.device(), impl.indices);
    impl.vertices = v.value();
    impl.indices = i.value();
    impl.vertexCount = uint32_t(vertices.size());
    impl.triangleCount = uint32_t(indices.size() / 3);
    ++impl.geometryVersion;
    for (uint32_t k = 0; k < impl.settings.cascades; ++k) {
        impl.writeSets(impl.cascades[k]);
    }
    return {};
}

Result<void> DynamicGi::setLights(std::span<const PunctualLight> lights) {
    if (lights.size() > kMaxGiLights) {
        return makeError(ErrorCode::OutOfRange,
                         "DynamicGi::setLights: " + std::to_string(lights.size()) +
                             " lights, at most 8");
    }
    m_impl->lights.assign(lights.begin(), lights.end());
    return {};
}

void DynamicGi::setSky(const sh::ShRgb& radiance) {
    m_impl->sky = radiance;
}

Result<void> DynamicGi::setTuning(const DynamicGiSettings& settings) {
    if (const std::string problem = checkSettings(settings); !problem.empty()) {
        return makeError(ErrorCode::InvalidArgument, "DynamicGi::setTuning: " + problem);
    }
    DynamicGiSettings& old = m_impl->settings;
    if (settings.cascades != old.cascades || settings.resolution != old.resolution ||
        settings.cellSize != old.cellSize) {
        return makeError(ErrorCode::InvalidArgument,
                         "DynamicGi::setTuning: cascades, resolution and cellSize are fixed at "
                         "create (create another DynamicGi to change them)");
    }
    const bool weight = settings.propagationWeight != old.propagationWeight;
    if (weight) {
        ++m_impl->geometryVersion; // the keep factors are built with the geometry volume
    }
    if (weight || settings.iterations != old.iterations || settings.bounces != old.bounces) {
        ++m_impl->tuningVersion;
    }
    old = settings;
    return {};
}

void DynamicGi::setCamera(glm::vec3 position, glm::vec3 forward) {
    m_impl->camera = position;
    m_impl->forward = forward;
}

Result<GiUpdateStats> DynamicGi::recordUpdate(VkCommandBuffer cmd, uint64_t frame) {
    Impl& impl = *m_impl;
    const DynamicGiSettings& s = impl.settings;
    const std::vector<GiCascadePlacement> placements =
        placeGiCascades(s, impl.camera, impl.forward);
    std::array<bool, kMaxGiCascades> due{};
    std::array<bool, kMaxGiCascades> rebuild{};
    bool any = false;
    for (uint32_t k = 0; k < s.cascades; ++k) {
        const GiCascadeState& c = impl.cascades[k];
        rebuild[k] = c.builtVersion != impl.geometryVersion ||
                     !samePlacement(c.builtPlacement, placements[k]);
        const bool dirty = !c.updated || rebuild[k] || c.litTuning != impl.tuningVersion ||
                           lightsChanged(c.litLights, impl.lights, s) ||
                           skyChanged(c.litSky, impl.sky, s);
        const bool interval_passed = frame < c.lastFrame || frame - c.lastFrame >= s.updateInterval;
        due[k] = !c.updated || (dirty && interval_passed);
        any = any || due[k];
    }
    GiUpdateStats stats;
    if (!any) {
        return stats;
    }

    impl.segments.clear();
    impl.queryCount = 0;
    impl.timingsRead = false;
    if (impl.queries != VK_NULL_HANDLE) {
        vkCmdResetQueryPool(cmd, impl.queries, 0, kMaxQueries);
    }
    // Whatever read or wrote these buffers before (the shading pass, an earlier update) is done
    // before they are written again.
    {
        VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
        barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                                VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT |
                                VK_ACCESS_UNIFORM_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                             VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                             0, 1, &barrier, 0, nullptr, 0, nullptr);
    }
    const GiFrameGpu frame_data = impl.frameData();
    vkCmdUpdateBuffer(cmd, impl.frame.buffer, 0, sizeof(frame_data), &frame_data);
    stageBarrier(cmd);

    for (uint32_t k = 0; k < s.cascades; ++k) {
        if (!due[k]) {
            continue;
        }
        GiCascadeState& c = impl.cascades[k];
        impl.recordCascade(cmd, c, placements[k], rebuild[k], stats);
        c.builtVersion = impl.geometryVersion;
        c.updated = true;
        c.lastFrame = frame;
        c.litPlacement = placements[k];
        c.litLights = impl.lights;
        c.litSky = impl.sky;
        c.litTuning = impl.tuningVersion;
        ++stats.cascadesUpdated;
    }
    // The shading pass (a compute shader) reads the radiance and the geometry volume.
    VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &barrier, 0, nullptr, 0,
                         nullptr);
    return stats;
}

Result<GiUpdateStats> DynamicGi::update(uint64_t frame) {
    Result<GiUpdateStats> stats = GiUpdateStats{};
    PK_TRY(m_impl->context->submitAndWait(
        [&](VkCommandBuffer cmd) { stats = recordUpdate(cmd, frame); }));
    return stats;
}

GiTimings DynamicGi::timings() const {
    const Impl& impl = *m_impl;
    if (impl.queries == VK_NULL_HANDLE || impl.segments.empty()) {
        return {};
    }
    if (!impl.timingsRead) {
        std::vector<uint64_t> ticks(impl.queryCount);
        const VkResult r = vkGetQueryPoolResults(
            impl.device(), impl.queries, 0, impl.queryCount, ticks.size() * sizeof(uint64_t),
            ticks.data(), sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
        GiTimings t;
        if (r == VK_SUCCESS) {
            const double ms = impl.context->timestampPeriodNs() * 1e-6;
            std::array<double, 4> sums{};
            std::array<bool, 4> seen{};
            for (const auto& [stage, first] : impl.segments) {
                const uint64_t begin = ticks[first];
                const uint64_t end = ticks[first + 1];
                sums[size_t(stage)] += end >= begin ? double(end - begin) * ms : 0.0;
                seen[size_t(stage)] = true;
            }
            const double nan = std::numeric_limits<double>::quiet_NaN();
            t.occupancyMs = seen[0] ? sums[0] : nan;
            t.injectMs = seen[1] ? sums[1] : nan;
            t.propagateMs = seen[2] ? sums[2] : nan;
            t.resolveMs = seen[3] ? sums[3] : nan;
        }
        impl.cachedTimings = t;
        impl.timingsRead = true;
    }
    return impl.cachedTimings;
}

uint64_t DynamicGi::gpuBytes() const {
    return m_impl->cascadeBytes;
}

GiShadingInputs DynamicGi::shadingInputs() const {
    const Impl& impl = *m_impl;
    GiShadingInputs in;
    in.cascades = impl.settings.cascades;
    in.fadeCells = impl.settings.fadeCells;
    in.quality = impl.settings.quality;
    for (uint32_t k = 0; k < impl.settings.cascades; ++k) {
        in.radiance[k] = impl.cascades[k].radiance.buffer;
        in.placement[k] = impl.cascades[k].litPlacement;
    }
    in.geometry = impl.cascades[0].geometry.buffer;
    return in;
}

const DynamicGiSettings& DynamicGi::settings() const {
    return m_impl->settings;
}

std::vector<GiCascadePlacement> DynamicGi::placements() const {
    // Where the radiance in the buffers was computed (the camera's placement once updated).
    std::vector<GiCascadePlacement> out;
    for (uint32_t k = 0; k < m_impl->settings.cascades; ++k) {
        out.push_back(m_impl->cascades[k].litPlacement);
    }
    return out;
}

Result<std::vector<float>> DynamicGi::readRadiance(uint32_t cascade) const {
    if (cascade >= m_impl->settings.cascades) {
        return makeError(ErrorCode::OutOfRange,
                         "DynamicGi::readRadiance: no cascade " + std::to_string(cascade));
    }
    Result<std::vector<uint8_t>> bytes = m_impl->readBack(m_impl->cascades[cascade].radiance);
    if (!bytes) {
        return bytes.error();
    }
    std::vector<float> out(bytes.value().size() / sizeof(float));
    std::memcpy(out.data(), bytes.value().data(), out.size() * sizeof(float));
    return out;
}

Result<std::vector<int32_t>> DynamicGi::readGeometry(uint32_t cascade) const {
    if (cascade >= m_impl->settings.cascades) {
        return makeError(ErrorCode::OutOfRange,
                         "DynamicGi::readGeometry: no cascade " + std::to_string(cascade));
    }
    Result<std::vector<uint8_t>> bytes = m_impl->readBack(m_impl->cascades[cascade].geometry);
    if (!bytes) {
        return bytes.error();
    }
    std::vector<int32_t> out(bytes.value().size() / sizeof(int32_t));
    std::memcpy(out.data(), bytes.value().data(), out.size() * sizeof(int32_t));
    return out;
}

} // namespace probekit::runtime
