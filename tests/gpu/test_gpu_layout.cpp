// CPU-only tests of the GPU layout shared by C++ and GLSL (shaders/probe_volume_layout.h,
// shaders/render_layout.h) and of the packing that fills it (runtime/.../gpu_volumes.hpp). No
// Vulkan device needed: label unit.
#include <cmath>
#include <cstring>
#include <random>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>

#include "probe_volume_layout.h"
#include "probekit/runtime/gpu_volumes.hpp"
#include "probekit/runtime/sampler.hpp"
#include "render_layout.h"

using namespace probekit;

namespace {

// A rotation matrix and a quaternion rotate the same vector to within a few float ulps of
// coordinates of magnitude ~10.
constexpr float kTransformTolerance = 1e-5f;

Volume makeVolume(glm::uvec3 resolution, grid::PositionMode mode, sh::Order order, Storage storage,
                  grid::RigidFrame frame, int32_t priority, float fade) {
    VolumeDesc desc;
    desc.name = "layout";
    desc.grid = grid::GridLayout({glm::vec3(-1.0f, 0.5f, -3.0f), glm::vec3(3.0f, 2.5f, 5.0f)},
                                 resolution, mode, frame);
    desc.shOrder = order;
    desc.storage = storage;
    desc.blendPriority = priority;
    desc.fadeDistance = fade;
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        for (int k = 0; k < sh::coefficientCount(order); ++k) {
            probes[i].rgb[size_t(k)] = glm::vec3(float(i), float(k), float(i % 7)) * 0.125f;
        }
    }
    Result<Volume> v = probekit::makeVolume(desc, probes);
    EXPECT_TRUE(v.ok());
    return std::move(v).value();
}

// What pk_to_local and pk_volume_uvw compute from the packed rows (written out here so the
// packing can be checked against grid::GridLayout without a GPU).
glm::vec3 packedToLocal(const gpu::PkVolumeGpu& v, glm::vec3 world) {
    const glm::vec3 d = world - glm::vec3(v.worldToLocal0.w, v.worldToLocal1.w, v.worldToLocal2.w);
    return {glm::dot(glm::vec3(v.worldToLocal0), d), glm::dot(glm::vec3(v.worldToLocal1), d),
            glm::dot(glm::vec3(v.worldToLocal2), d)};
}

glm::vec3 packedGrid(const gpu::PkVolumeGpu& v, glm::vec3 local) {
    return (local - glm::vec3(v.boxMin)) / glm::vec3(v.spacing) - v.spacing.w;
}

TEST(GpuLayout, SizesAndOffsetsMatchStd140) {
    // The static_asserts in the headers are the real check; these keep the figures visible.
    EXPECT_EQ(sizeof(gpu::PkVolumeGpu), 128u);
    EXPECT_EQ(sizeof(gpu::PkVolumeSetGpu), 64u + 128u * PK_MAX_VOLUMES);
    EXPECT_EQ(offsetof(gpu::PkVolumeSetGpu, volumes) % 16, 0u);
    // The lights, then the camera basis (3 rows) and the environment (2 rows) the background
    // pass reads (render_layout.h).
    EXPECT_EQ(sizeof(gpu::PkFrameGpu), 112u + 64u * PK_MAX_LIGHTS + 5u * 16u);
    // A uniform buffer update with vkCmdUpdateBuffer is limited to 65536 bytes.
    EXPECT_LE(sizeof(gpu::PkVolumeSetGpu), 65536u);
    EXPECT_EQ(runtime::kMaxGpuVolumes, size_t(PK_MAX_VOLUMES));
}

TEST(GpuLayout, PackedTransformMatchesGridLayout) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-6.0f, 6.0f);
    for (grid::PositionMode mode : {grid::PositionMode::Center, grid::PositionMode::Corner}) {
        grid::RigidFrame frame;
        frame.rotation = glm::angleAxis(0.7f, glm::normalize(glm::vec3(1.0f, -2.0f, 0.5f)));
        frame.translation = glm::vec3(0.5f, -1.25f, 2.0f);
        const Volume v =
            makeVolume({8, 4, 16}, mode, sh::Order::L2, Storage::Float16, frame, 3, 0.25f);
        const gpu::PkVolumeGpu packed = runtime::packVolumeGpu(v.desc, 0.0f);
        for (int i = 0; i < 1000; ++i) {
            const glm::vec3 world(u(rng), u(rng), u(rng));
            const glm::vec3 local = packedToLocal(packed, world);
            const glm::vec3 expected_local = v.desc.grid.frame().toLocal(world);
            const glm::vec3 grid_coords = packedGrid(packed, local);
            const glm::vec3 expected_grid = v.desc.grid.worldToGrid(world);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(local[c], expected_local[c], kTransformTolerance);
                EXPECT_NEAR(grid_coords[c], expected_grid[c], kTransformTolerance * 16.0f);
            }
        }
        EXPECT_EQ(packed.boxMin.w, 0.25f);
        EXPECT_EQ(packed.boxMax.w, 0.0f);
        EXPECT_EQ(glm::uvec3(packed.resolution), glm::uvec3(8, 4, 16));
        EXPECT_EQ(packed.resolution.w, PK_VOLUME_FLAG_L2);
    }
}

