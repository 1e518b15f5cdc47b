// GPU path (GpuVolumeSet + pk_irradiance, read back through GpuPointSampler) against the CPU
// reference VolumeSet::irradiance: dense and half volumes, L1 and L2, rotated frames, overlapping
// volumes with priorities and fades, the normal offset; dynamic updates (sub-box, move, second
// state). Validation layers are on; GpuTest fails any test that produced a message.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <initializer_list>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "bricked_test_volume.hpp"
#include "gpu_test_support.hpp"
#include "probekit/runtime/gpu_volumes.hpp"
#include "probekit/runtime/point_sampler.hpp"
#include "probekit/runtime/sampler.hpp"

using namespace probekit;
using namespace probekit::gputest;
using runtime::GpuPointSampler;
using runtime::GpuVolumeSet;
using runtime::VolumeSet;

namespace {

// Tolerances, relative to the largest channel of the CPU irradiance at the point.
//
// Float volumes: both sides read the same float texels; lavapipe filters float formats with
// float weights (TrilinearWeightPrecision measures 1.2e-7, one float ulp, not 8-bit steps), so
// what remains is float rounding in a different order: the world->local rotation (matrix on
// the GPU, quaternion on the CPU), the division by the spacing (~1e-6 of a grid coordinate up
// to 16), the trilinear sum and 9-term SH sums with cancellation. Measured maxima are ~1e-5;
// 1e-3 (100x the measured maximum) leaves room for hardware with coarser arithmetic.
constexpr float kFloatRelative = 1e-3f;
// Half volumes: the texels decode exactly to float on both sides, but GPUs may filter binary16
// formats at half precision, rounding each filtered plane to 2^-11 relative (4.9e-4); SH
// evaluation sums up to nine such values with partial cancellation, hence 2e-3 (four
// times the one-plane rounding). lavapipe filters in float, so it measures as the float case.
constexpr float kHalfRelative = 2e-3f;
// Where irradiance crosses zero a relative bound means nothing: errors are measured against at
// least this fraction of the median irradiance of the test.
constexpr float kScaleFloor = 0.05f;
constexpr size_t kPointsPerCase = 12000;

struct Sample {
    glm::vec3 position;
    glm::vec3 normal;
};

glm::vec3 randomUnit(std::mt19937& rng) {
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    while (true) {
        const glm::vec3 v(gauss(rng), gauss(rng), gauss(rng));
        const float length = glm::length(v);
        if (length > 1e-3f) {
            return v / length;
        }
    }
}

// Positions inside, outside, exactly on box faces and inside fade bands, with random normals.
std::vector<Sample> samplePoints(const std::vector<Volume>& volumes, size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const grid::Aabb all = worldBounds(volumes);
    const glm::vec3 pad = 0.25f * all.size();
    std::vector<Sample> samples;
    for (size_t i = 0; i < count; ++i) {
        Sample s;
        s.normal = randomUnit(rng);
        const Volume& v = volumes[i % volumes.size()];
        const grid::Aabb& b = v.desc.grid.bounds();
        const glm::vec3 t(unit(rng), unit(rng), unit(rng));
        glm::vec3 local = b.min + t * b.size();
        switch (i % 5) {
        case 0: // anywhere around the volumes, inside or out
        case 1:
            s.position = all.min - pad + t * (all.size() + 2.0f * pad);
            samples.push_back(s);
            continue;
        case 2: { // exactly on a face
            const int axis = int(i / 5) % 3;
            local[axis] = (i / 15) % 2 == 0 ? b.min[axis] : b.max[axis];
            break;
        }
        case 3: { // within the fade band (or a thin shell) inside a face
            const int axis = int(i / 5) % 3;
            const float band = std::max(v.desc.fadeDistance, 0.05f * b.size()[axis]);
            const float depth = unit(rng) * band;
            local[axis] = (i / 15) % 2 == 0 ? b.min[axis] + depth : b.max[axis] - depth;
            break;
        }
        default: // anywhere inside
            break;
        }
        s.position = v.desc.grid.frame().toWorld(local);
        samples.push_back(s);
    }
    return samples;
}

// The GPU's trilinear weight error: a two-probe ramp sampled at 4096 fractions per axis and
// storage; the irradiance of a band-0-only volume is pi Y00 x the interpolated value, so the
// weight the GPU applied comes straight back.
struct WeightPrecision {
    double maxError = 0.0;
    size_t distinctWeights = 0; // fewest distinct values over the axes (257 for 8-bit weights)
};

WeightPrecision measureWeightPrecision(runtime::GpuContext& context) {
    WeightPrecision out;
    out.distinctWeights = SIZE_MAX;
    constexpr int kSteps = 4096;
    for (int axis = 0; axis < 3; ++axis) {
        for (Storage storage : {Storage::Float32, Storage::Float16}) {
            VolumeSpec spec;
            glm::vec3 size(1.0f);
            size[axis] = 4.0f;
            glm::uvec3 res(1u);
            res[axis] = 4;
            spec.bounds = {glm::vec3(0.0f), size};
            spec.resolution = res;
            spec.order = sh::Order::L1;
            spec.storage = storage;
            // Probes at 0.5, 1.5, 2.5, 3.5: 0 up to 1.5, 1 from 2.5.
            const std::vector<Volume> volumes{makeTestVolume(spec, [axis](glm::vec3 x) {
                sh::ShRgb s;
                s.rgb[0] = glm::vec3(x[axis] > 2.0f ? 1.0f : 0.0f);
                return s;
            })};
            Result<GpuVolumeSet> set = GpuVolumeSet::create(context, volumes);
            Result<GpuPointSampler> sampler = GpuPointSampler::create(context);
            EXPECT_TRUE(set.ok() && sampler.ok());
            if (!set.ok() || !sampler.ok()) {
                return out;
            }
            std::vector<glm::vec3> positions;
            std::vector<glm::vec3> normals(kSteps, glm::vec3(0.0f, 1.0f, 0.0f));
            for (int i = 0; i < kSteps; ++i) {
                glm::vec3 p(0.5f);
                p[axis] = 1.5f + float(i) / float(kSteps);
                positions.push_back(p);
            }
            Result<std::vector<glm::vec3>> e =
                sampler.value().irradiance(set.value(), positions, normals);
            EXPECT_TRUE(e.ok());
            if (!e.ok()) {
                return out;
            }
            std::vector<float> weights;
            for (int i = 0; i < kSteps; ++i) {
                const float weight = e.value()[size_t(i)].x / (sh::kPi * sh::kY00);
                weights.push_back(weight);
                out.maxError =
                    std::max(out.maxError, double(std::abs(weight - float(i) / float(kSteps))));
            }
            std::sort(weights.begin(), weights.end());
            out.distinctWeights =
                std::min(out.distinctWeights,
                         size_t(std::unique(weights.begin(), weights.end()) - weights.begin()));
        }
    }
    return out;
}

const WeightPrecision& weightPrecision(runtime::GpuContext& context) {
    static const WeightPrecision measured = measureWeightPrecision(context);
    return measured;
}

struct Comparison {
    float maxRelative = 0.0f; // largest error / scale seen
    size_t failures = 0;
};

// Samples the set on the GPU and the CPU and checks every point. The tolerance is
// relative * scale, plus, for hardware with coarse filtering weights, the weight error times
// the irradiance change across a probe cell around the point.
// The positions and the normals of `samples`, as GpuPointSampler::irradiance takes them.
struct SamplePoints {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> normals;
};

SamplePoints splitSamples(const std::vector<Sample>& samples) {
    SamplePoints points;
    for (const Sample& s : samples) {
        points.positions.push_back(s.position);
        points.normals.push_back(s.normal);
    }
    return points;
}

Comparison compareWithCpu(runtime::GpuContext& context, GpuVolumeSet& gpu, const VolumeSet& cpu,
                          const std::vector<Sample>& samples, float relative, float normal_offset,
                          const std::string& name) {
    Comparison out;
    Result<GpuPointSampler> sampler = GpuPointSampler::create(context);
    EXPECT_TRUE(sampler.ok()) << sampler.error().message;
    if (!sampler.ok()) {
        return out;
    }
    const SamplePoints points = splitSamples(samples);
    Result<std::vector<glm::vec3>> gpu_e =
        sampler.value().irradiance(gpu, points.positions, points.normals);
    EXPECT_TRUE(gpu_e.ok()) << gpu_e.error().message;
    if (!gpu_e.ok()) {
        return out;
    }
    std::vector<glm::vec3> cpu_e;
    std::vector<float> magnitudes;
    for (const Sample& s : samples) {
        cpu_e.push_back(cpu.irradiance(s.position, s.normal, normal_offset));
        const glm::vec3 a = glm::abs(cpu_e.back());
        magnitudes.push_back(std::max(a.x, std::max(a.y, a.z)));
    }
    std::vector<float> sorted = magnitudes;
    std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
    const float floor = kScaleFloor * sorted[sorted.size() / 2];

    float min_spacing = INFINITY;
    for (const Volume& v : cpu.volumes()) {
        const glm::vec3 spacing = v.desc.grid.spacing();
        min_spacing = std::min(min_spacing, std::min(spacing.x, std::min(spacing.y, spacing.z)));
    }
    const float weight_error = float(weightPrecision(context).maxError);

    std::string report = "x,y,z,nx,ny,nz,cpu_r,cpu_g,cpu_b,gpu_r,gpu_g,gpu_b,error,tolerance\n";
    for (size_t i = 0; i < samples.size(); ++i) {
        const Sample& s = samples[i];
        const float scale = std::max(magnitudes[i], floor);
        float cell_change = 0.0f;
        for (int axis = 0; axis < 3; ++axis) {
            glm::vec3 h(0.0f);
            h[axis] = 0.5f * min_spacing;
            const glm::vec3 d = glm::abs(cpu.irradiance(s.position + h, s.normal, normal_offset) -
                                         cpu.irradiance(s.position - h, s.normal, normal_offset));
            cell_change += std::max(d.x, std::max(d.y, d.z));
        }
        const float tolerance = relative * scale + weight_error * cell_change;
        const glm::vec3 diff = glm::abs(gpu_e.value()[i] - cpu_e[i]);
        const float error = std::max(diff.x, std::max(diff.y, diff.z));
        out.maxRelative = std::max(out.maxRelative, error / scale);
        if (!(error <= tolerance)) {
            ++out.failures;
            char row[512];
            std::snprintf(row, sizeof row,
                          "%.9g,%.9g,%.9g,%.6g,%.6g,%.6g,%.9g,%.9g,%.9g,%.9g,%.9g,"
                          "%.9g,%.3g,%.3g\n",
                          s.position.x, s.position.y, s.position.z, s.normal.x, s.normal.y,
                          s.normal.z, cpu_e[i].x, cpu_e[i].y, cpu_e[i].z, gpu_e.value()[i].x,
                          gpu_e.value()[i].y, gpu_e.value()[i].z, error, tolerance);
            report += row;
        }
    }
    if (out.failures > 0) {
        const std::string path = failureOutputPath(name + "_mismatches.csv");
        std::ofstream(path) << report;
        ADD_FAILURE() << name << ": " << out.failures << " of " << samples.size()
                      << " points differ beyond tolerance (max error / scale " << out.maxRelative
                      << ", relative tolerance " << relative << "); mismatches in " << path;
    }
    std::printf("[ figures  ] %s: %zu points, max |GPU - CPU| / scale = %.3g (tolerance %.0e)\n",
                name.c_str(), samples.size(), double(out.maxRelative), double(relative));
    return out;
}

// For each factor t of `blends`: blends volume 0 of `gpu` between its two states by t and checks
// the GPU irradiance at `samples` against the lerp of the CPU irradiance of `cpu_a` (the sets as
// with the first state) and `cpu_b` (with the second): the blending weights do not depend on the
// state, so the blend of the set is the lerp of the two sets' irradiance. The error is relative
// to the expected value, or to 5% of |a + b| where that is larger; `what` names the figures.
void expectStateBlendIsLerp(runtime::GpuContext& context, GpuVolumeSet& gpu, const VolumeSet& cpu_a,
                            const VolumeSet& cpu_b, const std::vector<Sample>& samples,
                            std::initializer_list<float> blends, float tolerance,
                            const std::string& what) {
    Result<GpuPointSampler> sampler = GpuPointSampler::create(context);
    ASSERT_TRUE(sampler.ok());
    const SamplePoints points = splitSamples(samples);
    for (float t : blends) {
        ASSERT_TRUE(gpu.setStateBlend(0, t).ok());
        Result<std::vector<glm::vec3>> e =
            sampler.value().irradiance(gpu, points.positions, points.normals);
        ASSERT_TRUE(e.ok()) << e.error().message;
        float worst = 0.0f;
        for (size_t i = 0; i < samples.size(); ++i) {
            const glm::vec3 a = cpu_a.irradiance(points.positions[i], points.normals[i]);
            const glm::vec3 b = cpu_b.irradiance(points.positions[i], points.normals[i]);
            const glm::vec3 expected = (1.0f - t) * a + t * b;
            const float scale = std::max({std::abs(expected.x), std::abs(expected.y),
                                          std::abs(expected.z), 0.05f * glm::length(a + b)});
            const glm::vec3 d = glm::abs(e.value()[i] - expected);
            worst = std::max(worst, std::max(d.x, std::max(d.y, d.z)) / scale);
        }
        std::printf("[ figures  ] %s t=%.2f: max |GPU - lerp(CPU a, CPU b)| / scale = %.3g\n",
                    what.c_str(), double(t), double(worst));
        EXPECT_LE(worst, tolerance) << "blend factor " << t;
    }
}

grid::RigidFrame rotated(float angle_deg, glm::vec3 axis, glm::vec3 translation) {
    grid::RigidFrame frame;
    frame.rotation = glm::angleAxis(glm::radians(angle_deg), glm::normalize(axis));
    frame.translation = translation;
    return frame;
}

const ProbeFunction kFieldA = skyAndLight({0.3f, 0.4f, 0.6f}, {0.3f, 2.6f, -0.4f}, 10.0f);
const ProbeFunction kFieldB = skyAndLight({0.5f, 0.3f, 0.2f}, {-1.2f, 0.5f, 1.4f}, 6.0f);
const ProbeFunction kFieldC = skyAndLight({0.1f, 0.2f, 0.1f}, {1.8f, 1.9f, 1.1f}, 25.0f);

struct Case {
    std::string name;
    std::vector<VolumeSpec> specs;
    float normalOffset = 0.0f;
};

std::vector<Case> cases() {
    std::vector<Case> out;
    VolumeSpec dense;
    dense.bounds = {glm::vec3(-2.0f, 0.0f, -2.0f), glm::vec3(2.0f, 2.0f, 2.0f)};
    dense.resolution = glm::uvec3(8, 4, 8);
    out.push_back({"dense_l2_float", {dense}});
    dense.storage = Storage::Float16;
    out.push_back({"dense_l2_half", {dense}});

    VolumeSpec l1 = dense;
    l1.order = sh::Order::L1;
    l1.storage = Storage::Float32;
    l1.mode = grid::PositionMode::Corner;
    l1.resolution = glm::uvec3(4, 8, 16);
    l1.frame = rotated(35.0f, {1.0f, 2.0f, 0.5f}, {0.3f, -0.2f, 0.1f});
    out.push_back({"l1_corner_rotated_float", {l1}});
    l1.storage = Storage::Float16;
    out.push_back({"l1_corner_rotated_half", {l1}});

    VolumeSpec l2 = dense;
    l2.frame = rotated(-60.0f, {0.0f, 1.0f, 0.2f}, {1.0f, 0.5f, -0.5f});
    l2.resolution = glm::uvec3(16, 8, 4);
    out.push_back({"l2_center_rotated_half", {l2}});

    // Overlapping: a large half volume under a rotated L1 volume of higher priority with a
    // fade, a small hard-bordered float volume in between, and an equal-priority pair (set
    // order breaks the tie).
    VolumeSpec big = dense;
    big.storage = Storage::Float16;
    big.fade = 0.3f;
    big.name = "big";
    VolumeSpec tilted = l1;
    tilted.bounds = {glm::vec3(-1.0f, 0.2f, -1.0f), glm::vec3(1.0f, 1.6f, 1.2f)};
    tilted.storage = Storage::Float32;
    tilted.priority = 2;
    tilted.fade = 0.25f;
    tilted.name = "tilted";
    VolumeSpec small = dense;
    small.bounds = {glm::vec3(0.5f, 0.5f, 0.0f), glm::vec3(1.5f, 1.5f, 1.0f)};
    small.resolution = glm::uvec3(4, 4, 4);
    small.priority = 1;
    small.name = "small";
    VolumeSpec twin = small;
    twin.bounds = {glm::vec3(-1.5f, 0.4f, -0.5f), glm::vec3(0.8f, 1.2f, 0.6f)};
    twin.mode = grid::PositionMode::Corner;
    twin.fade = 0.2f;
    twin.name = "twin";
    out.push_back({"overlapping_fade", {big, tilted, small, twin}});
    out.push_back({"overlapping_normal_offset", {big, tilted, small, twin}, 0.15f});
    return out;
}

std::vector<Volume> buildVolumes(const std::vector<VolumeSpec>& specs) {
    const ProbeFunction fields[] = {kFieldA, kFieldB, kFieldC};
    std::vector<Volume> volumes;
    for (size_t i = 0; i < specs.size(); ++i) {
        volumes.push_back(makeTestVolume(specs[i], fields[i % 3]));
    }
    return volumes;
}

float relativeFor(const std::vector<Volume>& volumes) {
    const bool any_half = std::any_of(volumes.begin(), volumes.end(), [](const Volume& v) {
        return v.desc.storage == Storage::Float16;
    });
    return any_half ? kHalfRelative : kFloatRelative;
}

// compareWithCpu over the set of `volumes` at relativeFor's tolerance, no normal offset: the
// largest |GPU - CPU| / scale it found.
float caseError(runtime::GpuContext& context, GpuVolumeSet& gpu, const std::vector<Volume>& volumes,
                const std::vector<Sample>& samples, const std::string& name) {
    return compareWithCpu(context, gpu, VolumeSet(volumes), samples, relativeFor(volumes), 0.0f,
                          name)
        .maxRelative;
}

class GpuSampler : public GpuTest {};

TEST_F(GpuSampler, TrilinearWeightPrecision) {
    const WeightPrecision& measured = weightPrecision(context());
    const double limit = std::ldexp(1.0, -int(context().limits().subTexelPrecisionBits));
    std::printf("[ figures  ] %s: trilinear weight error %.3g (%zu distinct weights over 4096 "
                "fractions; 8-bit weights would give 257); subTexelPrecisionBits %u\n",
                context().deviceInfo().name.c_str(), measured.maxError, measured.distinctWeights,
                context().limits().subTexelPrecisionBits);
    RecordProperty("weight_error", std::to_string(measured.maxError));
    // Vulkan promises subTexelPrecisionBits of weight precision: rounding is within one step.
    EXPECT_LE(measured.maxError, limit);
}

TEST_F(GpuSampler, MatchesCpuSampler) {
    uint32_t seed = 1;
    for (const Case& c : cases()) {
        SCOPED_TRACE(c.name);
        const std::vector<Volume> volumes = buildVolumes(c.specs);
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
        ASSERT_TRUE(gpu.ok()) << gpu.error().message;
        gpu.value().setNormalOffset(c.normalOffset);
        const VolumeSet cpu(volumes);
        const std::vector<Sample> samples = samplePoints(volumes, kPointsPerCase, seed++);
        compareWithCpu(context(), gpu.value(), cpu, samples, relativeFor(volumes), c.normalOffset,
                       c.name);
    }
}

TEST_F(GpuSampler, NormalOffsetMovesTheSamplePoint) {
    // A field that changes along y: with the offset, a receiver facing +y sees the irradiance
    // of the point above it.
    const std::vector<Volume> volumes = buildVolumes({cases()[0].specs});
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    Result<GpuPointSampler> sampler = GpuPointSampler::create(context());
    ASSERT_TRUE(sampler.ok());
    const std::vector<glm::vec3> p{{0.1f, 0.7f, 0.2f}};
    const std::vector<glm::vec3> n{{0.0f, 1.0f, 0.0f}};
    gpu.value().setNormalOffset(0.3f);
    Result<std::vector<glm::vec3>> offset = sampler.value().irradiance(gpu.value(), p, n);
    gpu.value().setNormalOffset(0.0f);
    const std::vector<glm::vec3> above{{0.1f, 1.0f, 0.2f}};
    Result<std::vector<glm::vec3>> moved = sampler.value().irradiance(gpu.value(), above, n);
    ASSERT_TRUE(offset.ok() && moved.ok());
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(offset.value()[0][c], moved.value()[0][c], 1e-5f * moved.value()[0][c]);
    }
}

