// Tests of the CPU reference sampler (runtime/include/probekit/runtime/sampler.hpp): trilinear
// interpolation, clamp addressing, frames, position modes, and blending of overlapping volumes.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>

#include "../gpu/bricked_test_volume.hpp"
#include "../gpu/dense_test_volume.hpp"
#include "probekit/formats/pvol.hpp"
#include "probekit/runtime/sampler.hpp"

using namespace probekit;
using runtime::VolumeSet;

namespace probekit::sh {
// Readable gtest failure messages for EXPECT_EQ on coefficients. Internal linkage so another
// test file may print ShRgb its own way.
static void PrintTo(const ShRgb& s, std::ostream* out) {
    for (int i = 0; i < kMaxCoefficients; ++i) {
        *out << (i == 0 ? "{" : ", ") << "(" << s.rgb[i].x << " " << s.rgb[i].y << " " << s.rgb[i].z
             << ")";
    }
    *out << "}";
}
} // namespace probekit::sh

namespace {

// Interpolating values of magnitude ~100 with weights in [0, 1] sums at most eight products, so
// each result is within a few float ulps (2^-23 relative) of the exact value.
constexpr float kInterpolationRelative = 1e-6f;
// Positions go through a quaternion rotation and a division by the spacing before they become
// grid coordinates; each step loses an ulp or so of a coordinate of magnitude ~10, which the
// field's unit gradient turns into ~1e-6 absolute on values of magnitude ~10.
constexpr float kFrameRelative = 1e-5f;
// binary16 has an 11-bit significand: round to nearest gives relative error <= 2^-11.
constexpr float kHalfRelative = 1.0f / 2048.0f;
// kY00 = 0.282095 is 1 / (2 sqrt(pi)) to 6 decimals (relative error ~7e-7), so a constant
// radiance comes back as pi L to about 1e-6 relative.
constexpr float kFurnaceRelative = 1e-5f;
// Along a line crossing a brick or level border, two samples 2 * kBorderStep apart differ by the
// field's change over that step (a coefficient's slope along an axis is <= ~2.6 per metre here,
// so <= ~5e-4) plus rounding of values of magnitude ~10 (a few 1e-6): a seam, i.e. bricks
// disagreeing at their shared face, would show as a jump of the size of the field's variation
// across a brick (~0.1 and more).
constexpr float kBorderStep = 1e-4f;
constexpr float kBorderJump = 1e-3f;
// Depths like 4 - 3.9f carry the rounding of a decimal position (~2e-7 m), divided by a fade
// distance of 0.5 m.
constexpr float kWeightTolerance = 1e-6f;

using ProbeFunction = std::function<sh::ShRgb(glm::uvec3 probe, glm::vec3 world)>;

using VolumeSpec = densetest::BasicVolumeSpec<2>;

Volume makeTestVolume(const VolumeSpec& spec, const ProbeFunction& probe_sh) {
    const VolumeDesc desc = densetest::volumeDesc(spec);
    Result<Volume> v = makeVolume(desc, densetest::fieldProbes(desc, probe_sh));
    EXPECT_TRUE(v.ok()) << v.error().message;
    return std::move(v).value();
}

// Every coefficient of every channel differs between probes and within a probe.
sh::ShRgb distinctSh(glm::uvec3 probe) {
    sh::ShRgb s;
    const float id = float(probe.x + 7 * probe.y + 31 * probe.z);
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        for (int c = 0; c < 3; ++c) {
            s.rgb[i][c] = id * 1.5f + float(i) * 0.25f - float(c) * 0.125f + 0.5f;
        }
    }
    return s;
}

// Radiance SH of a uniform environment of radiance L: L00 = sqrt(4 pi) L, the rest zero.
sh::ShRgb constantRadiance(glm::vec3 radiance) {
    sh::ShRgb s;
    s.rgb[0] = radiance * (2.0f * std::sqrt(sh::kPi));
    return s;
}

ProbeFunction constantField(glm::vec3 radiance) {
    return [radiance](glm::uvec3, glm::vec3) { return constantRadiance(radiance); };
}

// Coefficient i, channel c is an affine function of the world position, each one different.
sh::ShRgb affineField(glm::vec3 world) {
    sh::ShRgb s;
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        for (int c = 0; c < 3; ++c) {
            const glm::vec3 gradient(0.5f + 0.1f * float(i), -0.3f + 0.2f * float(c),
                                     0.7f - 0.05f * float(i + c));
            s.rgb[i][c] = glm::dot(gradient, world) + float(i) - 2.0f * float(c);
        }
    }
    return s;
}

sh::ShRgb lerpSh(const sh::ShRgb& a, const sh::ShRgb& b, float t) {
    sh::ShRgb s;
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        s.rgb[i] = (1.0f - t) * a.rgb[i] + t * b.rgb[i];
    }
    return s;
}

void expectShNear(const sh::ShRgb& actual, const sh::ShRgb& expected, float relative,
                  const std::string& where) {
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        for (int c = 0; c < 3; ++c) {
            const float e = expected.rgb[i][c];
            EXPECT_NEAR(actual.rgb[i][c], e, relative * std::max(1.0f, std::abs(e)))
                << where << ": coefficient " << i << " channel " << c;
        }
    }
}