TEST(GpuLayout, FlagsFollowOrderAndBlend) {
    const Volume l1 = makeVolume({2, 2, 2}, grid::PositionMode::Center, sh::Order::L1,
                                 Storage::Float32, {}, 0, 0.0f);
    EXPECT_EQ(runtime::packVolumeGpu(l1.desc, 0.0f).resolution.w, 0u);
    const gpu::PkVolumeGpu blended = runtime::packVolumeGpu(l1.desc, 0.5f);
    EXPECT_EQ(blended.resolution.w, PK_VOLUME_FLAG_BLEND);
    EXPECT_EQ(blended.boxMax.w, 0.5f);
}

TEST(GpuLayout, BlendOrderIsTheCpuSamplersOrder) {
    std::vector<VolumeDesc> descs;
    const int32_t priorities[] = {0, 3, 1, 3, -2, 1};
    for (int32_t p : priorities) {
        descs.push_back(makeVolume({2, 2, 2}, grid::PositionMode::Center, sh::Order::L1,
                                   Storage::Float32, {}, p, 0.0f)
                            .desc);
    }
    // Descending priority, ties in set order (VolumeSet's stable sort).
    EXPECT_EQ(runtime::blendOrder(descs), (std::vector<uint32_t>{1, 3, 2, 5, 0, 4}));
    const std::vector<float> blends(descs.size(), 0.0f);
    const gpu::PkVolumeSetGpu set = runtime::packVolumeSetGpu(descs, blends, 0.125f);
    EXPECT_EQ(set.header.x, 6u);
    EXPECT_EQ(set.params.x, 0.125f);
    const uint32_t expected[] = {1, 3, 2, 5, 0, 4};
    for (size_t i = 0; i < 6; ++i) {
        EXPECT_EQ(set.order[i / 4][int(i % 4)], expected[i]) << "position " << i;
    }
}

TEST(GpuLayout, TexelBoxIsPlaneMajorXFastest) {
    for (Storage storage : {Storage::Float32, Storage::Float16}) {
        const Volume v =
            makeVolume({4, 2, 8}, grid::PositionMode::Center, sh::Order::L2, storage, {}, 0, 0.0f);
        const glm::uvec3 first(1, 0, 2);
        const glm::uvec3 count(2, 2, 3);
        std::vector<uint8_t> bytes(runtime::texelBoxBytes(v, count));
        runtime::packTexelBox(v, first, count, bytes);
        const size_t texel = 4 * bytesPerComponent(storage);
        ASSERT_EQ(bytes.size(), size_t(v.planes()) * 12 * texel);
        const auto* source = storage == Storage::Float32
                                 ? reinterpret_cast<const uint8_t*>(v.texelsF32.data())
                                 : reinterpret_cast<const uint8_t*>(v.texelsF16.data());
        size_t at = 0;
        for (uint32_t p = 0; p < v.planes(); ++p) {
            for (uint32_t z = 0; z < count.z; ++z) {
                for (uint32_t y = 0; y < count.y; ++y) {
                    for (uint32_t x = 0; x < count.x; ++x) {
                        const size_t probe = v.desc.grid.linearIndex(first + glm::uvec3(x, y, z));
                        EXPECT_EQ(std::memcmp(bytes.data() + at,
                                              source + (p * v.probeCount() + probe) * texel, texel),
                                  0);
                        at += texel;
                    }
                }
            }
        }
        // The whole grid is the volume's own texel array.
        std::vector<uint8_t> all(runtime::texelBoxBytes(v, {4, 2, 8}));
        runtime::packTexelBox(v, glm::uvec3(0), {4, 2, 8}, all);
        ASSERT_EQ(all.size(), v.texelBytes());
        EXPECT_EQ(std::memcmp(all.data(), source, all.size()), 0);
    }
}

