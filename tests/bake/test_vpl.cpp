// Tests of the VPL method: light paths (vpl_paths.hpp), the gather (vpl_gather.hpp) and bakes
// with method "vpl".
//
// Statistics, as in test_path.cpp:
//  * Light-path power checks: with a single floor and one bounce, every light path carries the
//    same flux (each light is sampled exactly proportionally to its emission, and white lights
//    are chosen proportionally to power), so the total VPL flux is flux x (number of paths
//    hitting the floor): a binomial count. Its relative standard deviation is
//    sqrt((1 - p) / (N p)) <= 1 / sqrt(K), K the number of VPLs; kSigmas of it is the
//    tolerance (random sampling; stratified sampling only does better).
//  * Gather checks: kSeeds independent VPL sets (seeds), and the mean compared with the exact
//    answer within kSigmas standard errors estimated from their spread (Student's t with
//    kSeeds - 1 = 15 degrees of freedom: |t| > 5 has probability 1.6e-4), plus kFloatSlack.
//  * Against the path method: the path reference's own noise is measured from two seeds and
//    stated; every tolerance below leaves room for it.
// A failing check writes its numbers to PROBEKIT_TEST_OUTPUT_DIR.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

#include "bake_test_support.hpp"
#include "methods/vpl_gather.hpp"
#include "methods/vpl_paths.hpp"
#include "probekit/baker/bake.hpp"
#include "probekit/baker/generators.hpp"
#include "probekit/formats/sh.hpp"
#include "trace/ray_tracer.hpp"

namespace probekit::baker {
namespace {

using test::kFloatSlack;
using test::kGaussNodes;
using test::kGaussWeights;
using test::kPi;
using test::kSigmas;

// See the file comment.
constexpr int kSeeds = 16;

// ---------------------------------------------------------------------------------------------
// Scenes, built face by face.

class SceneBuilder {
public:
    SceneBuilder() : m_scene(test::emptyScene()) {}
    uint32_t material(glm::vec3 albedo, glm::vec3 emission = glm::vec3(0.0f)) {
        return test::addMaterial(m_scene, albedo, emission);
    }
    // A planar quad corner, corner + u, corner + u + v, corner + v, wound so that its normal
    // points along `facing`.
    void quad(glm::vec3 corner, glm::vec3 u, glm::vec3 v, glm::vec3 facing, uint32_t material) {
        if (glm::dot(glm::cross(u, v), facing) < 0.0f) {
            std::swap(u, v);
        }
        const auto first = uint32_t(m_scene.positions.size());
        for (const glm::vec3 p : {corner, corner + u, corner + u + v, corner + v}) {
            m_scene.positions.push_back(p);
            m_scene.uvs.emplace_back(0.0f);
        }
        for (const glm::uvec3 t : {glm::uvec3(0, 1, 2), glm::uvec3(0, 2, 3)}) {
            m_scene.triangles.push_back(t + first);
            m_scene.triangleMaterial.push_back(material);
            m_scene.triangleNode.push_back(-1);
        }
    }
    // The six faces of an axis-aligned box, normals inward (a room) or outward (a block).
    void box(glm::vec3 lo, glm::vec3 hi, bool inward, uint32_t material) {
        for (int axis = 0; axis < 3; ++axis) {
            const int a = (axis + 1) % 3, b = (axis + 2) % 3;
            for (const bool high : {false, true}) {
                glm::vec3 corner = lo, u(0.0f), v(0.0f), out(0.0f);
                corner[axis] = high ? hi[axis] : lo[axis];
                u[a] = hi[a] - lo[a];
                v[b] = hi[b] - lo[b];
                out[axis] = high ? 1.0f : -1.0f;
                quad(corner, u, v, inward ? -out : out, material);
            }
        }
    }
    void light(const PunctualLight& l) { m_scene.lights.push_back(l); }
    void environment(glm::vec3 radiance) { m_scene.environment.constant = radiance; }