// The CPU twin of a box update: `base` with the texels and validity of `box` taken from
// `source`.
Volume withBox(const Volume& base, const Volume& source, glm::uvec3 first, glm::uvec3 count) {
    Volume out = base;
    const grid::GridLayout& layout = base.desc.grid;
    for (uint32_t z = first.z; z < first.z + count.z; ++z) {
        for (uint32_t y = first.y; y < first.y + count.y; ++y) {
            for (uint32_t x = first.x; x < first.x + count.x; ++x) {
                const size_t probe = layout.linearIndex({x, y, z});
                out.validity[probe] = source.validity[probe];
                for (uint32_t p = 0; p < base.planes(); ++p) {
                    const size_t at = 4 * (p * base.probeCount() + probe);
                    for (size_t k = 0; k < 4; ++k) {
                        if (base.desc.storage == Storage::Float32) {
                            out.texelsF32[at + k] = source.texelsF32[at + k];
                        } else {
                            out.texelsF16[at + k] = source.texelsF16[at + k];
                        }
                    }
                }
            }
        }
    }
    return out;
}

TEST_F(GpuSampler, SubBoxUpdateChangesExactlyTheBox) {
    for (Storage storage : {Storage::Float32, Storage::Float16}) {
        SCOPED_TRACE(std::string(toString(storage)));
        // Spacing 1 with probes on exact binary fractions: a probe position is exactly its
        // texel centre, so sampling there reads that texel alone.
        VolumeSpec spec;
        spec.bounds = {glm::vec3(0.0f), glm::vec3(8.0f, 4.0f, 8.0f)};
        spec.resolution = glm::uvec3(8, 4, 8);
        spec.storage = storage;
        const Volume before = makeTestVolume(spec, kFieldA);
        const Volume source = makeTestVolume(spec, kFieldB, 3);
        const glm::uvec3 first(2, 1, 3);
        const glm::uvec3 count(3, 2, 4);
        const std::vector<Volume> initial{before};
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), initial);
        ASSERT_TRUE(gpu.ok()) << gpu.error().message;
        const size_t uploaded = gpu.value().uploadedBytes();
        ASSERT_TRUE(gpu.value().updateBox(0, source, first, count).ok());
        // Only the box's texels went up.
        EXPECT_EQ(gpu.value().uploadedBytes() - uploaded, size_t(count.x) * count.y * count.z *
                                                              before.planes() * 4 *
                                                              bytesPerComponent(storage));

        const Volume expected = withBox(before, source, first, count);
        EXPECT_EQ(gpu.value().validity(0), expected.validity);
        const VolumeSet cpu_expected({expected});
        const VolumeSet cpu_before({before});
        const VolumeSet cpu_source({source});
        // Every probe, seen with several normals (together they pin every coefficient).
        std::vector<Sample> probes;
        const grid::GridLayout& layout = before.desc.grid;
        const glm::vec3 normals[] = {{0, 1, 0}, {1, 0, 0}, {0, 0, 1}, {0.6f, -0.48f, 0.64f}};
        for (size_t i = 0; i < layout.probeCount(); ++i) {
            for (const glm::vec3& n : normals) {
                probes.push_back({layout.probeWorld(layout.probeCoords(i)), n});
            }
        }
        compareWithCpu(context(), gpu.value(), cpu_expected, probes, kFloatRelative, 0.0f,
                       std::string("sub_box_probes_") + std::string(toString(storage)));
        // And every probe inside the box now differs from the old data, every probe outside
        // from the new (the two fields differ everywhere by far more than the tolerance).
        for (size_t i = 0; i < layout.probeCount(); ++i) {
            const glm::uvec3 c = layout.probeCoords(i);
            const bool inside = glm::all(glm::greaterThanEqual(c, first)) &&
                                glm::all(glm::lessThan(c, first + count));
            const glm::vec3 p = layout.probeWorld(c);
            const glm::vec3 other = (inside ? cpu_before : cpu_source).irradiance(p, normals[3]);
            const glm::vec3 now = cpu_expected.irradiance(p, normals[3]);
            EXPECT_GT(glm::length(now - other), 1e-2f * glm::length(now)) << "probe " << i;
        }
        // Interpolation across the box edges matches too.
        compareWithCpu(context(), gpu.value(), cpu_expected, samplePoints({expected}, 4000, 7),
                       kFloatRelative, 0.0f,
                       std::string("sub_box_interpolated_") + std::string(toString(storage)));
    }
}