void expectVec3Near(glm::vec3 actual, glm::vec3 expected, float relative,
                    const std::string& where) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(actual[c], expected[c], relative * std::max(1.0f, std::abs(expected[c])))
            << where << ": channel " << c;
    }
}

// Spacing 1 everywhere and probes on exact binary fractions, so probe positions map to integer
// grid coordinates without rounding.
VolumeSpec exactGridSpec(Storage storage) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(-2.0f, 0.0f, -4.0f), glm::vec3(2.0f, 2.0f, 4.0f)};
    spec.resolution = glm::uvec3(4, 2, 8);
    spec.storage = storage;
    return spec;
}

// A volume of `spec` whose every probe holds distinctSh of its coordinates.
Volume distinctVolume(const VolumeSpec& spec) {
    return makeTestVolume(spec, [](glm::uvec3 c, glm::vec3) { return distinctSh(c); });
}

// check(index, coordinates, the sampled SH at its position) for every probe of `v`.
void forEveryProbe(const Volume& v,
                   const std::function<void(size_t, glm::uvec3, const sh::ShRgb&)>& check) {
    const grid::GridLayout& g = v.desc.grid;
    for (size_t i = 0; i < v.probeCount(); ++i) {
        const glm::uvec3 c = g.probeCoords(i);
        check(i, c, runtime::sampleVolumeSh(v, g.probeWorld(c)));
    }
}

glm::vec3 furnaceE(glm::vec3 radiance) {
    return sh::kPi * radiance;
}

} // namespace

TEST(SamplerTrilinear, ReturnsStoredProbeExactlyAtEveryProbeFloat) {
    forEveryProbe(distinctVolume(exactGridSpec(Storage::Float32)),
                  [](size_t i, glm::uvec3 c, const sh::ShRgb& sampled) {
                      EXPECT_EQ(sampled, distinctSh(c)) << "probe " << i;
                  });
}

TEST(SamplerTrilinear, ReturnsStoredProbeWithinHalfPrecisionAtEveryProbeHalf) {
    const Volume v = distinctVolume(exactGridSpec(Storage::Float16));
    forEveryProbe(v, [&](size_t i, glm::uvec3 c, const sh::ShRgb& sampled) {
        // The decoded texels themselves come back bit for bit...
        EXPECT_EQ(sampled, v.probe(i)) << "probe " << i;
        // ...and they are the baked values to half precision.
        expectShNear(sampled, distinctSh(c), kHalfRelative, "probe " + std::to_string(i));
    });
}

TEST(SamplerTrilinear, MidwayBetweenProbesIsTheAverage) {
    const Volume v = distinctVolume(exactGridSpec(Storage::Float32));
    const grid::GridLayout& g = v.desc.grid;
    const glm::uvec3 a(1, 0, 3);
    const glm::uvec3 b(2, 0, 3);
    const glm::vec3 edge_mid = 0.5f * (g.probeWorld(a) + g.probeWorld(b));
    expectShNear(runtime::sampleVolumeSh(v, edge_mid), lerpSh(distinctSh(a), distinctSh(b), 0.5f),
                 kInterpolationRelative, "edge midpoint");

    // The centre of a cell is the mean of its eight probes.
    sh::ShRgb mean;
    for (uint32_t corner = 0; corner < 8; ++corner) {
        const glm::uvec3 c(1 + (corner & 1), (corner >> 1) & 1, 5 + (corner >> 2));
        sh::ShRgb s = distinctSh(c);
        s *= 0.125f;
        mean += s;
    }
    const glm::vec3 cell_centre =
        0.5f * (g.probeWorld(glm::uvec3(1, 0, 5)) + g.probeWorld(glm::uvec3(2, 1, 6)));
    expectShNear(runtime::sampleVolumeSh(v, cell_centre), mean, kInterpolationRelative,
                 "cell centre");
}

TEST(SamplerTrilinear, MatchesHandComputedValueAtArbitraryPoint) {
    // A separable, non-linear field v = a[x] * b[y] * c[z] (plus a per-coefficient offset and
    // scale so every coefficient differs): trilinear interpolation of a separable product is the
    // product of the three 1-D interpolations, which is easy to do by hand.
    static constexpr float kA[4] = {1, 3, 4, 10};
    static constexpr float kB[4] = {2, 5, 1, 7};
    static constexpr float kC[4] = {1, 2, 8, 3};
    auto field = [](glm::uvec3 p, glm::vec3) {
        sh::ShRgb s;
        for (int i = 0; i < sh::kMaxCoefficients; ++i) {
            for (int ch = 0; ch < 3; ++ch) {
                s.rgb[i][ch] = kA[p.x] * kB[p.y] * kC[p.z] * float(1 + i + 9 * ch) + float(i - ch);
            }
        }
        return s;
    };
    VolumeSpec spec;
    spec.mode = grid::PositionMode::Corner;
    spec.bounds = {glm::vec3(0.0f), glm::vec3(3.0f)}; // spacing 1: grid coordinate = position
    spec.resolution = glm::uvec3(4);
    const Volume v = makeTestVolume(spec, field);

    // Grid point (1.25, 2.5, 0.75):
    //   x: 0.75 * a[1] + 0.25 * a[2] = 2.25 + 1    = 3.25
    //   y: 0.5  * b[2] + 0.5  * b[3] = 0.5  + 3.5  = 4
    //   z: 0.25 * c[0] + 0.75 * c[1] = 0.25 + 1.5  = 1.75
    //   product 3.25 * 4 * 1.75 = 22.75
    constexpr float kProduct = 22.75f;
    const sh::ShRgb sampled = runtime::sampleVolumeSh(v, glm::vec3(1.25f, 2.5f, 0.75f));
    sh::ShRgb expected;
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        for (int ch = 0; ch < 3; ++ch) {
            expected.rgb[i][ch] = kProduct * float(1 + i + 9 * ch) + float(i - ch);
        }
    }
    expectShNear(sampled, expected, kInterpolationRelative, "(1.25, 2.5, 0.75)");
}