    Scene finish() {
        m_scene.bounds.min = m_scene.bounds.max = m_scene.positions.at(0);
        for (const glm::vec3& p : m_scene.positions) {
            m_scene.bounds.min = glm::min(m_scene.bounds.min, p);
            m_scene.bounds.max = glm::max(m_scene.bounds.max, p);
        }
        return m_scene;
    }

private:
    Scene m_scene;
};

std::unique_ptr<RayTracer> tracerFor(const Scene& scene) {
    Result<std::unique_ptr<RayTracer>> t = RayTracer::create(scene);
    EXPECT_TRUE(t.ok()) << (t.ok() ? "" : t.error().message);
    return t.ok() ? std::move(t).value() : nullptr;
}

PunctualLight pointLight(glm::vec3 position, float intensity) {
    PunctualLight l;
    l.type = LightType::Point;
    l.position = position;
    l.intensity = glm::vec3(intensity);
    return l;
}

void writeFailure(const std::string& name, const std::string& text) {
    const std::filesystem::path dir = PROBEKIT_TEST_OUTPUT_DIR;
    std::filesystem::create_directories(dir);
    std::ofstream(dir / ("vpl_" + name + ".txt")) << text;
}

// ---------------------------------------------------------------------------------------------
// Quadrature.

// Integral of f(x, z) over the square [-half, half]^2, cells x cells pieces of 8 x 8 points.
double integrateSquare(double half, int cells, const std::function<double(double, double)>& f) {
    const double h = 2.0 * half / cells;
    double sum = 0.0;
    for (int i = 0; i < cells; ++i) {
        for (int j = 0; j < cells; ++j) {
            for (int a = 0; a < 8; ++a) {
                for (int b = 0; b < 8; ++b) {
                    const double x = -half + (i + 0.5 + 0.5 * kGaussNodes[a]) * h;
                    const double z = -half + (j + 0.5 + 0.5 * kGaussNodes[b]) * h;
                    sum += kGaussWeights[a] * kGaussWeights[b] * 0.25 * h * h * f(x, z);
                }
            }
        }
    }
    return sum;
}

// View factor from a small surface facing a parallel rectangle at distance c, above one of
// the rectangle's corners, rectangle sides a and b (Howell's catalogue, B-3).
double cornerViewFactor(double a, double b, double c) {
    const double x = a / c, y = b / c;
    const double sx = std::sqrt(1.0 + x * x), sy = std::sqrt(1.0 + y * y);
    return (x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy)) / (2.0 * kPi);
}

// ... above the point (x, z) of the square [-half, half]^2: four corner rectangles.
double squareViewFactor(double half, double x, double z, double c) {
    return cornerViewFactor(half - x, half - z, c) + cornerViewFactor(half + x, half - z, c) +
           cornerViewFactor(half - x, half + z, c) + cornerViewFactor(half + x, half + z, c);
}

// ---------------------------------------------------------------------------------------------
// Light paths: power.

constexpr float kFloorHalf = 2.0f;   // the floor is [-2, 2]^2 at y = 0
constexpr float kFloorAlbedo = 0.5f; // white

struct PowerCase {
    const char* name;
    std::function<void(SceneBuilder&)> addLight;
    double powerOnFloor; // W reaching the floor (both sides), per channel
};

std::vector<PowerCase> powerCases() {
    const double half = kFloorHalf;
    std::vector<PowerCase> cases;
    {
        // Point light I at height h: I x the solid angle of the square,
        // 4 asin(a^2 / (a^2 + h^2)).
        const double intensity = 3.0, h = 1.0;
        cases.push_back({"point",
                         [=](SceneBuilder& b) {
                             b.light(pointLight(glm::vec3(0.0f, float(h), 0.0f), float(intensity)));
                         },
                         intensity * 4.0 * std::asin(half * half / (half * half + h * h))});
    }
    {
        // Spot light pointing down (outer cone 50 degrees at 1.5 m: the ramp reaches past the
        // floor's edge on one side). Reference: normalIrradianceAt x cos over the
        // floor, the falloff the path method uses.
        PunctualLight spot = pointLight(glm::vec3(0.3f, 1.5f, -0.2f), 5.0f);
        spot.type = LightType::Spot;
        spot.direction = glm::vec3(0.0f, -1.0f, 0.0f);
        spot.innerConeCos = std::cos(glm::radians(20.0f));
        spot.outerConeCos = std::cos(glm::radians(50.0f));
        const double power = integrateSquare(half, 64, [&](double x, double z) {
            const glm::vec3 p(float(x), 0.0f, float(z));
            const glm::vec3 to_light = spot.position - p;
            return double(normalIrradianceAt(spot, p).x) * double(to_light.y) /
                   double(glm::length(to_light));
        });
        cases.push_back({"spot", [=](SceneBuilder& b) { b.light(spot); }, power});
    }
    {
        // Directional light E straight down: E x the floor's area.
        PunctualLight sun;
        sun.type = LightType::Directional;
        sun.direction = glm::vec3(0.0f, -1.0f, 0.0f);
        sun.intensity = glm::vec3(2.0f);
        cases.push_back(
            {"directional", [=](SceneBuilder& b) { b.light(sun); }, 2.0 * 4.0 * half * half});
    }
    {
        // Constant sky L all around: pi L per unit area on each side.
        const double radiance = 0.7;
        cases.push_back({"environment",
                         [=](SceneBuilder& b) { b.environment(glm::vec3(float(radiance))); },
                         2.0 * kPi * radiance * 4.0 * half * half});
    }
    {
        // A 0.2 m emissive square facing down at 0.5 m: its lower side sends pi L x area x the
        // view factor to the floor (integrated over the emitter); its upper side escapes.
        const double radiance = 4.0, side = 0.2, h = 0.5;
        const double reaching = integrateSquare(0.5 * side, 2, [&](double x, double z) {
            return kPi * radiance * squareViewFactor(half, x, z, h);
        });
        cases.push_back({"emitter",
                         [=](SceneBuilder& b) {
                             b.quad(glm::vec3(float(-0.5 * side), float(h), float(-0.5 * side)),
                                    glm::vec3(float(side), 0.0f, 0.0f),
                                    glm::vec3(0.0f, 0.0f, float(side)),
                                    glm::vec3(0.0f, -1.0f, 0.0f),
                                    b.material(glm::vec3(0.0f), glm::vec3(float(radiance))));
                         },
                         reaching});
    }
    {
        // Two lights at once: choosing by power keeps every path's flux equal.
        const double intensity = 3.0, h = 1.0;
        PunctualLight sun;
        sun.type = LightType::Directional;
        sun.direction = glm::vec3(0.0f, -1.0f, 0.0f);
        sun.intensity = glm::vec3(0.25f);
        // The point light is off-centre: I h / r^3 integrated over the floor.
        const double point = integrateSquare(half, 64, [&](double x, double z) {
            const double dx = x - 0.5, r2 = dx * dx + z * z + h * h;
            return intensity * h / (r2 * std::sqrt(r2));
        });
        cases.push_back({"point+directional",
                         [=](SceneBuilder& b) {
                             b.light(pointLight(glm::vec3(0.5f, float(h), 0.0f), float(intensity)));
                             b.light(sun);
                         },
                         point + 0.25 * 4.0 * half * half});
    }
    return cases;
}

Scene floorScene(const PowerCase& c) {
    SceneBuilder b;
    b.quad(glm::vec3(-kFloorHalf, 0.0f, -kFloorHalf), glm::vec3(2.0f * kFloorHalf, 0.0f, 0.0f),
           glm::vec3(0.0f, 0.0f, 2.0f * kFloorHalf), glm::vec3(0.0f, 1.0f, 0.0f),
           b.material(glm::vec3(kFloorAlbedo)));
    c.addLight(b);
    return b.finish();
}

// Total VPL flux = albedo x power reaching the floor, for every kind of light; and the set
// holds about `count` VPLs (the pilot's estimate of hits per path has relative standard
// deviation sqrt((1 - p) / (pilot paths x p))).
TEST(VplPaths, TotalFluxIsAlbedoTimesPowerReachingTheFloor) {
    constexpr uint32_t kCount = 16384;
    for (const PowerCase& c : powerCases()) {
        const Scene scene = floorScene(c);
        const auto tracer = tracerFor(scene);
        ASSERT_TRUE(tracer);
        for (const VplSampling sampling : {VplSampling::Random, VplSampling::Stratified}) {
            VplConfig settings;
            settings.bounces = 1;
            settings.sampling = sampling;
            const VplSet set = traceVpls(scene, *tracer, kCount, settings, 3);
            double flux = 0.0;
            for (const Vpl& v : set.vpls) {
                flux += kPi * double(v.intensity.x); // intensity = albedo x flux / pi
            }
            const double expected = double(kFloorAlbedo) * c.powerOnFloor;
            const double hits = double(set.vpls.size());
            ASSERT_GT(hits, 0.0) << c.name;
            const double tolerance = kSigmas * expected / std::sqrt(hits);
            std::printf("[vpl power] %-18s %-10s %6zu VPLs from %7llu paths: flux %.5f, "
                        "expected %.5f (%+.3f%%, tolerance %.2f%%)\n",
                        c.name, std::string(toString(sampling)).c_str(), set.vpls.size(),
                        static_cast<unsigned long long>(set.lightPaths), flux, expected,
                        100.0 * (flux / expected - 1.0), 100.0 * tolerance / expected);
            EXPECT_NEAR(flux, expected, tolerance) << c.name << " " << toString(sampling);

            const double p = hits / double(set.lightPaths);
            const double pilot_sigma = std::sqrt((1.0 - p) / (double(kVplPilotPaths) * p));
            EXPECT_NEAR(hits / kCount, 1.0, kSigmas * (pilot_sigma + 1.0 / std::sqrt(hits)))
                << c.name;
        }
    }
}

// Every path leaves at most `bounces` VPLs; in a closed white box (albedo a) with Russian
// roulette a path leaves 1 / (1 - a) on average, and the flux of generation k is a^(k-1) times
// the first's.
TEST(VplPaths, BouncesCapGenerationsAndRussianRouletteKeepsEnergy) {
    SceneBuilder b;
    constexpr float kAlbedo = 0.6f;
    b.box(glm::vec3(-1.0f), glm::vec3(1.0f), true, b.material(glm::vec3(kAlbedo)));
    b.light(pointLight(glm::vec3(0.1f, 0.2f, -0.1f), 1.0f));
    const Scene scene = b.finish();
    const auto tracer = tracerFor(scene);
    ASSERT_TRUE(tracer);
    VplConfig settings;
    double flux_one = 0.0;
    for (const uint32_t bounces : {1u, 64u}) {
        settings.bounces = bounces;
        const VplSet set = traceVpls(scene, *tracer, 16384, settings, 5);
        double flux = 0.0;
        for (const Vpl& v : set.vpls) {
            flux += kPi * double(v.intensity.x);
        }
        const double per_path = double(set.vpls.size()) / double(set.lightPaths);
        std::printf("[vpl bounces] %2u: %.3f VPLs per path, reflected flux %.4f W\n", bounces,
                    per_path, flux);
        if (bounces == 1) {
            // Every path hits the closed box once: exactly one VPL each, flux a x 4 pi I.
            EXPECT_EQ(set.vpls.size(), set.lightPaths);
            EXPECT_NEAR(flux, kAlbedo * 4.0 * kPi, 1e-4 * flux);
            flux_one = flux;
        } else {
            // Reflected flux over all generations: a 4 pi I (1 + a + a^2 + ...) = flux_one /
            // (1 - a). Each path's generation count is geometric; kSigmas standard errors of
            // the mean of 1 / (1 - a) with variance a / (1 - a)^2 per path.
            const double n = double(set.lightPaths);
            const double mean = 1.0 / (1.0 - kAlbedo);
            const double sigma = std::sqrt(kAlbedo) / (1.0 - kAlbedo) / std::sqrt(n);
            EXPECT_NEAR(per_path, mean, kSigmas * sigma);
            EXPECT_NEAR(flux, flux_one / (1.0 - kAlbedo), kSigmas * sigma * flux_one);
        }
    }
}

// Jittered: each of the first dimensions puts exactly one path in each of its N strata.
// Stratified: the first b^k points of a dimension of base b fall in distinct intervals of
// width b^-k (Halton's stratification survives the nested digit scramble).
TEST(VplPaths, SamplersStratifyEveryDimension) {
    constexpr uint32_t kJittered = 1000;
    const VplPathSampler jittered(VplSampling::Jittered, 11, kJittered);
    std::array<std::vector<int>, kVplPathDimensions> seen;
    for (auto& s : seen) {
        s.assign(kJittered, 0);
    }
    for (uint32_t i = 0; i < kJittered; ++i) {
        const auto u = jittered(i);
        for (int d = 0; d < kVplPathDimensions; ++d) {
            ASSERT_GE(u[d], 0.0);
            ASSERT_LT(u[d], 1.0);
            seen[d][size_t(u[d] * kJittered)] += 1;
        }
    }
    for (int d = 0; d < kVplPathDimensions; ++d) {
        EXPECT_EQ(std::count(seen[d].begin(), seen[d].end(), 1), int(kJittered)) << "dim " << d;
    }

    const std::array<uint32_t, kVplPathDimensions> bases = {2, 3, 5, 7, 11, 13, 17};
    for (const uint64_t seed : {1ull, 99ull}) {
        const VplPathSampler stratified(VplSampling::Stratified, seed, 4096);
        for (int d = 0; d < kVplPathDimensions; ++d) {
            uint32_t n = 1;
            while (n * bases[d] <= 2048) {
                n *= bases[d];
            }
            std::vector<int> cells(n, 0);
            for (uint32_t i = 0; i < n; ++i) {
                const double u = stratified(i)[d];
                ASSERT_GE(u, 0.0);
                ASSERT_LT(u, 1.0);
                cells[size_t(u * n)] += 1;
            }
            EXPECT_EQ(std::count(cells.begin(), cells.end(), 1), int(n))
                << "dim " << d << ", seed " << seed;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Gather: a floor lit by a point light.

using ShDouble = std::array<glm::dvec3, sh::kMaxCoefficients>;

// The probe's radiance SH from the floor lit by a point light I at `light`: floor radiance
// (albedo / pi) I h / r^3, integrated against Y over the floor.
ShDouble floorSh(glm::dvec3 probe, glm::dvec3 light, double intensity, double albedo) {
    ShDouble out{};
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        out[i].x = integrateSquare(kFloorHalf, 48, [&](double x, double z) {
            const glm::dvec3 p(x, 0.0, z);
            const glm::dvec3 to_light = light - p;
            const double r2 = glm::dot(to_light, to_light);
            const double radiance = albedo / kPi * intensity * to_light.y / (r2 * std::sqrt(r2));
            const glm::dvec3 to_floor = p - probe;
            const double d2 = glm::dot(to_floor, to_floor);
            const double solid_angle = probe.y / (d2 * std::sqrt(d2)); // per unit area
            const sh::Coeffs y = sh::evalBasis(glm::vec3(glm::normalize(to_floor)));
            return radiance * solid_angle * double(y[i]);
        });
        out[i].y = out[i].z = out[i].x;
    }
    return out;
}

// The VPLs' SH at the probe (light reflected once by the floor; the point light's own delta is
// the path integrator's) matches the quadrature: unclamped, every VPL gathered, independent
// sets per seed.
TEST(VplFloor, IndirectIrradianceMatchesQuadrature) {
    const glm::vec3 light(0.4f, 1.0f, 0.0f);
    constexpr float kIntensity = 3.0f;
    SceneBuilder b;
    b.quad(glm::vec3(-kFloorHalf, 0.0f, -kFloorHalf), glm::vec3(2.0f * kFloorHalf, 0.0f, 0.0f),
           glm::vec3(0.0f, 0.0f, 2.0f * kFloorHalf), glm::vec3(0.0f, 1.0f, 0.0f),
           b.material(glm::vec3(kFloorAlbedo)));
    b.light(pointLight(light, kIntensity));
    const Scene scene = b.finish();
    const auto tracer = tracerFor(scene);
    ASSERT_TRUE(tracer);

    const glm::vec3 probe(-0.3f, 0.5f, 0.2f);
    const ShDouble reference =
        floorSh(glm::dvec3(probe), glm::dvec3(light), kIntensity, kFloorAlbedo);
    VplConfig gather;
    gather.clamp = VplClamp::None;
    gather.cutError = 0.0f;
    std::vector<sh::ShRgb> estimates;
    for (int seed = 0; seed < kSeeds; ++seed) {
        VplSet set = traceVpls(scene, *tracer, 4096, VplConfig{}, uint64_t(100 + seed));
        const VplGatherer gatherer(std::move(set.vpls), *tracer, gather, uint64_t(seed));
        estimates.push_back(gatherer.gather(probe, sh::Order::L2, sh::ShRgb{}).sh);
    }
    double largest = 0.0;
    for (const glm::dvec3& r : reference) {
        largest = std::max(largest, std::abs(r.x));
    }
    std::string log;
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        double mean = 0.0, square = 0.0;
        for (const sh::ShRgb& e : estimates) {
            mean += e.rgb[i].x / kSeeds;
        }
        for (const sh::ShRgb& e : estimates) {
            square += (e.rgb[i].x - mean) * (e.rgb[i].x - mean);
        }
        const double standard_error = std::sqrt(square / (kSeeds - 1) / kSeeds);
        const double tolerance = kSigmas * standard_error + kFloatSlack * largest;
        log += "coefficient " + std::to_string(i) + ": mean " + std::to_string(mean) +
               " reference " + std::to_string(reference[i].x) + " stderr " +
               std::to_string(standard_error) + "\n";
        EXPECT_NEAR(mean, reference[i].x, tolerance) << "coefficient " << i;
    }
    if (HasFailure()) {
        writeFailure("floor_indirect", log);
    }
}

// ---------------------------------------------------------------------------------------------
// A room (4 x 2.5 x 4 m, albedo 0.6, a red wall) with a block and a point light. Its probes:
// an 8 x 4 x 8 centre-mode grid (as `resolution: [8, 4, 8]` places them: the outer probes
// 0.25 m from the walls, 0.31 m from floor and ceiling), those inside the block left out,
// and one probe 5 cm from a floor corner (last). The path method is the reference.

const glm::vec3 kRoomMin(0.0f), kRoomMax(4.0f, 2.5f, 4.0f);
const glm::vec3 kBlockMin(2.4f, 0.0f, 0.6f), kBlockMax(3.4f, 1.2f, 1.6f);
const glm::vec3 kCorner(0.05f, 0.05f, 0.05f);

Scene roomScene() {
    SceneBuilder b;
    b.box(kRoomMin, kRoomMax, true, b.material(glm::vec3(0.6f)));
    // A red wall inside the x = 4 wall, so that colour bleeding shows in the SH.
    b.quad(glm::vec3(3.99f, 0.0f, 0.0f), glm::vec3(0.0f, 2.5f, 0.0f), glm::vec3(0.0f, 0.0f, 4.0f),
           glm::vec3(-1.0f, 0.0f, 0.0f), b.material(glm::vec3(0.7f, 0.15f, 0.1f)));
    b.box(kBlockMin, kBlockMax, false, b.material(glm::vec3(0.5f)));
    b.light(pointLight(glm::vec3(1.6f, 2.2f, 2.3f), 8.0f));
    return b.finish();
}

// One 1 x 1 x 1 volume per point, so each probe sits exactly at its point; no dilation.
BakeConfig probesAt(const std::vector<glm::vec3>& points) {
    BakeConfig c = test::probesAt(points, 0.02f);
    c.dilate = false;
    return c;
}

// E_L2 (luminance) of every probe at 64 Fibonacci normals: [probe][normal].
std::vector<std::vector<double>> probeIrradiance(const BakeResult& r) {
    std::vector<std::vector<double>> out;
    for (const Volume& v : r.file.volumes) {
        std::vector<double> row;
        for (int k = 0; k < 64; ++k) {
            const glm::vec3 e =
                sh::irradiance(v.probe(0), sh::Order::L2, sh::fibonacciDirection(k, 64));
            row.push_back(0.2126 * e.x + 0.7152 * e.y + 0.0722 * e.z);
        }
        out.push_back(row);
    }
    return out;
}

// Relative RMS difference of one probe's row, and of all rows together.
double relRms(const std::vector<double>& a, const std::vector<double>& b) {
    double num = 0.0, den = 0.0;
    for (size_t k = 0; k < a.size(); ++k) {
        num += (a[k] - b[k]) * (a[k] - b[k]);
        den += b[k] * b[k];
    }
    return std::sqrt(num / den);
}
double relRms(const std::vector<std::vector<double>>& a,
              const std::vector<std::vector<double>>& b) {
    double num = 0.0, den = 0.0;
    for (size_t p = 0; p < a.size(); ++p) {
        for (size_t k = 0; k < a[p].size(); ++k) {
            num += (a[p][k] - b[p][k]) * (a[p][k] - b[p][k]);
            den += b[p][k] * b[p][k];
        }
    }
    return std::sqrt(num / den);
}

class VplRoom : public ::testing::Test {
protected:
    // Path samples per probe for the reference. Its noise (measured from two seeds, printed)
    // must stay well below the VPL errors it judges: kReferenceNoiseBound is a quarter of the
    // smallest VPL error asserted on (kConvergedError).
    static constexpr uint32_t kReferenceSamples = 8192;
    static constexpr double kReferenceNoiseBound = 0.005;

    static void SetUpTestSuite() {
        s_scene = new Scene(roomScene());
        s_points = new std::vector<glm::vec3>();
        for (int i = 0; i < 8; ++i) {
            for (int j = 0; j < 4; ++j) {
                for (int k = 0; k < 8; ++k) {
                    const glm::vec3 p(0.25f + 0.5f * float(i), 0.3125f + 0.625f * float(j),
                                      0.25f + 0.5f * float(k));
                    if (!(glm::all(glm::greaterThan(p, kBlockMin)) &&
                          glm::all(glm::lessThan(p, kBlockMax)))) {
                        s_points->push_back(p);
                    }
                }
            }
        }
        s_points->push_back(kCorner);
        BakeConfig c = probesAt(*s_points);
        c.path.samples = kReferenceSamples;
        c.path.maxBounces = 64;
        Result<BakeResult> a = bake(*s_scene, c);
        c.seed = 2;
        Result<BakeResult> b = bake(*s_scene, c);
        ASSERT_TRUE(a.ok() && b.ok());
        s_reference = new std::vector<std::vector<double>>(probeIrradiance(a.value()));
        // One bake's noise from the difference of two: rms(a - b) / sqrt(2).
        s_referenceNoise = relRms(probeIrradiance(b.value()), *s_reference) / std::sqrt(2.0);
        std::printf("[vpl room] %zu probes; path reference at %u samples: noise %.4f, %.2f s\n",
                    s_points->size(), kReferenceSamples, s_referenceNoise, a.value().stats.seconds);
    }
    static void TearDownTestSuite() {
        delete s_scene;
        delete s_points;
        delete s_reference;
    }

    static std::vector<std::vector<double>> bakeVpl(const VplConfig& vpl, uint64_t seed) {
        BakeConfig c = probesAt(*s_points);
        c.method = Method::Vpl;
        c.vpl = vpl;
        c.seed = seed;
        Result<BakeResult> r = bake(*s_scene, c);
        EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
        return r.ok() ? probeIrradiance(r.value()) : std::vector<std::vector<double>>{};
    }

    struct Errors {
        double corner = 0.0;  // the corner probe's rel RMSE
        double average = 0.0; // mean over probes of their rel RMSE
        double worst = 0.0;   // largest single-probe rel RMSE
        double bias = 0.0;    // mean(E - E_reference) / mean(E_reference)
    };
    static Errors errorsOf(const std::vector<std::vector<double>>& e) {
        Errors out;
        double diff = 0.0, mean = 0.0;
        for (size_t p = 0; p < e.size(); ++p) {
            const double error = relRms(e[p], (*s_reference)[p]);
            out.worst = std::max(out.worst, error);
            out.average += error / double(e.size());
            for (size_t k = 0; k < e[p].size(); ++k) {
                diff += e[p][k] - (*s_reference)[p][k];
                mean += (*s_reference)[p][k];
            }
        }
        out.corner = relRms(e.back(), s_reference->back());
        out.bias = diff / mean;
        return out;
    }

    static Scene* s_scene;
    static std::vector<glm::vec3>* s_points;
    static std::vector<std::vector<double>>* s_reference;
    static double s_referenceNoise;
};
Scene* VplRoom::s_scene = nullptr;
std::vector<glm::vec3>* VplRoom::s_points = nullptr;
std::vector<std::vector<double>>* VplRoom::s_reference = nullptr;
double VplRoom::s_referenceNoise = 0.0;

TEST_F(VplRoom, ReferenceIsQuietEnoughToJudge) {
    EXPECT_LT(s_referenceNoise, kReferenceNoiseBound);
}

// More VPLs, less error: at 256, 4096 and 16384 VPLs, the VPLs' error against the path
// reference falls, and at 16384 it is below kConvergedError. The near field is off (by
// default it grows as the count shrinks, handing the light to paths) and the corner probe
// left out (the next test is about it), so this is the VPLs' own convergence.
TEST_F(VplRoom, ErrorFallsAsTheCountGrows) {
    // Measured 0.87% at 16384 (seed 1); the bound leaves room for another seed, the
    // reference's noise (0.4%) and the lightcut's error.
    constexpr double kConvergedError = 0.02;
    std::vector<double> errors;
    for (const uint32_t count : {256u, 4096u, 16384u}) {
        VplConfig vpl;
        vpl.count = count;
        vpl.nearField = 0.0f;
        auto e = bakeVpl(vpl, 1);
        ASSERT_EQ(e.size(), s_points->size());
        e.pop_back();
        const std::vector<std::vector<double>> reference(s_reference->begin(),
                                                         s_reference->end() - 1);
        errors.push_back(relRms(e, reference));
        std::printf("[vpl room] %5u VPLs: rel RMSE of E_L2 vs path %.4f\n", count, errors.back());
    }
    EXPECT_GT(errors[0], errors[1]);
    EXPECT_GT(errors[1], errors[2]);
    EXPECT_LT(errors[2], kConvergedError);
}

// The corner probe (5 cm from the floor and two walls) sees VPLs a few centimetres away:
// without clamping their 1 / d^2 makes it the worst probe by far. Prints, for each clamp
// alone (near field off) and with the default near field, the corner's error, the largest
// single-probe error, the scene average, and the clamping bias (mean of E_clamp - E_none over
// probes and normals for the same VPL sets, relative to the mean E: E_none is unbiased, so
// this is the clamp's bias; with the near field, the bias against the path reference). With the
// default settings (spherical clamp, near field) the corner must stay within 2x of the
// scene-average error.
TEST_F(VplRoom, SphericalClampKeepsTheCornerSpikeNearTheAverage) {
    constexpr int kCornerSeeds = 2;
    constexpr uint32_t kCount = 16384;
    double default_corner = 0.0, default_average = 0.0;
    for (const bool near_field : {false, true}) {
        std::vector<std::vector<std::vector<double>>> unclamped;
        for (const VplClamp clamp : {VplClamp::None, VplClamp::Distance, VplClamp::Spherical}) {
            if (near_field && clamp != VplClamp::Spherical) {
                continue; // with the near field, clamps hardly matter: the default only
            }
            Errors sum;
            double clamp_bias = 0.0;
            for (int seed = 1; seed <= kCornerSeeds; ++seed) {
                VplConfig vpl;
                vpl.count = kCount;
                vpl.clamp = clamp;
                if (!near_field) {
                    vpl.nearField = 0.0f;
                }
                const auto e = bakeVpl(vpl, uint64_t(seed));
                ASSERT_EQ(e.size(), s_points->size());
                if (clamp == VplClamp::None) {
                    unclamped.push_back(e);
                }
                const Errors one = errorsOf(e);
                sum.corner += one.corner / kCornerSeeds;
                sum.average += one.average / kCornerSeeds;
                sum.worst = std::max(sum.worst, one.worst);
                // Without the near field: the bias against the unclamped gather of the same
                // VPLs; with it (no unclamped run): against the path reference.
                const double baseline =
                    unclamped.empty() ? 0.0 : errorsOf(unclamped[size_t(seed - 1)]).bias;
                clamp_bias += (one.bias - baseline) / kCornerSeeds;
            }
            std::printf("[vpl corner] near field %-3s clamp %-9s corner error %.4f, worst probe "
                        "%.4f, scene average %.4f, bias %+.5f vs %s (%u VPLs, %d seeds)\n",
                        near_field ? "on" : "off", std::string(toString(clamp)).c_str(), sum.corner,
                        sum.worst, sum.average, clamp_bias, near_field ? "path" : "none", kCount,
                        kCornerSeeds);
            if (near_field && clamp == VplClamp::Spherical) {
                default_corner = sum.corner;
                default_average = sum.average;
            }
        }
    }
    EXPECT_LE(default_corner, 2.0 * default_average);
}

// The lightcut's stated bound: on the same VPLs, |E_L2(n)_cut - E_L2(n)_all| <= 1.11 x the
// sum of the cut's cluster bounds, for every normal, with and without visibility.
TEST_F(VplRoom, LightcutErrorStaysWithinItsBound) {
    const auto tracer = tracerFor(*s_scene);
    ASSERT_TRUE(tracer);
    const VplSet set = traceVpls(*s_scene, *tracer, 16384, VplConfig{}, 9);
    for (const bool shadows : {true, false}) {
        VplConfig settings;
        settings.clampDistance = 0.05f;
        settings.shadows = shadows;
        const VplGatherer cut(set.vpls, *tracer, settings, 9);
        settings.cutError = 0.0f;
        const VplGatherer all(set.vpls, *tracer, settings, 9);
        double worst_ratio = 0.0, cut_sizes = 0.0, rel_num = 0.0, rel_den = 0.0;
        for (const glm::vec3& p : *s_points) {
            const VplGatherResult a = cut.gather(p, sh::Order::L2, sh::ShRgb{});
            const VplGatherResult b = all.gather(p, sh::Order::L2, sh::ShRgb{});
            cut_sizes += a.cutSize;
            for (int k = 0; k < 64; ++k) {
                const glm::vec3 n = sh::fibonacciDirection(k, 64);
                const glm::vec3 ea = sh::irradiance(a.sh, sh::Order::L2, n);
                const glm::vec3 eb = sh::irradiance(b.sh, sh::Order::L2, n);
                const double la = 0.2126 * ea.x + 0.7152 * ea.y + 0.0722 * ea.z;
                const double lb = 0.2126 * eb.x + 0.7152 * eb.y + 0.0722 * eb.z;
                // Float rounding of the sums: far below any cluster's bound.
                const double bound = 1.11 * double(a.errorBound) + 1e-4 * std::abs(lb);
                EXPECT_LE(std::abs(la - lb), bound)
                    << "probe " << p.x << " " << p.y << " " << p.z << ", normal " << k;
                worst_ratio = std::max(worst_ratio, std::abs(la - lb) / bound);
                rel_num += (la - lb) * (la - lb);
                rel_den += lb * lb;
            }
        }
        std::printf("[vpl lightcut] shadows %-3s: %.0f clusters per probe (of %zu VPLs), rel "
                    "RMS difference to gathering all %.4f, largest error / bound %.3f\n",
                    shadows ? "on" : "off", cut_sizes / double(s_points->size()), set.vpls.size(),
                    std::sqrt(rel_num / rel_den), worst_ratio);
    }
}

// ---------------------------------------------------------------------------------------------
// Bakes: determinism, config.

TEST(VplBake, BitIdenticalForOneAndTwoThreadsAndRecordsResolvedSettings) {
    const Scene scene = test::generatedScene("cornell");
    BakeConfig c = test::methodVolume(Method::Vpl, glm::uvec3(4, 4, 2));
    c.vpl.count = 4096;
    auto [a, b] = test::bakeOnOneAndTwoThreads(scene, c);
    ASSERT_TRUE(a.ok() && b.ok());
    test::expectSameFileButTiming(a.value(), b.value());
    EXPECT_GT(a.value().stats.vpls, 0u);
    EXPECT_GT(a.value().stats.vplMeanCut, 0.0);

    // The metadata records what was baked: the count and the clamp distance chosen.
    const std::string& json = a.value().file.metadata.parametersJson;
    EXPECT_NE(json.find("\"count\":4096"), std::string::npos) << json;
    EXPECT_NE(json.find("\"clamp\":\"spherical\""), std::string::npos) << json;
    EXPECT_EQ(json.find("\"clamp_distance\":\"auto\""), std::string::npos) << json;
    EXPECT_EQ(json.find("\"near_field\":\"auto\""), std::string::npos) << json;

    test::expectOtherSeedChangesTexels(scene, c, a.value());
}

// The automatic count: 4 x area / spacing^2 as a power of two in 16384..65536.
TEST(VplBake, AutomaticCountFollowsAreaAndProbeSpacing) {
    Scene scene;
    // One 10 m x 10 m quad: 100 m^2.
    SceneBuilder b;
    b.quad(glm::vec3(0.0f), glm::vec3(10.0f, 0.0f, 0.0f), glm::vec3(0.0f, 0.0f, 10.0f),
           glm::vec3(0.0f, 1.0f, 0.0f), 0);
    scene = b.finish();
    BakeConfig c;
    VolumeConfig v;
    v.bounds.mode = BoundsMode::Custom;
    v.bounds.min = glm::vec3(0.0f);
    v.bounds.max = glm::vec3(10.0f, 2.0f, 10.0f);
    // The smallest spacing is y's, 2 m / res: 4 x 100 / (2 / res)^2 = 100 res^2 wanted.
    for (const auto& [resolution, expected] :
         std::vector<std::pair<uint32_t, uint32_t>>{{4, 16384},   // 1600: the floor
                                                    {16, 32768},  // 25600: the next power of two
                                                    {32, 65536}}) // 102400: the cap
    {
        v.resolution = glm::uvec3(resolution);
        c.volumes = {v};
        Result<std::vector<VolumeDesc>> descs = resolveVolumes(scene, c);
        ASSERT_TRUE(descs.ok());
        const VplConfig r = resolveVplConfig(scene, descs.value(), c);
        EXPECT_EQ(*r.count, expected) << "resolution " << resolution;
        EXPECT_NEAR(*r.clampDistance, 2.0 * std::sqrt(100.0 / (kPi * expected)), 1e-5);
        EXPECT_EQ(*r.nearField, 2.0f * *r.clampDistance);
    }
    c.vpl.count = 1000;
    c.vpl.clampDistance = 0.3f;
    const VplConfig kept = resolveVplConfig(scene, resolveVolumes(scene, c).value(), c);
    EXPECT_EQ(*kept.count, 1000u);
    EXPECT_EQ(*kept.clampDistance, 0.3f);
}

TEST(VplConfig, ParsesTheSection) {
    const char* text = R"({"method": "vpl",
      "vpl": {"count": 8192, "bounces": 1, "direct_samples": 64, "sampling": "jittered",
              "clamp": "distance", "clamp_distance": 0.05, "near_field": 0, "shadows": "off",
              "cut_error": 0}})";
    Result<BakeConfig> c = parseBakeConfig(text, "bake.json");
    ASSERT_TRUE(c.ok()) << c.error().message;
    const VplConfig& v = c.value().vpl;
    EXPECT_EQ(c.value().method, Method::Vpl);
    EXPECT_EQ(*v.count, 8192u);
    EXPECT_EQ(v.bounces, 1u);
    EXPECT_EQ(v.directSamples, 64u);
    EXPECT_EQ(v.sampling, VplSampling::Jittered);
    EXPECT_EQ(v.clamp, VplClamp::Distance);
    EXPECT_EQ(*v.clampDistance, 0.05f);
    EXPECT_EQ(*v.nearField, 0.0f);
    EXPECT_FALSE(v.shadows);
    EXPECT_EQ(v.cutError, 0.0f);