TEST_F(GpuSampler, ReplaceVolumeUploadsNewData) {
    const std::vector<Volume> volumes = buildVolumes(cases()[5].specs);
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    // New data, new fade and priority (the blending order changes).
    std::vector<Volume> changed = volumes;
    VolumeSpec spec = cases()[5].specs[2];
    spec.priority = 5;
    spec.fade = 0.1f;
    changed[2] = makeTestVolume(spec, kFieldA);
    ASSERT_TRUE(gpu.value().replaceVolume(2, changed[2]).ok());
    compareWithCpu(context(), gpu.value(), VolumeSet(changed), samplePoints(changed, 4000, 11),
                   kHalfRelative, 0.0f, "replace_volume");
}

TEST_F(GpuSampler, MoveWithoutReupload) {
    std::vector<Volume> volumes = buildVolumes(cases()[5].specs);
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    const size_t uploaded = gpu.value().uploadedBytes();
    const grid::RigidFrame moved = rotated(20.0f, {0.3f, 1.0f, -0.2f}, {0.4f, 0.1f, -0.3f});
    ASSERT_TRUE(gpu.value().setFrame(1, moved).ok());
    volumes[1].desc.grid.setFrame(moved);
    compareWithCpu(context(), gpu.value(), VolumeSet(volumes), samplePoints(volumes, 6000, 5),
                   kHalfRelative, 0.0f, "moved");
    EXPECT_EQ(gpu.value().uploadedBytes(), uploaded) << "moving a volume re-uploaded texels";
    EXPECT_EQ(gpu.value().desc(1).grid.frame().translation, moved.translation);
}