TEST(SamplerTrilinear, ReproducesAnAffineFieldAnywhereInside) {
    // Trilinear interpolation is exact for affine functions, so any error here is a wrong
    // index, weight, frame or position mode.
    const grid::RigidFrame rotated{glm::angleAxis(0.7f, glm::normalize(glm::vec3(1, 2, 3))),
                                   glm::vec3(5.0f, -1.0f, 2.0f)};
    for (grid::PositionMode mode : {grid::PositionMode::Center, grid::PositionMode::Corner}) {
        for (const grid::RigidFrame& frame : {grid::RigidFrame{}, rotated}) {
            VolumeSpec spec;
            spec.bounds = {glm::vec3(-1.0f, 0.5f, -3.0f), glm::vec3(2.0f, 2.0f, 1.0f)};
            spec.resolution = glm::uvec3(8, 4, 16);
            spec.mode = mode;
            spec.frame = frame;
            const Volume v = makeTestVolume(
                spec, [](glm::uvec3, glm::vec3 world) { return affineField(world); });
            const grid::GridLayout& g = v.desc.grid;
            const glm::vec3 last = glm::vec3(spec.resolution) - 1.0f;
            // Points spread over the lattice (inside the outermost probes, where there is no
            // clamping), at irrational fractions so no weight is 0 or 1.
            for (int k = 0; k < 50; ++k) {
                const glm::vec3 t(std::fmod(0.1f + 0.618034f * float(k), 1.0f),
                                  std::fmod(0.3f + 0.414214f * float(k), 1.0f),
                                  std::fmod(0.7f + 0.732051f * float(k), 1.0f));
                const glm::vec3 world = g.gridToWorld(t * last);
                expectShNear(runtime::sampleVolumeSh(v, world), affineField(world), kFrameRelative,
                             std::string(grid::toString(mode)) + " point " + std::to_string(k));
            }
        }
    }
}

TEST(SamplerClamp, OutsideEqualsNearestBorderValue) {
    const Volume v = distinctVolume(exactGridSpec(Storage::Float32));
    const grid::GridLayout& g = v.desc.grid;
    const glm::uvec3 res = g.resolution();

    // Beyond the -x face (and between the face and the outer probes), at a y, z between probes:
    // the value on the first probe plane at the same y, z.
    const glm::vec3 inside_yz = g.gridToWorld(glm::vec3(0.0f, 0.3f, 2.6f));
    const sh::ShRgb border = runtime::sampleVolumeSh(v, inside_yz);
    for (float x : {-2.1f, -2.0f, -1.9f, -50.0f}) {
        expectShNear(runtime::sampleVolumeSh(v, glm::vec3(x, inside_yz.y, inside_yz.z)), border,
                     kInterpolationRelative, "x = " + std::to_string(x));
    }
    // Far beyond a corner of the box: the corner probe itself.
    EXPECT_EQ(runtime::sampleVolumeSh(v, glm::vec3(100.0f, 100.0f, 100.0f)), distinctSh(res - 1u));
    EXPECT_EQ(runtime::sampleVolumeSh(v, glm::vec3(-100.0f, -100.0f, -100.0f)),
              distinctSh(glm::uvec3(0)));
    // Beyond the +z face only: interpolates in x, y as usual, clamps in z.
    const glm::vec3 near_top = g.gridToWorld(glm::vec3(1.5f, 0.5f, float(res.z - 1)));
    expectShNear(runtime::sampleVolumeSh(v, near_top + glm::vec3(0.0f, 0.0f, 10.0f)),
                 runtime::sampleVolumeSh(v, near_top), kInterpolationRelative, "beyond +z");
}

TEST(SamplerGrid, ResolutionOneAxesUseTheirSingleProbe) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(0.0f), glm::vec3(1.0f, 4.0f, 1.0f)};
    spec.resolution = glm::uvec3(1, 4, 1);
    const Volume column = distinctVolume(spec);
    // Probes at y = 0.5, 1.5, 2.5, 3.5; x and z do not matter, even outside the box.
    for (glm::vec2 xz : {glm::vec2(0.5f, 0.5f), glm::vec2(0.0f, 1.0f), glm::vec2(-3.0f, 7.0f)}) {
        EXPECT_EQ(runtime::sampleVolumeSh(column, glm::vec3(xz.x, 2.5f, xz.y)),
                  distinctSh(glm::uvec3(0, 2, 0)));
        expectShNear(
            runtime::sampleVolumeSh(column, glm::vec3(xz.x, 1.75f, xz.y)),
            lerpSh(distinctSh(glm::uvec3(0, 1, 0)), distinctSh(glm::uvec3(0, 2, 0)), 0.25f),
            kInterpolationRelative, "y = 1.75");
    }

    spec.resolution = glm::uvec3(1);
    const Volume single = distinctVolume(spec);
    for (glm::vec3 p :
         {glm::vec3(0.5f, 2.0f, 0.5f), glm::vec3(0.0f), glm::vec3(9.0f, -9.0f, 3.0f)}) {
        EXPECT_EQ(runtime::sampleVolumeSh(single, p), distinctSh(glm::uvec3(0)));
    }
}

