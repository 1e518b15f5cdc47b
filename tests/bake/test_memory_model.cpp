// The bake's memory model (baker/src/memory_model.hpp): its terms against hand-computed bytes,
// its BVH constants against Embree's own count, and the refusals of bakes too big for
// max_memory_mb before they allocate. Prediction against measured peaks of real bakes is
// checked end to end in tests/cli/cli_test.sh (a whole process, where the peak is clean).
#include <chrono>
#include <cmath>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "bake_test_support.hpp"
#include "memory_model.hpp"
#include "methods/vpl_gather.hpp"
#include "probekit/baker/settings.hpp"
#include "trace/ray_tracer.hpp"
#include "trace/rng.hpp"
#include "volume/bricked.hpp"

namespace probekit::baker {
namespace {

// A unit quad (two triangles) with uvs and one 16 x 8 image: 4 vertices, 2 triangles.
Scene quad() {
    Scene s;
    s.positions = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}};
    s.uvs.assign(4, glm::vec2(0.0f));
    s.normals.assign(4, glm::vec3(0, 1, 0));
    s.triangles = {{0, 2, 1}, {0, 3, 2}};
    s.triangleMaterial = {0, 0};
    s.triangleNode = {-1, -1};
    s.materials.resize(1);
    Image image;
    image.width = 16;
    image.height = 8;
    image.texels.assign(16 * 8, glm::vec4(1.0f));
    s.images.push_back(image);
    s.bounds = {glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 1.0f)};
    return s;
}

VolumeDesc denseDesc(glm::uvec3 resolution, sh::Order order, Storage storage) {
    VolumeDesc d;
    d.name = "v";
    d.grid = grid::GridLayout::make({glm::vec3(0.0f), glm::vec3(1.0f)}, resolution,
                                    grid::PositionMode::Center)
                 .value();
    d.shOrder = order;
    d.storage = storage;
    return d;
}

const MemoryTerm* findTerm(const MemoryPhase& phase, const std::string& start) {
    for (const MemoryTerm& t : phase.terms) {
        if (t.what.rfind(start, 0) == 0) {
            return &t;
        }
    }
    return nullptr;
}

const MemoryPhase* findPhase(const MemoryPrediction& p, const std::string& name) {
    for (const MemoryPhase& phase : p.phases) {
        if (phase.name == name) {
            return &phase;
        }
    }
    return nullptr;
}

// The bytes of the term starting with `term` in phase `phase`; fails the test (and gives 0)
// when there is none.
uint64_t termBytes(const MemoryPrediction& p, const std::string& phase, const std::string& term) {
    const MemoryPhase* in = findPhase(p, phase);
    const MemoryTerm* t = in ? findTerm(*in, term) : nullptr;
    if (!t) {
        ADD_FAILURE() << "no term '" << term << "' in phase '" << phase << "'";
        return 0;
    }
    return t->bytes;
}

// The quad's bytes by hand: per vertex position 12, uv 8, normal 12; per triangle indices 12,
// material 4, node 4; the image 16 x 8 RGBA floats.
constexpr uint64_t kQuadArrays = 4 * (12 + 8 + 12) + 2 * (12 + 4 + 4) + 16 * 8 * 16;
// The tracer's copies (vertices and indices padded by one, a normal per triangle) and the BVH.
constexpr uint64_t kQuadTracer = 5 * 12 + 3 * 12 + 2 * (12 + kBvhBytesPerTriangle);

TEST(MemoryModel, SceneBytesCountEveryArray) {
    const Scene s = quad();
    EXPECT_EQ(sceneBytes(s), kQuadArrays + sizeof(Material));
}