TEST_F(GpuSampler, SecondStateBlendOnTheGpu) {
    for (Storage storage : {Storage::Float32, Storage::Float16}) {
        SCOPED_TRACE(std::string(toString(storage)));
        VolumeSpec spec = cases()[2].specs[0]; // L1, corner, rotated
        spec.storage = storage;
        VolumeSpec other = cases()[5].specs[2];
        other.storage = storage;
        const Volume state_a = makeTestVolume(spec, kFieldA);
        const Volume state_b = makeTestVolume(spec, kFieldC);
        const Volume neighbour = makeTestVolume(other, kFieldB);
        const std::vector<Volume> initial{state_a, neighbour};
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), initial);
        ASSERT_TRUE(gpu.ok()) << gpu.error().message;
        ASSERT_TRUE(gpu.value().replaceVolume(0, state_b, runtime::VolumeState::Secondary).ok());
        const size_t uploaded = gpu.value().uploadedBytes();
        const VolumeSet cpu_a(initial);
        const VolumeSet cpu_b(std::vector<Volume>{state_b, neighbour});
        const std::vector<Sample> samples = samplePoints(initial, 6000, 3);
        ASSERT_NO_FATAL_FAILURE(expectStateBlendIsLerp(
            context(), gpu.value(), cpu_a, cpu_b, samples, {0.0f, 0.5f, 1.0f, 0.25f},
            storage == Storage::Float16 ? kHalfRelative : kFloatRelative,
            "blend " + std::string(toString(storage))));
        EXPECT_EQ(gpu.value().uploadedBytes(), uploaded) << "changing the blend re-uploaded";
    }
}

TEST_F(GpuSampler, RejectsBadInput) {
    const std::vector<Volume> volumes = buildVolumes({cases()[0].specs});
    EXPECT_EQ(GpuVolumeSet::create(context(), {}).error().code, ErrorCode::OutOfRange);
    const std::vector<Volume> too_many(runtime::kMaxGpuVolumes + 1, volumes[0]);
    EXPECT_EQ(GpuVolumeSet::create(context(), too_many).error().code, ErrorCode::OutOfRange);

    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok());
    VolumeSpec spec = cases()[0].specs[0];
    spec.resolution = glm::uvec3(4, 4, 4);
    const Result<void> mismatch = gpu.value().replaceVolume(0, makeTestVolume(spec, kFieldA));
    ASSERT_FALSE(mismatch.ok());
    EXPECT_NE(mismatch.error().message.find("resolution"), std::string::npos)
        << mismatch.error().message;
    spec = cases()[0].specs[0];
    spec.storage = Storage::Float16;
    EXPECT_FALSE(gpu.value().replaceVolume(0, makeTestVolume(spec, kFieldA)).ok());

    const Result<void> outside =
        gpu.value().updateBox(0, volumes[0], glm::uvec3(6, 0, 0), glm::uvec3(3, 1, 1));
    ASSERT_FALSE(outside.ok());
    EXPECT_EQ(outside.error().code, ErrorCode::OutOfRange);
    EXPECT_FALSE(
        gpu.value().updateBox(0, volumes[0], glm::uvec3(0, 0, 0), glm::uvec3(0, 1, 1)).ok());
    EXPECT_FALSE(
        gpu.value()
            .updateBox(0, volumes[0], glm::uvec3(0), glm::uvec3(1), runtime::VolumeState::Secondary)
            .ok());
    grid::RigidFrame bad;
    bad.rotation = glm::quat(2.0f, 0.0f, 0.0f, 0.0f);
    EXPECT_FALSE(gpu.value().setFrame(0, bad).ok());
    // A failed call changes nothing.
    compareWithCpu(context(), gpu.value(), VolumeSet(volumes), samplePoints(volumes, 2000, 9),
                   kFloatRelative, 0.0f, "after_rejections");
}