TEST(SamplerFrame, RotatedTranslatedVolumeFindsTheRightProbes) {
    // Two probes along local x, at local (0.5, 0.5, 0.5) and (1.5, 0.5, 0.5). A quarter turn
    // about +Y takes local +x to world -z; then the volume moves by (10, 0, 0). By hand:
    //   probe 0 -> (0.5, 0.5, -0.5) + (10, 0, 0) = (10.5, 0.5, -0.5)
    //   probe 1 -> (0.5, 0.5, -1.5) + (10, 0, 0) = (10.5, 0.5, -1.5)
    VolumeSpec spec;
    spec.bounds = {glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 1.0f)};
    spec.resolution = glm::uvec3(2, 1, 1);
    spec.frame = grid::RigidFrame{glm::angleAxis(0.5f * sh::kPi, glm::vec3(0, 1, 0)),
                                  glm::vec3(10.0f, 0.0f, 0.0f)};
    const Volume v = distinctVolume(spec);
    const sh::ShRgb p0 = distinctSh(glm::uvec3(0, 0, 0));
    const sh::ShRgb p1 = distinctSh(glm::uvec3(1, 0, 0));
    expectShNear(runtime::sampleVolumeSh(v, glm::vec3(10.5f, 0.5f, -0.5f)), p0, kFrameRelative,
                 "probe 0");
    expectShNear(runtime::sampleVolumeSh(v, glm::vec3(10.5f, 0.5f, -1.5f)), p1, kFrameRelative,
                 "probe 1");
    expectShNear(runtime::sampleVolumeSh(v, glm::vec3(10.5f, 0.5f, -1.25f)), lerpSh(p0, p1, 0.75f),
                 kFrameRelative, "between");
    // The world position of the untransformed volume's probe 1 is outside the moved box; it
    // clamps to probe 0 (local x < 0.5), not to probe 1.
    expectShNear(runtime::sampleVolumeSh(v, glm::vec3(1.5f, 0.5f, 0.5f)), p0, kFrameRelative,
                 "old position");
    EXPECT_FLOAT_EQ(runtime::volumeWeight(v, glm::vec3(10.5f, 0.5f, -1.0f)), 1.0f);
    EXPECT_FLOAT_EQ(runtime::volumeWeight(v, glm::vec3(1.0f, 0.5f, 0.5f)), 0.0f);
    EXPECT_NEAR(runtime::distanceToVolume(v, glm::vec3(10.5f, 0.5f, 1.0f)), 1.0f, kFrameRelative);
}

TEST(SamplerGrid, CornerAndCenterModesPlaceProbesDifferently) {
    // Box [0, 3] on x with 4 probes: corner mode puts them at 0, 1, 2, 3; centre mode at
    // 0.375, 1.125, 1.875, 2.625 (spacing 0.75). The field depends on the x index only.
    auto by_x = [](glm::uvec3 c, glm::vec3) { return distinctSh(glm::uvec3(c.x, 0, 0)); };
    VolumeSpec spec;
    spec.bounds = {glm::vec3(0.0f), glm::vec3(3.0f, 1.0f, 1.0f)};
    spec.resolution = glm::uvec3(4, 2, 2);
    spec.mode = grid::PositionMode::Corner;
    const Volume corner = makeTestVolume(spec, by_x);
    spec.mode = grid::PositionMode::Center;
    const Volume center = makeTestVolume(spec, by_x);
    const sh::ShRgb p0 = distinctSh(glm::uvec3(0, 0, 0));
    const sh::ShRgb p1 = distinctSh(glm::uvec3(1, 0, 0));

    const glm::vec3 at_x1(1.0f, 0.5f, 0.5f);
    expectShNear(runtime::sampleVolumeSh(corner, at_x1), p1, kInterpolationRelative,
                 "corner x = 1");
    // centre mode: grid x = 1 / 0.75 - 0.5 = 5/6 between probes 0 and 1
    expectShNear(runtime::sampleVolumeSh(center, at_x1), lerpSh(p0, p1, 5.0f / 6.0f),
                 kInterpolationRelative, "center x = 1");
    // At the box's -x face, corner mode has a probe; centre mode clamps to its first probe.
    const glm::vec3 at_face(0.0f, 0.5f, 0.5f);
    expectShNear(runtime::sampleVolumeSh(corner, at_face), p0, kInterpolationRelative,
                 "corner face");
    expectShNear(runtime::sampleVolumeSh(center, at_face), p0, kInterpolationRelative,
                 "center face");
    expectShNear(runtime::sampleVolumeSh(corner, glm::vec3(0.375f, 0.5f, 0.5f)),
                 lerpSh(p0, p1, 0.375f), kInterpolationRelative, "corner x = 0.375");
    expectShNear(runtime::sampleVolumeSh(center, glm::vec3(0.375f, 0.5f, 0.5f)), p0,
                 kInterpolationRelative, "center x = 0.375");
}