// Path, 8^3 L2 half with visibility: per probe position 12, id 8, SH 9 x 12, validity 1,
// visibility 6, makeVolume's float staging 7 planes x 16 and its half texels 7 x 8, validity 1
// and visibility 6 = 310 bytes.
TEST(MemoryModel, DensePathTermsMatchHandCount) {
    const Scene s = quad();
    BakeConfig c;
    const std::vector<VolumeDesc> volumes = {
        denseDesc(glm::uvec3(8), sh::Order::L2, Storage::Float16)};
    const MemoryPrediction p = predictBakeMemory({s, c, volumes, 0, 2, 1000});
    EXPECT_EQ(termBytes(p, "baking volumes[0]'s probes", "volumes[0] ('v'): 512 probes"),
              512u * 310u);
    const MemoryPhase* probes = findPhase(p, "baking volumes[0]'s probes");
    ASSERT_NE(probes, nullptr);
    const uint64_t fixed = 1000 + kQuadArrays + sizeof(Material) + kQuadTracer + 2 * kThreadBytes;
    EXPECT_EQ(probes->bytes(), fixed + 512u * 310u);
    // The peak is the probes' phase; the BVH build holds less here.
    EXPECT_EQ(p.peakBytes, probes->bytes());
    const MemoryPhase* build = findPhase(p, "building the BVH");
    ASSERT_NE(build, nullptr);
    EXPECT_EQ(build->bytes(), 1000 + kQuadArrays + sizeof(Material) + kQuadTracer +
                                  2 * (kBvhBuildBytesPerTriangle - kBvhBytesPerTriangle));
    // What is written: texels 56, validity 1, visibility 6, twice (volumes and encoded file).
    const MemoryPhase* write = findPhase(p, "writing the file");
    ASSERT_NE(write, nullptr);
    EXPECT_EQ(write->bytes(), 1000 + kQuadArrays + sizeof(Material) + 2 * 512u * 63u);
}

// What the process held before the bake (an application's own data, a sanitizer's shadow
// memory) is in the predicted peak but not in what max_memory_mb limits: an application holding
// 8 GiB can still bake the quad at the default 4096, and the limit applies to the bake's bytes.
TEST(MemoryModel, TheProcessBytesAreReportedButNotLimited) {
    const Scene s = quad();
    BakeConfig c;
    const std::vector<VolumeDesc> volumes = {
        denseDesc(glm::uvec3(8), sh::Order::L2, Storage::Float16)};
    const uint64_t held = 8ull << 30;
    const MemoryPrediction p = predictBakeMemory({s, c, volumes, 0, 2, held});
    const MemoryPhase* probes = findPhase(p, "baking volumes[0]'s probes");
    ASSERT_NE(probes, nullptr);
    EXPECT_EQ(p.peakBytes, probes->bytes());
    EXPECT_EQ(probes->bytes() - probes->ownBytes(), held);
    EXPECT_TRUE(checkBakeMemory(p, c).ok());
    // The bake's own bytes still count: a limit below them (and above the 256 MiB floor, made
    // reachable by a 256^3 grid's 310 bytes a probe) refuses, naming the grid, not the
    // process.
    const std::vector<VolumeDesc> big = {
        denseDesc(glm::uvec3(256), sh::Order::L2, Storage::Float16)};
    const Result<void> refused = checkBakeMemory(predictBakeMemory({s, c, big, 0, 2, held}), c);
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.error().message.find("the bake's predicted peak memory 4.8 GiB (baking "
                                           "volumes[0]'s probes) exceeds max_memory_mb = 4096: "
                                           "volumes[0] ('v'): 16777216 probes need 4.8 GiB"),
              std::string::npos)
        << refused.error().message;
    EXPECT_EQ(refused.error().message.find("process"), std::string::npos)
        << refused.error().message;
}

// L1 float without visibility: position 12, id 8, SH 108, validity 1, texels 3 planes x 16
// (float staging moved into the volume), validity 1 = 178 bytes per probe.
TEST(MemoryModel, DenseL1FloatWithoutVisibility) {
    const Scene s = quad();
    BakeConfig c;
    c.visibility = false;
    const std::vector<VolumeDesc> volumes = {
        denseDesc(glm::uvec3(4, 2, 8), sh::Order::L1, Storage::Float32)};
    const MemoryPrediction p = predictBakeMemory({s, c, volumes, 0, 1, 0});
    EXPECT_EQ(termBytes(p, "baking volumes[0]'s probes", "volumes[0] ('v'): 64 probes"),
              64u * 178u);
}