// The index and state checks of the update calls and the point sampler's sizes hold in every
// build type (gpu_volumes.hpp, point_sampler.hpp, ARCHITECTURE.md "Preconditions"): errors that
// name the call and the argument, and nothing changes.
TEST_F(GpuSampler, RejectsBadIndicesBlendsAndSizes) {
    const std::vector<Volume> volumes = buildVolumes({cases()[0].specs});
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok());
    GpuVolumeSet& set = gpu.value();
    const size_t past = set.size();
    const std::string outside = " is outside the set of " + std::to_string(past) + " volumes";
    const auto expectOutOfRange = [&](const Result<void>& r, const std::string& call) {
        ASSERT_FALSE(r.ok()) << call;
        EXPECT_EQ(r.error().code, ErrorCode::OutOfRange);
        EXPECT_EQ(r.error().message,
                  "GpuVolumeSet::" + call + ": volume index " + std::to_string(past) + outside);
    };
    expectOutOfRange(set.replaceVolume(past, volumes[0]), "replaceVolume");
    expectOutOfRange(set.updateBox(past, volumes[0], glm::uvec3(0), glm::uvec3(1)), "updateBox");
    expectOutOfRange(set.setFrame(past, grid::RigidFrame{}), "setFrame");
    expectOutOfRange(set.setStateBlend(past, 0.0f), "setStateBlend");

    // Blending towards a second state that was never uploaded; 0 (and what clamps to 0) is fine.
    const Result<void> blend = set.setStateBlend(0, 0.5f);
    ASSERT_FALSE(blend.ok());
    EXPECT_EQ(blend.error().code, ErrorCode::InvalidArgument);
    EXPECT_NE(blend.error().message.find("has no second state"), std::string::npos)
        << blend.error().message;
    EXPECT_EQ(set.stateBlend(0), 0.0f);
    EXPECT_TRUE(set.setStateBlend(0, 0.0f).ok());
    EXPECT_TRUE(set.setStateBlend(0, -1.0f).ok());

    Result<GpuPointSampler> sampler = GpuPointSampler::create(context());
    ASSERT_TRUE(sampler.ok());
    const std::vector<glm::vec3> positions(3, glm::vec3(0.5f));
    const std::vector<glm::vec3> normals(2, glm::vec3(0.0f, 1.0f, 0.0f));
    const Result<std::vector<glm::vec3>> mismatch =
        sampler.value().irradiance(set, positions, normals);
    ASSERT_FALSE(mismatch.ok());
    EXPECT_EQ(mismatch.error().code, ErrorCode::InvalidArgument);
    EXPECT_EQ(mismatch.error().message, "GpuPointSampler::irradiance: 3 positions but 2 normals "
                                        "(one normal per position)");
    compareWithCpu(context(), set, VolumeSet(volumes), samplePoints(volumes, 2000, 9),
                   kFloatRelative, 0.0f, "after_index_rejections");
}

// The accessors cannot return an error: an index past the set aborts, naming the condition.
TEST_F(GpuSampler, AccessorsCheckTheIndex) {
    const std::vector<Volume> volumes = buildVolumes({cases()[0].specs});
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), volumes);
    ASSERT_TRUE(gpu.ok());
    const GpuVolumeSet& set = gpu.value();
    const size_t past = set.size();
    EXPECT_DEATH((void)set.desc(past), "precondition failed in desc: index < size");
    EXPECT_DEATH((void)set.validity(past), "precondition failed in validity: index < size");
    EXPECT_DEATH((void)set.hasVisibility(past),
                 "precondition failed in hasVisibility: index < size");
    EXPECT_DEATH((void)set.hasSecondState(past),
                 "precondition failed in hasSecondState: index < size");
    EXPECT_DEATH((void)set.stateBlend(past), "precondition failed in stateBlend: index < size");
}

} // namespace

// ---- Bricked volumes: indirection + brick atlas against the CPU sampler's steps B1-B4 ----

namespace {

// Tolerances: the dense ones (kFloatRelative, kHalfRelative), for the same reasons: both sides
// filter the same stored texels, in float on lavapipe. The atlas adds the rounding of a
// normalised coordinate over 4 A texels (A <= 8 slots per axis here: <= 2e-6 texel) and, on a
// brick or level border, the two sides may pick different bricks for one point; the volumes are
// stitched (brick::stitchBorders) before storage, so the bricks agree there to within float
// rounding. Half storage rounds the stitched border probes and the coarse probes they were
// interpolated from separately: the two bricks then differ by up to 2^-11 of the *coefficients*,
// which where irradiance cancels (E ~ 0.1 from coefficients ~ 1) exceeds 2e-3 of E (measured
// 3.2e-3). So border points are tested where both sides pick the same brick: on half volumes
// only with an identity frame (points snapped exactly onto a face in local coordinates).
struct BrickedCase {
    std::string name;
    std::vector<Volume> volumes;
    bool borderPoints = true;
};

struct BrickedSpec {
    grid::Aabb bounds{glm::vec3(-2.0f, 0.0f, -2.0f), glm::vec3(2.0f, 2.0f, 2.0f)};
    glm::uvec3 top{2, 1, 2};
    brick::BrickLayout layout = bricktest::mixedLayout(glm::uvec3(2, 1, 2));
    grid::RigidFrame frame{};
    sh::Order order = sh::Order::L2;
    Storage storage = Storage::Float32;
    int32_t priority = 0;
    float fade = 0.0f;
};

Volume makeBricked(const BrickedSpec& spec, const ProbeFunction& field) {
    VolumeDesc desc;
    desc.name = "bricked";
    desc.grid = grid::GridLayout(spec.bounds, spec.top, grid::PositionMode::Center, spec.frame);
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = spec.layout;
    desc.shOrder = spec.order;
    desc.storage = spec.storage;
    desc.blendPriority = spec.priority;
    desc.fadeDistance = spec.fade;
    return bricktest::makeBrickedVolume(desc, field, true);
}

// Points exactly on finest-cell faces of the bricked volumes (so on every brick and level
// border, and on faces inside bricks), and on their edges and corners, with random normals.
std::vector<Sample> brickBorderPoints(const std::vector<Volume>& volumes, size_t count,
                                      uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Sample> samples;
    for (const Volume& v : volumes) {
        if (v.desc.layout != VolumeLayout::Bricked) {
            continue;
        }
        const glm::uvec3 cells =
            brick::finestCells(v.desc.grid.resolution(), v.desc.bricks.maxLevel);
        const grid::Aabb& box = v.desc.grid.bounds();
        for (size_t i = 0; i < count; ++i) {
            glm::vec3 t(unit(rng), unit(rng), unit(rng));
            // One, two or three axes snapped to a cell face: faces, edges, corners.
            for (int axis = 0; axis < 1 + int(i % 3); ++axis) {
                const int a = (axis + int(i / 3)) % 3;
                t[a] = std::round(t[a] * float(cells[a])) / float(cells[a]);
            }
            samples.push_back(
                {v.desc.grid.frame().toWorld(box.min + t * box.size()), randomUnit(rng)});
        }
    }
    return samples;
}

std::vector<BrickedCase> brickedCases() {
    std::vector<BrickedCase> out;
    BrickedSpec uniform;
    uniform.top = glm::uvec3(4, 2, 4);
    uniform.layout = brick::uniformLayout(uniform.top, 1);
    out.push_back({"bricked_uniform_l2_float", {makeBricked(uniform, kFieldA)}});

    BrickedSpec mixed;
    out.push_back({"bricked_mixed_l2_float", {makeBricked(mixed, kFieldA)}});
    mixed.storage = Storage::Float16;
    out.push_back({"bricked_mixed_l2_half", {makeBricked(mixed, kFieldB)}});

    BrickedSpec nested;
    nested.layout = bricktest::nestedLayout(nested.top);
    out.push_back({"bricked_nested_l2_float", {makeBricked(nested, kFieldA)}});

    BrickedSpec rotated_l1 = mixed;
    rotated_l1.order = sh::Order::L1;
    rotated_l1.storage = Storage::Float32;
    rotated_l1.frame = rotated(35.0f, {1.0f, 2.0f, 0.5f}, {0.3f, -0.2f, 0.1f});
    out.push_back({"bricked_mixed_l1_rotated_float", {makeBricked(rotated_l1, kFieldC)}});
    rotated_l1.storage = Storage::Float16;
    out.push_back({"bricked_mixed_l1_rotated_half", {makeBricked(rotated_l1, kFieldC)}, false});

    // A bricked volume with a fade over a dense one of lower priority, under a small dense one
    // of higher priority.
    VolumeSpec dense = cases()[0].specs[0];
    dense.bounds = {glm::vec3(-3.0f, -0.5f, -3.0f), glm::vec3(3.0f, 2.5f, 3.0f)};
    VolumeSpec small = cases()[5].specs[2];
    small.priority = 3;
    BrickedSpec over = mixed;
    over.priority = 1;
    over.fade = 0.3f;
    over.frame = rotated(-20.0f, {0.0f, 1.0f, 0.2f}, {0.2f, 0.1f, -0.1f});
    out.push_back({"bricked_over_dense",
                   {makeTestVolume(dense, kFieldB), makeBricked(over, kFieldA),
                    makeTestVolume(small, kFieldC)}});
    return out;
}

TEST_F(GpuSampler, BrickedMatchesCpuSampler) {
    float worst = 0.0f;
    for (const BrickedCase& c : brickedCases()) {
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), c.volumes);
        ASSERT_TRUE(gpu.ok()) << c.name << ": " << gpu.error().message;
        std::vector<Sample> samples = samplePoints(c.volumes, kPointsPerCase, 41);
        if (c.borderPoints) {
            const std::vector<Sample> borders =
                brickBorderPoints(c.volumes, kPointsPerCase / 2, 43);
            samples.insert(samples.end(), borders.begin(), borders.end());
        }
        worst = std::max(worst, caseError(context(), gpu.value(), c.volumes, samples, c.name));
    }
    std::printf("[ figures  ] bricked: worst max |GPU - CPU| / scale over all cases = %.3g\n",
                double(worst));
}