TEST(SamplerIrradiance, ConstantRadianceGivesPiLForEveryNormal) {
    const glm::vec3 radiance(0.3f, 1.7f, 4.0f);
    for (sh::Order order : {sh::Order::L1, sh::Order::L2}) {
        for (Storage storage : {Storage::Float32, Storage::Float16}) {
            VolumeSpec spec = exactGridSpec(storage);
            spec.order = order;
            const VolumeSet set({makeTestVolume(spec, constantField(radiance))});
            const float tolerance = storage == Storage::Float16 ? kHalfRelative : kFurnaceRelative;
            for (int i = 0; i < 64; ++i) {
                const glm::vec3 n = sh::fibonacciDirection(i, 64);
                for (glm::vec3 p : {glm::vec3(0.1f, 1.3f, -2.7f), glm::vec3(30.0f, -4.0f, 0.0f)}) {
                    expectVec3Near(set.irradiance(p, n), furnaceE(radiance), tolerance,
                                   "normal " + std::to_string(i));
                }
            }
        }
    }
}

TEST(VolumeSetBlend, FullyCoveringHighPriorityVolumeHidesLowerOnes) {
    const VolumeSpec high{
        .bounds = {glm::vec3(0.0f), glm::vec3(4.0f)}, .priority = 5, .fade = 0.5f};
    const VolumeSpec low{.bounds = {glm::vec3(-10.0f), glm::vec3(10.0f)}, .priority = 1};
    const glm::vec3 l_high(1.0f), l_low(3.0f, 2.0f, 7.0f);
    const glm::vec3 n(0.0f, 1.0f, 0.0f);
    // File order must not matter: the higher priority wins either way.
    const VolumeSet high_first(
        {makeTestVolume(high, constantField(l_high)), makeTestVolume(low, constantField(l_low))});
    const VolumeSet low_first(
        {makeTestVolume(low, constantField(l_low)), makeTestVolume(high, constantField(l_high))});
    for (const VolumeSet* set : {&high_first, &low_first}) {
        expectVec3Near(set->irradiance(glm::vec3(2.0f), n), furnaceE(l_high), kFurnaceRelative,
                       "deep inside the high-priority volume");
        // Exactly fadeDistance deep: still full weight.
        expectVec3Near(set->irradiance(glm::vec3(0.5f, 2.0f, 2.0f), n), furnaceE(l_high),
                       kFurnaceRelative, "at the inner edge of the fade band");
        expectVec3Near(set->irradiance(glm::vec3(-1.0f, 2.0f, 2.0f), n), furnaceE(l_low),
                       kFurnaceRelative, "outside the high-priority volume");
    }
}

TEST(VolumeSetBlend, FadeBandWeightsAreLinear) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(0.0f), glm::vec3(4.0f)};
    spec.fade = 0.5f;
    const Volume v = makeTestVolume(spec, constantField(glm::vec3(1.0f)));
    // Depth = distance to the nearest face.
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(0.0f, 2.0f, 2.0f)), 0.0f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(0.1f, 2.0f, 2.0f)), 0.2f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(2.0f, 3.8f, 2.0f)), 0.4f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(0.3f, 0.2f, 3.9f)), 0.2f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(0.5f, 2.0f, 2.0f)), 1.0f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(2.0f)), 1.0f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(-0.1f, 2.0f, 2.0f)), 0.0f, kWeightTolerance);
    EXPECT_NEAR(runtime::volumeWeight(v, glm::vec3(2.0f, 2.0f, 4.5f)), 0.0f, kWeightTolerance);

    // fadeDistance 0: a hard border, full weight up to and including the faces.
    spec.fade = 0.0f;
    const Volume hard = makeTestVolume(spec, constantField(glm::vec3(1.0f)));
    EXPECT_EQ(runtime::volumeWeight(hard, glm::vec3(0.001f, 2.0f, 2.0f)), 1.0f);
    EXPECT_EQ(runtime::volumeWeight(hard, glm::vec3(4.0f, 2.0f, 2.0f)), 1.0f);
    EXPECT_EQ(runtime::volumeWeight(hard, glm::vec3(4.001f, 2.0f, 2.0f)), 0.0f);

    // Three nested volumes at a point 0.2 m deep in A (fade 0.5: w = 0.4) and 0.25 m deep in B
    // (fade 0.5: w = 0.5), well inside C:
    //   a_A = 0.4, a_B = 0.5 * 0.6 = 0.3, a_C = 1 * 0.3 = 0.3, sum 1.
    VolumeSpec a = spec, b = spec, c = spec;
    a.bounds = {glm::vec3(0.0f), glm::vec3(4.0f)};
    a.fade = 0.5f;
    a.priority = 3;
    b.bounds = {glm::vec3(-0.05f, -4.0f, -4.0f), glm::vec3(8.0f)};
    b.fade = 0.5f;
    b.priority = 2;
    c.bounds = {glm::vec3(-20.0f), glm::vec3(20.0f)};
    c.fade = 1.0f;
    c.priority = 1;
    const glm::vec3 la(1.0f, 0.0f, 0.0f), lb(0.0f, 1.0f, 0.0f), lc(0.0f, 0.0f, 1.0f);
    // File order scrambled on purpose.
    const VolumeSet set({makeTestVolume(c, constantField(lc)), makeTestVolume(a, constantField(la)),
                         makeTestVolume(b, constantField(lb))});
    const glm::vec3 p(0.2f, 2.0f, 2.0f);
    const glm::vec3 expected = furnaceE(0.4f * la + 0.3f * lb + 0.3f * lc);
    expectVec3Near(set.irradiance(p, glm::vec3(1.0f, 0.0f, 0.0f)), expected, kFurnaceRelative,
                   "three-volume blend");
}