TEST(GpuLayout, CpuNormalOffsetIsTheOffsetPoint) {
    const Volume v = makeVolume({4, 4, 4}, grid::PositionMode::Center, sh::Order::L2,
                                Storage::Float32, {}, 0, 0.0f);
    const runtime::VolumeSet set({v});
    const glm::vec3 p(0.3f, 1.1f, 0.7f);
    const glm::vec3 n = glm::normalize(glm::vec3(0.2f, 1.0f, -0.3f));
    EXPECT_EQ(set.irradiance(p, n, 0.0f), set.irradiance(p, n));
    EXPECT_EQ(set.irradiance(p, n, 0.25f), set.irradiance(p + 0.25f * n, n));
}

} // namespace

TEST(GpuLayout, BrickAtlasSlotsArePowersOfTwoThatHoldEveryBrick) {
    for (size_t bricks : {size_t(1), size_t(2), size_t(7), size_t(18), size_t(64), size_t(65),
                          size_t(1000), size_t(262144)}) {
        const Result<glm::uvec3> a = runtime::brickAtlasSlots(bricks, 2048);
        ASSERT_TRUE(a.ok()) << a.error().message;
        const glm::uvec3 s = a.value();
        const size_t slots = size_t(s.x) * s.y * s.z;
        EXPECT_GE(slots, bricks);
        EXPECT_LT(slots, 2 * bricks + 1) << bricks << " bricks";
        for (int axis = 0; axis < 3; ++axis) {
            EXPECT_EQ(s[axis] & (s[axis] - 1), 0u) << "not a power of two";
            EXPECT_LE(s[axis] * PK_BRICK_SIZE, 2048u);
        }
        EXPECT_TRUE(s.x >= s.y && s.y >= s.z && s.x <= 2 * s.z) << s.x << "x" << s.y << "x" << s.z;
    }
    EXPECT_EQ(runtime::brickAtlasSlots(18, 2048).value(), glm::uvec3(4, 4, 2));
    // The device limit: 16 texels per axis hold 4 x 4 x 4 slots, not 65.
    EXPECT_EQ(runtime::brickAtlasSlots(64, 16).value(), glm::uvec3(4));
    EXPECT_EQ(runtime::brickAtlasSlots(65, 16).error().code, ErrorCode::OutOfRange);
    EXPECT_EQ(runtime::brickAtlasSlots(0, 2048).error().code, ErrorCode::OutOfRange);
    // Slots are filled x fastest, then y, then z.
    EXPECT_EQ(runtime::brickAtlasSlot(0, {4, 2, 2}), glm::uvec3(0, 0, 0));
    EXPECT_EQ(runtime::brickAtlasSlot(5, {4, 2, 2}), glm::uvec3(1, 1, 0));
    EXPECT_EQ(runtime::brickAtlasSlot(13, {4, 2, 2}), glm::uvec3(1, 1, 1));
}