TEST_F(GpuSampler, BrickedReplaceAndSecondState) {
    // Dense -> bricked -> a bricked layout of another size: each replacement reallocates.
    const std::vector<Volume> initial = buildVolumes(cases()[0].specs);
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), initial);
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    BrickedSpec mixed;
    const Volume first = makeBricked(mixed, kFieldA);
    ASSERT_TRUE(gpu.value().replaceVolume(0, first).ok());
    compareWithCpu(context(), gpu.value(), VolumeSet({first}), samplePoints({first}, 3000, 13),
                   kFloatRelative, 0.0f, "bricked_replaced_dense");
    BrickedSpec bigger;
    bigger.top = glm::uvec3(4, 2, 4);
    bigger.layout = bricktest::mixedLayout(bigger.top);
    const Volume second = makeBricked(bigger, kFieldB);
    ASSERT_TRUE(gpu.value().replaceVolume(0, second).ok());
    compareWithCpu(context(), gpu.value(), VolumeSet({second}), samplePoints({second}, 3000, 17),
                   kFloatRelative, 0.0f, "bricked_replaced_bricked");

    // A second state with the same layout blends on the GPU; at factor 1 it is state b.
    const Volume state_b = makeBricked(bigger, kFieldC);
    ASSERT_TRUE(gpu.value().replaceVolume(0, state_b, runtime::VolumeState::Secondary).ok());
    ASSERT_TRUE(gpu.value().setStateBlend(0, 1.0f).ok());
    compareWithCpu(context(), gpu.value(), VolumeSet({state_b}), samplePoints({state_b}, 3000, 19),
                   kFloatRelative, 0.0f, "bricked_second_state");

    // With a second state the layout stays; a box update means nothing in an atlas.
    const Result<void> relayout = gpu.value().replaceVolume(0, first);
    ASSERT_FALSE(relayout.ok());
    EXPECT_NE(relayout.error().message.find("second state"), std::string::npos)
        << relayout.error().message;
    const Result<void> box = gpu.value().updateBox(0, state_b, glm::uvec3(0), glm::uvec3(1));
    ASSERT_FALSE(box.ok());
    EXPECT_EQ(box.error().code, ErrorCode::InvalidArgument);
    EXPECT_NE(box.error().message.find("dense volumes only"), std::string::npos);
}

} // namespace

// ---- Visibility (leak-proof interpolation): pk_visible_texels against the CPU's step V ----

namespace {

// Tolerances: the dense and bricked ones above (kFloatRelative, kHalfRelative), point by point.
// Both sides weight the same decoded texels with the same formula in float (visibility.hpp),
// the GPU with texelFetch, so no filter weights are involved; the visibility ramp is 1/32 of a
// cell wide, so a ~1e-6 cell difference in the sample point (rotation matrix against
// quaternion) moves a tap's weight by ~3e-5 of it, and normalising by a small weight sum (every
// tap hidden but one, partly) can enlarge that: the measured maxima are printed.

Volume withVisibility(Volume volume, uint32_t seed) {
    addVisibility(volume, seed);
    return volume;
}

Volume withoutVisibility(Volume volume) {
    volume.visibility.clear();
    return volume;
}

// World positions of a volume's probes (dense grid or brick lattice).
std::vector<glm::vec3> probePositions(const Volume& v) {
    std::vector<glm::vec3> out;
    if (v.desc.layout == VolumeLayout::Bricked) {
        for (const brick::Brick& b : v.desc.bricks.bricks) {
            for (uint32_t k = 0; k < brick::kBrickProbeCount; ++k) {
                out.push_back(v.desc.grid.frame().toWorld(bricktest::probeLocal(v.desc, b, k)));
            }
        }
    } else {
        for (size_t i = 0; i < v.probeCount(); ++i) {
            out.push_back(v.desc.grid.probeWorld(v.desc.grid.probeCoords(i)));
        }
    }
    return out;
}

// Points in the cells around hidden probes (those with a zero byte): up to half a cell of the
// finest spacing from the probe, so inside the visibility ramps and beyond, and with
// `exact_points` some exactly at the probe or on the cell faces through it.
std::vector<Sample> nearHiddenProbes(const std::vector<Volume>& volumes, size_t count,
                                     uint32_t seed, bool exact_points = true) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> offset(-0.5f, 0.5f);
    std::vector<Sample> samples;
    for (const Volume& v : volumes) {
        if (!v.hasVisibility()) {
            continue;
        }
        const std::vector<glm::vec3> positions = probePositions(v);
        std::vector<size_t> hidden;
        for (size_t i = 0; i < v.probeCount(); ++i) {
            const uint8_t* q = &v.visibility[i * visibility::kBytesPerProbe];
            if (std::find(q, q + visibility::kBytesPerProbe, uint8_t(0)) !=
                q + visibility::kBytesPerProbe) {
                hidden.push_back(i);
            }
        }
        const glm::vec3 spacing =
            v.desc.layout == VolumeLayout::Bricked
                ? v.desc.grid.bounds().size() /
                      (3.0f * glm::vec3(brick::finestCells(v.desc.grid.resolution(),
                                                           v.desc.bricks.maxLevel)))
                : v.desc.grid.spacing();
        std::uniform_int_distribution<size_t> pick(0, hidden.size() - 1);
        for (size_t i = 0; i < count && !hidden.empty(); ++i) {
            const glm::vec3 local = v.desc.grid.frame().toLocal(positions[hidden[pick(rng)]]);
            const glm::vec3 d(offset(rng), offset(rng), offset(rng));
            // A few exactly at the probe and on the cell faces through it.
            glm::vec3 step = d * spacing;
            if (exact_points && i % 7 == 0) {
                step = glm::vec3(0.0f);
            } else if (exact_points && i % 7 == 1) {
                step[int(i / 7) % 3] = 0.0f;
            }
            samples.push_back({v.desc.grid.frame().toWorld(local + step), randomUnit(rng)});
        }
    }
    return samples;
}