TEST(VolumeSetBlend, NoFadeToBlackAtTheOuterBorderOfTheLastVolume) {
    const VolumeSpec inner{
        .bounds = {glm::vec3(0.0f), glm::vec3(4.0f)}, .priority = 1, .fade = 1.0f};
    const VolumeSpec elsewhere{.bounds = {glm::vec3(10.0f), glm::vec3(12.0f)}};
    const glm::vec3 l_inner(2.0f, 1.0f, 0.5f);
    const VolumeSet set({makeTestVolume(inner, constantField(l_inner)),
                         makeTestVolume(elsewhere, constantField(glm::vec3(9.0f)))});
    const glm::vec3 n = glm::normalize(glm::vec3(1.0f, -2.0f, 0.5f));
    // Depths 0.5, 0.1 and 0.001 into a 1 m fade band, and exactly on the face: all full E.
    for (float x : {0.5f, 0.1f, 0.001f, 0.0f}) {
        expectVec3Near(set.irradiance(glm::vec3(x, 2.0f, 2.0f), n), furnaceE(l_inner),
                       kFurnaceRelative, "x = " + std::to_string(x));
    }
}

TEST(VolumeSetBlend, OutsideAllVolumesUsesTheNearestOne) {
    VolumeSpec left;
    left.bounds = {glm::vec3(0.0f), glm::vec3(1.0f)};
    left.resolution = glm::uvec3(4);
    left.priority = 0;
    VolumeSpec right = left;
    right.bounds = {glm::vec3(5.0f, 0.0f, 0.0f), glm::vec3(6.0f, 1.0f, 1.0f)};
    auto distinct = [](glm::uvec3 c, glm::vec3) { return distinctSh(c); };
    auto shifted = [](glm::uvec3 c, glm::vec3) { return distinctSh(c + 4u); };
    const Volume vl = makeTestVolume(left, distinct);
    const Volume vr = makeTestVolume(right, shifted);
    const VolumeSet set({vl, vr});
    const glm::vec3 n(0.0f, 0.0f, 1.0f);

    // x = 3.9 is 1.1 m from the right box and 2.9 m from the left one; clamp addressing there
    // gives the right volume's -x face values at (y, z).
    const glm::vec3 p(3.9f, 0.3f, 0.8f);
    EXPECT_NEAR(runtime::distanceToVolume(vr, p), 1.1f, kInterpolationRelative);
    EXPECT_NEAR(runtime::distanceToVolume(vl, p), 2.9f, kInterpolationRelative);
    const glm::vec3 expected =
        sh::irradiance(runtime::sampleVolumeSh(vr, glm::vec3(5.0f, p.y, p.z)), sh::Order::L2, n);
    expectVec3Near(set.irradiance(p, n), expected, kInterpolationRelative, "nearer the right");
    const glm::vec3 q(1.5f, 2.0f, -1.0f);
    expectVec3Near(set.irradiance(q, n),
                   sh::irradiance(runtime::sampleVolumeSh(vl, q), sh::Order::L2, n),
                   kInterpolationRelative, "nearer the left");

    // Equidistant (x = 3): the higher priority wins; with equal priorities, file order.
    const glm::vec3 mid(3.0f, 0.5f, 0.5f);
    const glm::vec3 e_left = sh::irradiance(runtime::sampleVolumeSh(vl, mid), sh::Order::L2, n);
    const glm::vec3 e_right = sh::irradiance(runtime::sampleVolumeSh(vr, mid), sh::Order::L2, n);
    ASSERT_NE(e_left, e_right);
    EXPECT_EQ(set.irradiance(mid, n), e_left);
    EXPECT_EQ(VolumeSet({vr, vl}).irradiance(mid, n), e_right);
    right.priority = 1;
    const Volume vr_high = makeTestVolume(right, shifted);
    EXPECT_EQ(VolumeSet({vl, vr_high}).irradiance(mid, n), e_right);
}

TEST(VolumeSetBlend, DistanceToVolume) {
    VolumeSpec spec;
    spec.bounds = {glm::vec3(0.0f), glm::vec3(2.0f)};
    const Volume v = makeTestVolume(spec, constantField(glm::vec3(1.0f)));
    EXPECT_EQ(runtime::distanceToVolume(v, glm::vec3(1.0f)), 0.0f);
    EXPECT_EQ(runtime::distanceToVolume(v, glm::vec3(2.0f, 0.0f, 1.0f)), 0.0f);
    EXPECT_FLOAT_EQ(runtime::distanceToVolume(v, glm::vec3(1.0f, 5.0f, 1.0f)), 3.0f);
    EXPECT_FLOAT_EQ(runtime::distanceToVolume(v, glm::vec3(-1.0f, -1.0f, 3.0f)), std::sqrt(3.0f));
}