// VPLs: 48 bytes each, twice while the gatherer copies them, the build order (4 bytes each) and
// 2n - 1 tree nodes of 132 bytes; after the build the copy and the tree stay.
TEST(MemoryModel, VplTermsMatchHandCount) {
    static_assert(sizeof(Vpl) == 48);
    EXPECT_EQ(VplGatherer::buildBytes(1000), 1000u * (48 + 48 + 4) + 1999u * 132u);
    EXPECT_EQ(VplGatherer::heldBytes(1000), 1000u * 48 + 1999u * 132u);
    const Scene s = quad();
    BakeConfig c;
    c.method = Method::Vpl;
    const std::vector<VolumeDesc> volumes = {
        denseDesc(glm::uvec3(2), sh::Order::L2, Storage::Float16)};
    const MemoryPrediction p = predictBakeMemory({s, c, volumes, 1000, 1, 0});
    EXPECT_EQ(termBytes(p, "tracing the VPLs", "vpl.count 1000 VPLs"), 363868u);
    EXPECT_EQ(termBytes(p, "baking volumes[0]'s probes", "vpl.count 1000 VPLs"), 311868u);
}

// LPV grid 8, 2 cascades, no occlusion, over a unit volume in an empty scene: 6 cells span the
// box plus one on each side, 8^3 = 512 cells a cascade. Propagating holds three fields
// (48 bytes a cell each) and the crossings (72): 216 a cell; each result keeps 48. Cascade 0:
// 216 x 512; cascade 1 keeps cascade 0's result and propagates twice (all lights, then those
// outside cascade 0), keeping both: peak 2 x 48 x 512 + 216 x 512, kept 3 x 48 x 512.
TEST(MemoryModel, LpvTermsMatchHandCount) {
    const Scene s;
    BakeConfig c;
    c.method = Method::Lpv;
    c.lpv.grid = 8;
    c.lpv.cascades = 2;
    c.lpv.occlusion = false;
    c.lpv.vplCount = 100;
    const std::vector<VolumeDesc> volumes = {
        denseDesc(glm::uvec3(2), sh::Order::L2, Storage::Float16)};
    const MemoryPrediction p = predictBakeMemory({s, c, volumes, 0, 1, 0});
    const std::string cells = "1024 cells of lpv.grid 8 x lpv.cascades 2";
    EXPECT_EQ(termBytes(p, "propagating volumes[0]'s cascades", cells), 2u * 48 * 512 + 216u * 512);
    EXPECT_EQ(termBytes(p, "baking volumes[0]'s probes", cells), 3u * 48 * 512);
    // Injected lights: per light 36 (position, normal, flux), 4 escape directions (48) and
    // distances (16); while injecting, the VPL set (48 each) too.
    EXPECT_EQ(termBytes(p, "injecting the LPV lights", "lpv.vpl_count 100 injected lights"),
              100u * (48 + 36 + 48 + 16));
}

// Bricked 2^3 level-0 bricks, one finer level: (2 x 3 + 1)^3 = 343 lattice probes at level 0,
// (2 x 3 x 2 + 1)^3 = 2197 with every brick refined, kBakedProbeBytes each; the refinement is
// counted at its bound and never fails the bake.
TEST(MemoryModel, BrickedTermsMatchHandCount) {
    const Scene s = quad();
    BakeConfig c;
    VolumeDesc d = denseDesc(glm::uvec3(2), sh::Order::L2, Storage::Float16);
    d.layout = VolumeLayout::Bricked;
    d.bricks.maxLevel = 1;
    const MemoryPrediction p = predictBakeMemory({s, c, {d}, 0, 1, 0});
    const MemoryPhase* probes = findPhase(p, "baking volumes[0]'s probes");
    ASSERT_NE(probes, nullptr);
    const MemoryTerm* level0 = findTerm(*probes, "volumes[0] ('v'): 343 level-0 lattice probes");
    ASSERT_NE(level0, nullptr);
    EXPECT_EQ(level0->bytes, 343u * kBakedProbeBytes);
    const MemoryTerm* refinement = findTerm(*probes, "volumes[0] ('v'): refinement");
    ASSERT_NE(refinement, nullptr);
    EXPECT_EQ(refinement->bytes, (2197u - 343u) * kBakedProbeBytes);
    EXPECT_TRUE(refinement->adapts);
    EXPECT_EQ(p.refinementBoundBytes, refinement->bytes);
    // max_memory_mb less the rest of the phase.
    ASSERT_EQ(p.brickedWorkingBytes.size(), 1u);
    EXPECT_EQ(p.brickedWorkingBytes[0],
              c.maxMemoryBytes - (probes->bytes() - level0->bytes - refinement->bytes));
}