TEST(GpuLayout, VisibilityFlagAndBinding) {
    // The flag is its own bit, set exactly when asked, with every other flag.
    const Volume l2 = makeVolume({2, 2, 2}, grid::PositionMode::Center, sh::Order::L2,
                                 Storage::Float32, {}, 0, 0.0f);
    EXPECT_EQ(runtime::packVolumeGpu(l2.desc, 0.0f).resolution.w, PK_VOLUME_FLAG_L2);
    EXPECT_EQ(runtime::packVolumeGpu(l2.desc, 0.5f, glm::uvec3(0u), true).resolution.w,
              PK_VOLUME_FLAG_L2 | PK_VOLUME_FLAG_BLEND | PK_VOLUME_FLAG_VISIBILITY);
    VolumeDesc bricked = l2.desc;
    bricked.layout = VolumeLayout::Bricked;
    bricked.bricks = brick::uniformLayout(bricked.grid.resolution(), 0);
    const gpu::PkVolumeGpu packed = runtime::packVolumeGpu(bricked, 0.0f, {2, 2, 2}, true);
    EXPECT_EQ(packed.resolution.w,
              PK_VOLUME_FLAG_L2 | PK_VOLUME_FLAG_BRICKED | PK_VOLUME_FLAG_VISIBILITY);
    // In a set, per volume.
    const std::vector<VolumeDesc> descs{l2.desc, l2.desc, l2.desc};
    const std::vector<float> blends(3, 0.0f);
    const std::vector<uint8_t> visibility{0, 1, 0};
    const gpu::PkVolumeSetGpu set = runtime::packVolumeSetGpu(descs, blends, 0.0f, {}, visibility);
    EXPECT_EQ(set.volumes[0].resolution.w & PK_VOLUME_FLAG_VISIBILITY, 0u);
    EXPECT_EQ(set.volumes[1].resolution.w & PK_VOLUME_FLAG_VISIBILITY, PK_VOLUME_FLAG_VISIBILITY);
    EXPECT_EQ(set.volumes[2].resolution.w & PK_VOLUME_FLAG_VISIBILITY, 0u);
    EXPECT_EQ(runtime::packVolumeSetGpu(descs, blends, 0.0f).volumes[1].resolution.w &
                  PK_VOLUME_FLAG_VISIBILITY,
              0u);
    // Visibility shares the integer images (PK_MAX_VOLUMES explains why): the set stays at 120
    // sampled images, and with its uniform buffer and the renderer's 7 descriptors within
    // lavapipe's maxPerStageResources of 128.
    EXPECT_EQ(PK_BINDING_VISIBILITY, PK_BINDING_INDIRECTION);
    EXPECT_EQ(PK_SAMPLED_IMAGES, 120);
    EXPECT_LE(PK_SAMPLED_IMAGES + 1 + 7, 128);
    // The shader's constants are the CPU sampler's.
    EXPECT_EQ(float(PK_VISIBILITY_RAMP), visibility::kRamp);
    EXPECT_EQ(float(PK_VISIBILITY_FLOOR), visibility::kFloor);
    EXPECT_NE(PK_VISIBILITY_OFF, PK_VISIBILITY_BRANCH);
    EXPECT_NE(PK_VISIBILITY_BRANCH, PK_VISIBILITY_TAPS);
}

TEST(GpuLayout, VisibilityTexelsArePerProbeBytesThenZeros) {
    Volume v = makeVolume({4, 2, 8}, grid::PositionMode::Center, sh::Order::L1, Storage::Float16,
                          {}, 0, 0.0f);
    std::mt19937 rng(9);
    std::uniform_int_distribution<int> byte(0, 255);
    v.visibility.resize(v.probeCount() * visibility::kBytesPerProbe);
    for (uint8_t& q : v.visibility) {
        q = uint8_t(byte(rng));
    }
    ASSERT_TRUE(validateVolume(v).ok());
    const glm::uvec3 first(1, 0, 2);
    const glm::uvec3 count(2, 2, 3);
    std::vector<uint8_t> bytes(runtime::visibilityBoxBytes(count));
    ASSERT_EQ(bytes.size(), size_t(12) * runtime::kVisibilityTexelBytes);
    runtime::packVisibilityBox(v, first, count, bytes);
    size_t at = 0;
    for (uint32_t z = 0; z < count.z; ++z) {
        for (uint32_t y = 0; y < count.y; ++y) {
            for (uint32_t x = 0; x < count.x; ++x) {
                const size_t probe = v.desc.grid.linearIndex(first + glm::uvec3(x, y, z));
                const uint8_t* q = &v.visibility[probe * visibility::kBytesPerProbe];
                const uint8_t* texel = bytes.data() + at;
                EXPECT_EQ(std::memcmp(texel, q, 6), 0);
                EXPECT_EQ(texel[6], 0);
                EXPECT_EQ(texel[7], 0);
                // Read as RG32_UINT (what the shader fetches) and as RGBA16_UINT: the same
                // memory, (q0 | q1 << 8 | q2 << 16 | q3 << 24, q4 | q5 << 8) and
                // (q0 | q1 << 8, q2 | q3 << 8, q4 | q5 << 8, 0).
                uint32_t rg[2];
                uint16_t rgba[4];
                std::memcpy(rg, texel, 8);
                std::memcpy(rgba, texel, 8);
                EXPECT_EQ(rg[0], uint32_t(q[0]) | uint32_t(q[1]) << 8 | uint32_t(q[2]) << 16 |
                                     uint32_t(q[3]) << 24);
                EXPECT_EQ(rg[1], uint32_t(q[4]) | uint32_t(q[5]) << 8);
                for (int c = 0; c < 3; ++c) {
                    EXPECT_EQ(rgba[c], uint16_t(q[2 * c] | q[2 * c + 1] << 8));
                }
                EXPECT_EQ(rgba[3], 0u);
                // pk_probe_visibility's byte selection: half-axis 2 a + side, side 0 for a
                // positive offset along the axis, 1 otherwise.
                const auto pick = [&](int axis, float o) {
                    const uint32_t shift = (axis == 1 ? 16u : 0u) + (o > 0.0f ? 0u : 8u);
                    return uint8_t((rg[axis == 2 ? 1 : 0] >> shift) & 255u);
                };
                for (int axis = 0; axis < 3; ++axis) {
                    EXPECT_EQ(pick(axis, 0.25f), q[2 * axis]);
                    EXPECT_EQ(pick(axis, -0.25f), q[2 * axis + 1]);
                }
                at += runtime::kVisibilityTexelBytes;
            }
        }
    }
    // A bricked volume's integer image: the indirection, the visibility atlas above it.
    EXPECT_EQ(runtime::brickedIntegerExtent({16, 8, 16}, {4, 2, 2}), glm::uvec3(16, 8, 24));
    EXPECT_EQ(runtime::brickedIntegerExtent({4, 2, 4}, {4, 4, 2}), glm::uvec3(16, 16, 12));
}