    Result<BakeConfig> autos = parseBakeConfig(
        R"({"vpl": {"count": "auto", "clamp_distance": "auto", "near_field": "auto"}})", "b.json");
    ASSERT_TRUE(autos.ok()) << autos.error().message;
    EXPECT_FALSE(autos.value().vpl.count.has_value());
    EXPECT_FALSE(autos.value().vpl.clampDistance.has_value());
    EXPECT_FALSE(autos.value().vpl.nearField.has_value());
}

TEST(VplConfig, ErrorsNameFileAndField) {
    const test::ConfigErrorCase cases[] = {
        {R"({"vpl": {"cuont": 10}})", "bake.json: vpl.cuont: unknown field"},
        {R"({"vpl": {"count": 0}})", "bake.json: vpl.count: must be in 1.."},
        {R"({"vpl": {"count": "many"}})", "vpl.count: \"many\" is not one of auto"},
        {R"({"vpl": {"count": 1.5}})", "vpl.count: must be a whole number"},
        {R"({"vpl": {"bounces": 0}})", "vpl.bounces"},
        {R"({"vpl": {"direct_samples": 0}})", "vpl.direct_samples"},
        {R"({"vpl": {"sampling": "sobol"}})", "vpl.sampling: \"sobol\" is not one of random"},
        {R"({"vpl": {"clamp": "sphere"}})", "vpl.clamp: \"sphere\" is not one of none"},
        {R"({"vpl": {"clamp_distance": -0.1}})", "vpl.clamp_distance: must be > 0"},
        {R"({"vpl": {"near_field": -1}})", "vpl.near_field: must be >= 0"},
        {R"({"vpl": {"near_field": "far"}})", "vpl.near_field: \"far\" is not one of auto"},
        {R"({"vpl": {"shadows": true}})", "vpl.shadows: must be a string"},
        {R"({"vpl": {"shadows": "yes"}})", "vpl.shadows: \"yes\" is not one of on, off"},
        {R"({"vpl": {"cut_error": 1.5}})", "vpl.cut_error: must be in [0, 1)"},
        {R"({"vpl": []})", "vpl: must be a JSON object"},
        {R"({"method": "photon"})", "method: \"photon\" is not one of path, vpl"},
    };
    test::expectConfigErrors(cases);
}

} // namespace
} // namespace probekit::baker