TEST(VolumeSetLoad, RoundTripsAFile) {
    const std::filesystem::path path =
        std::filesystem::path(::testing::TempDir()) / "sampler_roundtrip.pvol";
    PvolFile file;
    file.metadata.method = "synthetic";
    VolumeSpec spec;
    spec.priority = 4;
    spec.fade = 0.25f;
    file.volumes.push_back(makeTestVolume(spec, constantField(glm::vec3(0.5f, 1.0f, 2.0f))));
    ASSERT_TRUE(writePvol(path, file).ok());
    Result<VolumeSet> set = VolumeSet::load(path);
    ASSERT_TRUE(set.ok()) << set.error().message;
    ASSERT_EQ(set.value().volumes().size(), 1u);
    EXPECT_EQ(set.value().volumes()[0].desc.blendPriority, 4);
    expectVec3Near(set.value().irradiance(glm::vec3(0.5f), glm::vec3(0.0f, 1.0f, 0.0f)),
                   furnaceE(glm::vec3(0.5f, 1.0f, 2.0f)), kFurnaceRelative, "loaded");
    std::filesystem::remove(path);
}

TEST(VolumeSetLoad, ErrorsPassThroughTheFileMessage) {
    const std::filesystem::path dir = ::testing::TempDir();
    const std::filesystem::path missing = dir / "sampler_does_not_exist.pvol";
    const std::filesystem::path garbage = dir / "sampler_garbage.pvol";
    {
        std::ofstream out(garbage, std::ios::binary);
        out << "this is not a probe volume file, not even close";
    }
    for (const std::filesystem::path& path : {missing, garbage}) {
        Result<VolumeSet> set = VolumeSet::load(path);
        ASSERT_FALSE(set.ok()) << path;
        const Result<PvolFile> direct = readPvol(path);
        ASSERT_FALSE(direct.ok());
        EXPECT_EQ(set.error().code, direct.error().code);
        EXPECT_EQ(set.error().message, direct.error().message);
        EXPECT_NE(set.error().message.find(path.filename().string()), std::string::npos)
            << set.error().message;
    }
    std::filesystem::remove(garbage);
}

// VolumeSet's precondition, every volume passing validateVolume, is checked in every build type
// (sampler.hpp, ARCHITECTURE.md "Preconditions"): make() returns the error naming the volume,
// the constructor aborts with it, and sampling an empty set aborts rather than reading a
// volume that is not there.
TEST(VolumeSetMake, RejectsAnInvalidVolumeNamingIt) {
    VolumeSpec spec;
    spec.name = "truncated";
    const Volume good = makeTestVolume(VolumeSpec{}, constantField(glm::vec3(1.0f)));
    Volume bad = makeTestVolume(spec, constantField(glm::vec3(1.0f)));
    bad.texelsF32.pop_back();
    Result<VolumeSet> set = VolumeSet::make({good, bad});
    ASSERT_FALSE(set.ok());
    EXPECT_EQ(set.error().code, ErrorCode::InconsistentSize);
    EXPECT_EQ(set.error().message.rfind("volumes[1]: volume 'truncated': texel data holds", 0), 0u)
        << set.error().message;
    Result<VolumeSet> valid = VolumeSet::make({good});
    ASSERT_TRUE(valid.ok()) << valid.error().message;
    EXPECT_EQ(valid.value().irradiance(glm::vec3(0.5f), glm::vec3(0.0f, 1.0f, 0.0f)),
              VolumeSet({good}).irradiance(glm::vec3(0.5f), glm::vec3(0.0f, 1.0f, 0.0f)));
}

TEST(VolumeSetDeathTest, ChecksItsPreconditions) {
    VolumeSpec spec;
    spec.name = "truncated";
    Volume bad = makeTestVolume(spec, constantField(glm::vec3(1.0f)));
    bad.validity.pop_back();
    EXPECT_DEATH(VolumeSet({bad}), "precondition failed in VolumeSet: validateVolume.*volume "
                                   "'truncated': 7 validity bytes for 8 probes");
    const VolumeSet empty;
    EXPECT_DEATH(empty.irradiance(glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f)),
                 "precondition failed in irradiance: !empty");
}

// ---- Bricked volumes (steps B1-B4 of sampler.hpp) ----

namespace {

VolumeDesc brickedDesc(const brick::BrickLayout& layout, glm::uvec3 top,
                       const grid::RigidFrame& frame, Storage storage) {
    VolumeDesc desc;
    desc.name = "bricked";
    desc.grid = grid::GridLayout({glm::vec3(-1.0f, 0.5f, -3.0f), glm::vec3(2.0f, 2.0f, 1.0f)}, top,
                                 grid::PositionMode::Center, frame);
    desc.layout = VolumeLayout::Bricked;
    desc.bricks = layout;
    desc.storage = storage;
    return desc;
}

const grid::RigidFrame kRotated{glm::angleAxis(0.7f, glm::normalize(glm::vec3(1, 2, 3))),
                                glm::vec3(5.0f, -1.0f, 2.0f)};

// An irrational-fraction point of the box (no weight exactly 0 or 1), world frame.
glm::vec3 boxPoint(const VolumeDesc& desc, int k) {
    const glm::vec3 t(std::fmod(0.1f + 0.618034f * float(k), 1.0f),
                      std::fmod(0.3f + 0.414214f * float(k), 1.0f),
                      std::fmod(0.7f + 0.732051f * float(k), 1.0f));
    const grid::Aabb& box = desc.grid.bounds();
    return desc.grid.frame().toWorld(box.min + t * box.size());
}

} // namespace