// The BVH constants against Embree's memory monitor, over a bumpy height field and a soup of
// long overlapping triangles (spatial splits' worst case) of 10^5 triangles: measured 57.8 to
// 60.8 bytes a triangle after the build and 99.7 to 103 at its peak, so the constants (68,
// 136) are upper bounds within 25% (after) and 35% (peak) of what Embree reports.
Scene heightField(uint32_t n) {
    Scene s;
    for (uint32_t z = 0; z <= n; ++z) {
        for (uint32_t x = 0; x <= n; ++x) {
            const float fx = float(x) / float(n);
            const float fz = float(z) / float(n);
            s.positions.push_back(
                {fx * 100.0f, std::sin(fx * 40.0f) * std::cos(fz * 37.0f) * 3.0f, fz * 100.0f});
        }
    }
    for (uint32_t z = 0; z < n; ++z) {
        for (uint32_t x = 0; x < n; ++x) {
            const uint32_t a = z * (n + 1) + x;
            s.triangles.push_back({a, a + 1, a + n + 1});
            s.triangles.push_back({a + 1, a + n + 2, a + n + 1});
        }
    }
    return s;
}

Scene soup(uint32_t count) {
    Scene s;
    Rng rng(7);
    for (uint32_t i = 0; i < count; ++i) {
        const glm::vec3 c(rng.uniform() * 100.0f, rng.uniform() * 100.0f, rng.uniform() * 100.0f);
        for (int k = 0; k < 3; ++k) {
            s.positions.push_back(c +
                                  glm::vec3(rng.uniform(), rng.uniform(), rng.uniform()) * 30.0f);
        }
        s.triangles.push_back({3 * i, 3 * i + 1, 3 * i + 2});
    }
    return s;
}

TEST(MemoryModel, BvhConstantsBoundEmbreesCount) {
    for (const Scene& s : {heightField(224), soup(100000)}) {
        Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(s);
        ASSERT_TRUE(tracer.ok()) << tracer.error().message;
        const double n = double(s.triangles.size());
        const double after = double(tracer.value()->embreeBytes()) / n;
        const double peak = double(tracer.value()->embreePeakBytes()) / n;
        std::printf("[bvh] %.0f triangles: %.1f bytes a triangle after the build, %.1f at its "
                    "peak\n",
                    n, after, peak);
        EXPECT_LE(after, double(kBvhBytesPerTriangle));
        EXPECT_GE(after, 0.75 * double(kBvhBytesPerTriangle));
        EXPECT_LE(peak, double(kBvhBuildBytesPerTriangle));
        EXPECT_GE(peak, 0.65 * double(kBvhBuildBytesPerTriangle));
    }
}

// ---- Refusals before anything big is allocated ----

uint64_t peakResidentKb() {
    std::ifstream status("/proc/self/status");
    std::string line;
    while (std::getline(status, line)) {
        if (line.rfind("VmHWM:", 0) == 0) {
            return std::stoull(line.substr(6));
        }
    }
    return 0;
}