// Bricked volumes with these random bytes are discontinuous across brick faces (a border probe
// and the coincident probe of the neighbouring brick hold different bytes; baked ones differ
// too where the two bricks' spacings do, since distances are in each probe's own cells). Where
// GPU and CPU may put a point on a face into different bricks, in rotated frames where the face
// is only within rounding of the point, the two answers differ by that jump, both right: so,
// as for the half-volume border points above, points on faces (brick borders, and the exact
// points of nearHiddenProbes) are sampled in identity frames only.
struct VisibilityCase {
    std::string name;
    std::vector<Volume> volumes;
    bool facePoints = true; // points exactly on (brick) cell faces
};

std::vector<VisibilityCase> visibilityCases() {
    std::vector<VisibilityCase> out;
    const std::vector<Case> dense = cases();
    // Dense: L2 centre float and half, L1 corner rotated float and half.
    for (size_t c : {size_t(0), size_t(1), size_t(2), size_t(3), size_t(4)}) {
        out.push_back({dense[c].name + "_visibility",
                       {withVisibility(buildVolumes(dense[c].specs)[0], uint32_t(100 + c))}});
    }
    // Bricked: mixed levels float and half, nested, L1 rotated float and half.
    const std::vector<BrickedCase> bricked = brickedCases();
    for (size_t c : {size_t(1), size_t(2), size_t(3), size_t(4), size_t(5)}) {
        const bool rotated = c >= 4;
        out.push_back({bricked[c].name + "_visibility",
                       {withVisibility(bricked[c].volumes[0], uint32_t(200 + c))},
                       !rotated});
    }
    // A set mixing volumes with and without visibility: the overlapping case with visibility
    // on the big and the tilted volume, and the bricked-over-dense case on the bricked one.
    std::vector<Volume> overlapping = buildVolumes(dense[5].specs);
    addVisibility(overlapping[0], 301);
    addVisibility(overlapping[1], 302);
    out.push_back({"overlapping_fade_mixed_visibility", overlapping});
    std::vector<Volume> over = bricked[6].volumes; // the bricked volume is rotated
    addVisibility(over[1], 303);
    out.push_back({"bricked_over_dense_mixed_visibility", over, false});
    return out;
}

// How far visibility moves the CPU result at the samples (the test must not pass vacuously):
// the share of points changed by more than 5% of the scale, and the largest change.
struct VisibilityEffect {
    double changedShare = 0.0;
    float maxChange = 0.0f;
};

VisibilityEffect visibilityEffect(const std::vector<Volume>& volumes,
                                  const std::vector<Sample>& samples) {
    std::vector<Volume> plain;
    for (const Volume& v : volumes) {
        plain.push_back(withoutVisibility(v));
    }
    const VolumeSet with(volumes);
    const VolumeSet without(plain);
    std::vector<float> magnitudes;
    std::vector<float> changes;
    for (const Sample& s : samples) {
        const glm::vec3 a = with.irradiance(s.position, s.normal);
        const glm::vec3 b = without.irradiance(s.position, s.normal);
        const glm::vec3 m = glm::abs(a);
        magnitudes.push_back(std::max(m.x, std::max(m.y, m.z)));
        const glm::vec3 d = glm::abs(a - b);
        changes.push_back(std::max(d.x, std::max(d.y, d.z)));
    }
    std::vector<float> sorted = magnitudes;
    std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
    const float floor = kScaleFloor * sorted[sorted.size() / 2];
    VisibilityEffect out;
    size_t changed = 0;
    for (size_t i = 0; i < samples.size(); ++i) {
        const float relative = changes[i] / std::max(magnitudes[i], floor);
        out.maxChange = std::max(out.maxChange, relative);
        changed += relative > 0.05f ? 1 : 0;
    }
    out.changedShare = double(changed) / double(samples.size());
    return out;
}

std::vector<Sample> visibilitySamples(const VisibilityCase& c, uint32_t seed) {
    std::vector<Sample> samples = samplePoints(c.volumes, kPointsPerCase, seed);
    const std::vector<Sample> near =
        nearHiddenProbes(c.volumes, kPointsPerCase / 2, seed + 1, c.facePoints);
    samples.insert(samples.end(), near.begin(), near.end());
    if (c.facePoints) {
        const std::vector<Sample> borders = brickBorderPoints(c.volumes, kPointsPerCase / 4, 43);
        samples.insert(samples.end(), borders.begin(), borders.end());
    }
    return samples;
}

TEST_F(GpuSampler, VisibilityMatchesCpuSampler) {
    uint32_t seed = 500;
    float worst = 0.0f;
    for (const VisibilityCase& c : visibilityCases()) {
        SCOPED_TRACE(c.name);
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), c.volumes);
        ASSERT_TRUE(gpu.ok()) << gpu.error().message;
        const std::vector<Sample> samples = visibilitySamples(c, seed);
        seed += 7;
        const VisibilityEffect effect = visibilityEffect(c.volumes, samples);
        std::printf("[ figures  ] %s: visibility changes %.1f%% of the points by > 5%% (max "
                    "%.3g of the scale)\n",
                    c.name.c_str(), 100.0 * effect.changedShare, double(effect.maxChange));
        // Not vacuous: the weights really differ from trilinear interpolation (measured 4.9%
        // of the points for the mixed set, where the volume with visibility covers a part,
        // 12.8% and more for the others).
        EXPECT_GT(effect.changedShare, 0.03) << c.name;
        EXPECT_GT(effect.maxChange, 0.3f) << c.name;
        worst = std::max(worst, caseError(context(), gpu.value(), c.volumes, samples, c.name));
    }
    std::printf("[ figures  ] visibility: worst max |GPU - CPU| / scale over all cases = %.3g\n",
                double(worst));
}

TEST_F(GpuSampler, VisibilitySecondStateBlend) {
    // Both states take the primary's visibility; the second state's own bytes are ignored.
    for (bool bricked : {false, true}) {
        for (Storage storage : {Storage::Float32, Storage::Float16}) {
            const std::string name =
                std::string(bricked ? "bricked" : "dense") + "_" + std::string(toString(storage));
            SCOPED_TRACE(name);
            Volume state_a;
            Volume state_b;
            if (bricked) {
                BrickedSpec spec;
                spec.storage = storage;
                state_a = makeBricked(spec, kFieldA);
                state_b = makeBricked(spec, kFieldC);
            } else {
                VolumeSpec spec = cases()[2].specs[0]; // L1, corner, rotated
                spec.storage = storage;
                state_a = makeTestVolume(spec, kFieldA);
                state_b = makeTestVolume(spec, kFieldC);
            }
            addVisibility(state_a, 41);
            addVisibility(state_b, 42); // different bytes: must not be used
            const std::vector<Volume> initial{state_a};
            Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), initial);
            ASSERT_TRUE(gpu.ok()) << gpu.error().message;
            ASSERT_TRUE(
                gpu.value().replaceVolume(0, state_b, runtime::VolumeState::Secondary).ok());
            EXPECT_TRUE(gpu.value().hasVisibility(0));
            Volume b_weighted_by_a = state_b;
            b_weighted_by_a.visibility = state_a.visibility;
            const VolumeSet cpu_a(initial);
            const VolumeSet cpu_b(std::vector<Volume>{b_weighted_by_a});
            std::vector<Sample> samples = samplePoints(initial, 4000, 61);
            const std::vector<Sample> near = nearHiddenProbes(initial, 2000, 62);
            samples.insert(samples.end(), near.begin(), near.end());
            ASSERT_NO_FATAL_FAILURE(expectStateBlendIsLerp(
                context(), gpu.value(), cpu_a, cpu_b, samples, {0.0f, 0.3f, 1.0f},
                storage == Storage::Float16 ? kHalfRelative : kFloatRelative,
                "visibility blend " + name));
        }
    }
}