TEST(SamplerBricked, EqualsBrickInterpolateOfTheStoredSh) {
    // Interpolating texels then unpacking equals unpacking then interpolating SH (both linear),
    // so sampleVolumeSh must equal brick::locate + brick::interpolate over Volume::probe.
    const glm::uvec3 top(2, 1, 2);
    for (Storage storage : {Storage::Float32, Storage::Float16}) {
        const VolumeDesc desc = brickedDesc(bricktest::mixedLayout(top), top, kRotated, storage);
        // Unstitched distinct values: any wrong brick, probe or weight shows.
        size_t counter = 0;
        const Volume v = bricktest::makeBrickedVolume(
            desc,
            [&counter](glm::vec3) {
                ++counter;
                return distinctSh(glm::uvec3(counter % 97, counter / 97, counter % 5));
            },
            false);
        std::vector<sh::ShRgb> probes(v.probeCount());
        for (size_t i = 0; i < probes.size(); ++i) {
            probes[i] = v.probe(i);
        }
        const glm::uvec3 cells = brick::finestCells(top, desc.bricks.maxLevel);
        for (int k = 0; k < 400; ++k) {
            const glm::vec3 world = boxPoint(desc, k);
            const grid::Aabb& box = desc.grid.bounds();
            const glm::vec3 f =
                (desc.grid.frame().toLocal(world) - box.min) / box.size() * glm::vec3(cells);
            const brick::BrickSample at = brick::locate(top, desc.bricks, v.indirection, f);
            const sh::ShRgb expected =
                brick::interpolate(std::span(probes).subspan(size_t(at.brick) * 64, 64), at.local);
            expectShNear(runtime::sampleVolumeSh(v, world), expected, kInterpolationRelative * 4,
                         std::string(toString(storage)) + " point " + std::to_string(k));
        }
    }
}

TEST(SamplerBricked, UniformLevel0OfALinearFieldIsTheField) {
    // Probes sit on the box faces, so the whole box (faces included) reproduces an affine field;
    // outside, the value clamps to the nearest face's.
    for (const grid::RigidFrame& frame : {grid::RigidFrame{}, kRotated}) {
        const glm::uvec3 top(4, 2, 8);
        const VolumeDesc desc =
            brickedDesc(brick::uniformLayout(top, 0), top, frame, Storage::Float32);
        const Volume v = bricktest::makeBrickedVolume(desc, affineField, false);
        for (int k = 0; k < 200; ++k) {
            const glm::vec3 world = boxPoint(desc, k);
            expectShNear(runtime::sampleVolumeSh(v, world), affineField(world), kFrameRelative,
                         "point " + std::to_string(k));
        }
        const grid::Aabb& box = desc.grid.bounds();
        const glm::vec3 outside = box.max + glm::vec3(0.5f, 0.25f, 1.0f);
        expectShNear(runtime::sampleVolumeSh(v, frame.toWorld(outside)),
                     affineField(frame.toWorld(box.max)), kFrameRelative, "outside");
    }
}

TEST(SamplerBricked, ContinuousAcrossBrickAndLevelBorders) {
    // Lines through every kind of border of the mixed layout (level 0/1, 0/2, 1/2 and same-level
    // faces): globally linear data needs no stitching; a smooth non-linear field is stitched.
    const glm::uvec3 top(2, 1, 2);
    const VolumeDesc desc = brickedDesc(bricktest::mixedLayout(top), top, {}, Storage::Float32);
    const auto smooth = [](glm::vec3 x) {
        sh::ShRgb s = affineField(x);
        for (int i = 0; i < sh::kMaxCoefficients; ++i) {
            s.rgb[i] += glm::vec3(std::sin(1.3f * x.x + 0.2f * float(i)) * std::cos(0.9f * x.z));
        }
        return s;
    };
    const Volume linear = bricktest::makeBrickedVolume(desc, affineField, false);
    const Volume stitched = bricktest::makeBrickedVolume(desc, smooth, true);
    const glm::uvec3 cells = brick::finestCells(top, desc.bricks.maxLevel);
    const grid::Aabb& box = desc.grid.bounds();
    const glm::vec3 cell = box.size() / glm::vec3(cells);
    float worst = 0.0f;
    for (int axis = 0; axis < 3; ++axis) {
        // Every interior finest-cell face on this axis, crossed at irrational points.
        for (uint32_t face = 1; face < cells[axis]; ++face) {
            for (int k = 0; k < 20; ++k) {
                glm::vec3 local = desc.grid.frame().toLocal(boxPoint(desc, k + 20 * int(face)));
                local[axis] = box.min[axis] + float(face) * cell[axis];
                glm::vec3 step(0.0f);
                step[axis] = kBorderStep;
                for (const Volume* v : {&linear, &stitched}) {
                    const sh::ShRgb a = runtime::sampleVolumeSh(*v, local - step);
                    const sh::ShRgb b = runtime::sampleVolumeSh(*v, local + step);
                    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
                        const glm::vec3 d = glm::abs(a.rgb[i] - b.rgb[i]);
                        worst = std::max(worst, std::max(d.x, std::max(d.y, d.z)));
                    }
                }
            }
        }
    }
    std::printf("[ figures  ] largest jump across bricked borders: %.3g (bound %.0e)\n",
                double(worst), double(kBorderJump));
    EXPECT_LE(worst, kBorderJump);
}