// The bake fails with a message containing `expect`, and the process's peak resident set grows
// by less than 64 MiB on the way (the bakes asked for need gigabytes, or hundreds of MiB).
void expectRefusedEarly(const Scene& scene, const BakeConfig& config, const std::string& expect) {
    const uint64_t before = peakResidentKb();
    Result<BakeResult> r = bake(scene, config);
    const uint64_t after = peakResidentKb();
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find(expect), std::string::npos) << r.error().message;
    EXPECT_LT(after - before, 64u << 10) << "KiB of peak growth before the refusal";
}

TEST(MemoryModel, RefusesTooManyVplsBeforeAllocating) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c;
    c.method = Method::Vpl;
    c.vpl.count = 16777216;
    // 16.8 M VPLs: twice 48 bytes, the order and 2n - 1 nodes of 132 bytes while the tree is
    // built: 5.7 GiB, the bake's own peak with the scene, BVH and threads (the process's own
    // bytes are not limited).
    expectRefusedEarly(scene, c,
                       "the bake's predicted peak memory 5.7 GiB (tracing the VPLs) exceeds "
                       "max_memory_mb = 4096: vpl.count 16777216 "
                       "VPLs and their light tree need 5.7 GiB (lower --vpl-count, or raise "
                       "--max-memory)");
}

TEST(MemoryModel, RefusesHugeLpvGridsBeforeAllocating) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c;
    c.method = Method::Lpv;
    c.lpv.grid = 256;
    c.lpv.cascades = 4;
    VolumeConfig v;
    v.resolution = glm::uvec3(2);
    c.volumes = {v};
    expectRefusedEarly(scene, c,
                       " GiB (propagating volumes[0]'s cascades) exceeds max_memory_mb = 4096: "
                       "65802240 cells of lpv.grid 256 x lpv.cascades 4 need 8.1 GiB (lower "
                       "--lpv-grid or --lpv-cascades, or raise --max-memory)");
}

TEST(MemoryModel, RefusesADenseGridAboveAModestLimit) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c = test::sceneVolume(1, glm::uvec3(128, 128, 64));
    // The grids alone (277 MiB by estimateBakeMemory) fit; with the makeVolume staging the
    // bake does not. The process's own bytes (libraries, about 130 MiB; about 270 under
    // AddressSanitizer) are not part of what max_memory_mb limits.
    c.maxMemoryBytes = 300ull << 20;
    expectRefusedEarly(scene, c,
                       "(baking volumes[0]'s probes) exceeds max_memory_mb = 300: volumes[0] "
                       "('volume'): 1048576 probes need 310 MiB");
}

// max_memory_mb is in MiB; values whose bytes do not fit 64 bits are refused, from a flag, the
// file and a config built in code (where maxMemoryBytes is bytes).
TEST(MemoryModel, MaxMemoryOverflowIsRefused) {
    BakeConfig c;
    Result<void> flag = setBakeSetting(c, "max_memory_mb", "17592186044416", "--max-memory");
    ASSERT_FALSE(flag.ok());
    EXPECT_EQ(flag.error().message,
              "--max-memory: max_memory_mb: must be in 1..1073741824 (got 17592186044416)");
    Result<BakeConfig> file = parseBakeConfig(R"({"max_memory_mb": 17592186044416})", "bake.json");
    ASSERT_FALSE(file.ok());
    EXPECT_EQ(file.error().message,
              "bake.json: max_memory_mb: must be in 1..1073741824 (got 17592186044416)");
    c.maxMemoryBytes = ~uint64_t(0);
    Result<void> code = validateBakeConfig(c);
    ASSERT_FALSE(code.ok());
    EXPECT_EQ(code.error().message,
              "bake config: max_memory_mb: must be in 1..1073741824 (got 17592186044415)");
    // The largest value admitted converts exactly.
    Result<BakeConfig> largest = parseBakeConfig(R"({"max_memory_mb": 1073741824})", "bake.json");
    ASSERT_TRUE(largest.ok()) << largest.error().message;
    EXPECT_EQ(largest.value().maxMemoryBytes, uint64_t(1) << 50);
}

} // namespace
} // namespace probekit::baker