TEST_F(GpuSampler, ReplaceVolumeSwitchesVisibility) {
    for (bool bricked : {false, true}) {
        SCOPED_TRACE(bricked ? "bricked" : "dense");
        const Volume plain =
            bricked ? makeBricked(BrickedSpec{}, kFieldA) : buildVolumes(cases()[0].specs)[0];
        const Volume visible = withVisibility(plain, 71);
        const Volume other = withVisibility(bricked ? makeBricked(BrickedSpec{}, kFieldB)
                                                    : buildVolumes({cases()[0].specs})[0],
                                            72);
        const std::vector<Volume> initial{plain};
        Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), initial);
        ASSERT_TRUE(gpu.ok()) << gpu.error().message;
        const size_t plain_bytes = gpu.value().texelBytes();
        EXPECT_FALSE(gpu.value().anyVisibility());
        const auto check = [&](const Volume& expected, const std::string& name) {
            std::vector<Sample> samples = samplePoints({expected}, 3000, 73);
            const std::vector<Sample> near = nearHiddenProbes({expected}, 1500, 74);
            samples.insert(samples.end(), near.begin(), near.end());
            compareWithCpu(context(), gpu.value(), VolumeSet({expected}), samples, kFloatRelative,
                           0.0f, name);
        };
        // Off -> on: the integer image grows by 8 bytes per probe (dense) or becomes the
        // indirection plus the visibility atlas in 8-byte texels (bricked).
        size_t uploaded = gpu.value().uploadedBytes();
        ASSERT_TRUE(gpu.value().replaceVolume(0, visible).ok());
        EXPECT_TRUE(gpu.value().hasVisibility(0) && gpu.value().anyVisibility());
        EXPECT_EQ(gpu.value().uploadedBytes() - uploaded,
                  visible.texelBytes() + visible.visibilityGpuBytes() +
                      visible.indirection.size() * (bricked ? 8 : 0));
        if (bricked) {
            const glm::uvec3 cells =
                brick::finestCells(visible.desc.grid.resolution(), visible.desc.bricks.maxLevel);
            const glm::uvec3 slots =
                runtime::brickAtlasSlots(visible.desc.bricks.bricks.size(),
                                         context().limits().maxImageDimension3D)
                    .value();
            const glm::uvec3 e = runtime::brickedIntegerExtent(cells, slots);
            EXPECT_EQ(gpu.value().texelBytes() - plain_bytes,
                      size_t(e.x) * e.y * e.z * 8 - visible.indirection.size() * 4);
        } else {
            EXPECT_EQ(gpu.value().texelBytes() - plain_bytes, visible.probeCount() * 8);
        }
        check(visible, std::string(bricked ? "bricked" : "dense") + "_visibility_on");
        // On -> on with other data, then off again.
        ASSERT_TRUE(gpu.value().replaceVolume(0, other).ok());
        check(other, std::string(bricked ? "bricked" : "dense") + "_visibility_replaced");
        ASSERT_TRUE(gpu.value().replaceVolume(0, plain).ok());
        EXPECT_FALSE(gpu.value().hasVisibility(0));
        EXPECT_EQ(gpu.value().texelBytes(), plain_bytes);
        check(plain, std::string(bricked ? "bricked" : "dense") + "_visibility_off");
    }
    // A dense slot with a second state switches too; the second state keeps its texels.
    const Volume a = buildVolumes(cases()[0].specs)[0];
    const VolumeSpec spec = cases()[0].specs[0];
    const Volume second = makeTestVolume(spec, kFieldC);
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), std::vector<Volume>{a});
    ASSERT_TRUE(gpu.ok());
    ASSERT_TRUE(gpu.value().replaceVolume(0, second, runtime::VolumeState::Secondary).ok());
    ASSERT_TRUE(gpu.value().setStateBlend(0, 1.0f).ok());
    const Volume visible_a = withVisibility(a, 75);
    ASSERT_TRUE(gpu.value().replaceVolume(0, visible_a).ok());
    Volume second_weighted = second;
    second_weighted.visibility = visible_a.visibility;
    compareWithCpu(context(), gpu.value(), VolumeSet({second_weighted}),
                   samplePoints({second_weighted}, 3000, 76), kFloatRelative, 0.0f,
                   "second_state_visibility_on");
}

TEST_F(GpuSampler, UpdateBoxCopiesVisibility) {
    VolumeSpec spec = cases()[0].specs[0];
    const Volume before = withVisibility(makeTestVolume(spec, kFieldA), 81);
    const Volume source = withVisibility(makeTestVolume(spec, kFieldB, 3), 82);
    const glm::uvec3 first(2, 1, 3);
    const glm::uvec3 count(3, 2, 4);
    Result<GpuVolumeSet> gpu = GpuVolumeSet::create(context(), std::vector<Volume>{before});
    ASSERT_TRUE(gpu.ok()) << gpu.error().message;
    const size_t uploaded = gpu.value().uploadedBytes();
    ASSERT_TRUE(gpu.value().updateBox(0, source, first, count).ok());
    const size_t box = size_t(count.x) * count.y * count.z;
    EXPECT_EQ(gpu.value().uploadedBytes() - uploaded, box * before.planes() * 16 + box * 8);
    // The CPU twin: texels, validity and visibility of the box from the source.
    Volume expected = withBox(before, source, first, count);
    const grid::GridLayout& layout = before.desc.grid;
    for (uint32_t z = first.z; z < first.z + count.z; ++z) {
        for (uint32_t y = first.y; y < first.y + count.y; ++y) {
            for (uint32_t x = first.x; x < first.x + count.x; ++x) {
                const size_t probe = layout.linearIndex({x, y, z});
                std::copy_n(&source.visibility[probe * visibility::kBytesPerProbe],
                            visibility::kBytesPerProbe,
                            &expected.visibility[probe * visibility::kBytesPerProbe]);
            }
        }
    }
    std::vector<Sample> samples = samplePoints({expected}, 4000, 83);
    const std::vector<Sample> near = nearHiddenProbes({expected}, 2000, 84);
    samples.insert(samples.end(), near.begin(), near.end());
    compareWithCpu(context(), gpu.value(), VolumeSet({expected}), samples, kFloatRelative, 0.0f,
                   "update_box_visibility");
    // Not vacuous: the box's visibility changes the result (against keeping the old bytes).
    Volume stale = expected;
    stale.visibility = before.visibility;
    const VolumeSet cpu_expected({expected});
    const VolumeSet cpu_stale({stale});
    size_t changed = 0;
    for (const Sample& s : samples) {
        const glm::vec3 e = cpu_expected.irradiance(s.position, s.normal);
        changed +=
            glm::length(e - cpu_stale.irradiance(s.position, s.normal)) > 0.05f * glm::length(e)
                ? 1
                : 0;
    }
    EXPECT_GT(changed, samples.size() / 100) << "the box's visibility changes nothing";
    // A source without visibility cannot update a slot with it (and vice versa); a second
    // state's box ignores visibility.
    const Result<void> mismatch = gpu.value().updateBox(0, withoutVisibility(source), first, count);
    ASSERT_FALSE(mismatch.ok());
    EXPECT_EQ(mismatch.error().code, ErrorCode::InvalidArgument);
    EXPECT_NE(mismatch.error().message.find("visibility"), std::string::npos);
    Result<GpuVolumeSet> plain =
        GpuVolumeSet::create(context(), std::vector<Volume>{withoutVisibility(before)});
    ASSERT_TRUE(plain.ok());
    EXPECT_FALSE(plain.value().updateBox(0, source, first, count).ok());
    ASSERT_TRUE(plain.value()
                    .replaceVolume(0, withoutVisibility(source), runtime::VolumeState::Secondary)
                    .ok());
    EXPECT_TRUE(
        plain.value().updateBox(0, source, first, count, runtime::VolumeState::Secondary).ok());
}

} // namespace