// The packing functions check their preconditions in every build type (gpu_volumes.hpp,
// ARCHITECTURE.md "Preconditions"): each case below would read or write past an array.
TEST(GpuLayoutDeathTest, PackingChecksItsPreconditions) {
    const Volume v = makeVolume({4, 2, 8}, grid::PositionMode::Center, sh::Order::L1,
                                Storage::Float32, {}, 0, 0.0f);
    // A box leaving the grid (x 3 + 2 > 4), an empty one, one whose end overflows, and a
    // buffer one byte short.
    std::vector<uint8_t> bytes(runtime::texelBoxBytes(v, {2, 1, 1}));
    EXPECT_DEATH(runtime::packTexelBox(v, {3, 0, 0}, {2, 1, 1}, bytes),
                 "precondition failed in packTexelBox: boxInside");
    EXPECT_DEATH(runtime::packTexelBox(v, {0, 0, 0}, {0, 1, 1}, bytes),
                 "precondition failed in packTexelBox: boxInside");
    EXPECT_DEATH(runtime::packTexelBox(v, {0xFFFFFFFFu, 0, 0}, {2, 1, 1}, bytes),
                 "precondition failed in packTexelBox: boxInside");
    std::vector<uint8_t> short_bytes(bytes.size() - 1);
    EXPECT_DEATH(runtime::packTexelBox(v, {0, 0, 0}, {2, 1, 1}, short_bytes),
                 "precondition failed in packTexelBox: bytes.size");
    Volume truncated = v;
    truncated.texelsF32.pop_back();
    EXPECT_DEATH(runtime::packTexelBox(truncated, {0, 0, 0}, {2, 1, 1}, bytes),
                 "precondition failed in packTexelBox: holdsTexels");
    Volume bricked = v;
    bricked.desc.layout = VolumeLayout::Bricked;
    EXPECT_DEATH(runtime::packTexelBox(bricked, {0, 0, 0}, {2, 1, 1}, bytes),
                 "precondition failed in packTexelBox: !isBricked");
    // Visibility: the volume has none, then a box leaving the grid.
    std::vector<uint8_t> texels(runtime::visibilityBoxBytes({2, 1, 1}));
    EXPECT_DEATH(runtime::packVisibilityBox(v, {0, 0, 0}, {2, 1, 1}, texels),
                 "precondition failed in packVisibilityBox: volume.visibility.size");
    Volume visible = v;
    visible.visibility.resize(v.probeCount() * visibility::kBytesPerProbe);
    EXPECT_DEATH(runtime::packVisibilityBox(visible, {0, 2, 0}, {2, 1, 1}, texels),
                 "precondition failed in packVisibilityBox: boxInside");
    // The uniform buffer: more volumes than it has room for, and a missing blend factor.
    const std::vector<VolumeDesc> too_many(runtime::kMaxGpuVolumes + 1, v.desc);
    const std::vector<float> blends(too_many.size(), 0.0f);
    EXPECT_DEATH(runtime::packVolumeSetGpu(too_many, blends, 0.0f),
                 "precondition failed in packVolumeSetGpu: !descs.empty");
    const std::vector<VolumeDesc> two{v.desc, v.desc};
    EXPECT_DEATH(runtime::packVolumeSetGpu(two, std::span(blends.data(), 1), 0.0f),
                 "precondition failed in packVolumeSetGpu: blends.size");
    const std::vector<uint8_t> one_flag{1};
    EXPECT_DEATH(runtime::packVolumeSetGpu(two, std::span(blends.data(), 2), 0.0f, {}, one_flag),
                 "precondition failed in packVolumeSetGpu: visibility.empty");
}
