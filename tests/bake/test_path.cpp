// Tests of the Embree ray tracer, the path-traced SH probe reference and bench-rays.
//
// The integrator is the accuracy reference of the project, so it is tested against scenes with
// known answers (pbrt-v4 style), statistically (Mitsuba style):
//
//  * Each Monte Carlo check bakes kProbes independent probes at the same position (different
//    probe_index, hence independent Sobol scrambles and path streams) and compares the mean with
//    the exact answer. The tolerance is kSigmas standard errors of that mean, the standard error
//    estimated from the spread of the kProbes estimates themselves (s / sqrt(kProbes)): the
//    variance of stratified, multi-bounce estimators has no convenient closed form, and this
//    estimate needs none. With kProbes = 16 the normalised error follows Student's t with 15
//    degrees of freedom, for which |t| > 5 has probability 1.6e-4: a correct integrator fails
//    a given check about once in 6000 seeds, while a bias of a few standard errors fails it.
//    Since every seed is fixed, each check is deterministic.
//  * Estimators whose samples are all equal have zero spread; kFloatSlack then covers float
//    rounding of the accumulation (N terms of relative error 2^-24 summed in blocks).
//  * Reference values are computed in double: closed forms where they exist (furnace, delta
//    lights, Lambert's polygon formula, solid angles), otherwise Gauss-Legendre quadrature of the
//    exact integrand over smooth pieces (converged far below the tolerances).
//
// A failing statistical check writes its estimates, standard errors and references to
// PROBEKIT_TEST_OUTPUT_DIR so that the failure can be looked at.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include <glm/geometric.hpp>

#include "bake_test_support.hpp"
#include "methods/irradiance_error.hpp"
#include "methods/path_integrator.hpp"
#include "probekit/baker/bench_rays.hpp"
#include "probekit/baker/scene.hpp"
#include "probekit/baker/target.hpp"
#include "probekit/formats/sh.hpp"
#include "trace/light_sampler.hpp"
#include "trace/ray_tracer.hpp"
#include "trace/rng.hpp"

namespace probekit::baker {
namespace {

using namespace test; // kPi, kSigmas, kFloatSlack, kGauss*, emptyScene, addMaterial

// See the file comment for why this number.
constexpr int kProbes = 16;

// Exact-arithmetic checks (delta projections, spot falloff): float evaluation of a handful of
// terms, nothing random.
constexpr double kDeltaRelativeTolerance = 1e-5;

using ShDouble = std::array<glm::dvec3, sh::kMaxCoefficients>;

// ---------------------------------------------------------------------------------------------
// Scene building.

void addTriangle(Scene& scene, glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material) {
    const auto base = uint32_t(scene.positions.size());
    scene.positions.insert(scene.positions.end(), {a, b, c});
    scene.uvs.insert(scene.uvs.end(), 3, glm::vec2(0.0f));
    scene.triangles.push_back(glm::uvec3(base, base + 1, base + 2));
    scene.triangleMaterial.push_back(material);
    scene.triangleNode.push_back(-1);
}

// Quad a b c d (in order around its boundary) as triangles (a, b, c) and (a, c, d): the winding
// normal is (b - a) x (c - a).
void addQuad(Scene& scene, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t material) {
    addTriangle(scene, a, b, c, material);
    addTriangle(scene, a, c, d, material);
}

// Axis-aligned box with outward winding.
void addBox(Scene& scene, glm::vec3 lo, glm::vec3 hi, uint32_t material) {
    const glm::vec3 v[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
                            {lo.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                            {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
    addQuad(scene, v[0], v[3], v[2], v[1], material); // -z
    addQuad(scene, v[4], v[5], v[6], v[7], material); // +z
    addQuad(scene, v[0], v[4], v[7], v[3], material); // -x
    addQuad(scene, v[1], v[2], v[6], v[5], material); // +x
    addQuad(scene, v[0], v[1], v[5], v[4], material); // -y
    addQuad(scene, v[3], v[7], v[6], v[2], material); // +y
}

// Icosphere: an icosahedron with each face split into 4 `subdivisions` times, vertices pushed
// to the sphere; winding made outward face by face.
void addIcosphere(Scene& scene, glm::vec3 centre, float radius, int subdivisions,
                  uint32_t material) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    std::vector<glm::vec3> faces;
    const glm::vec3 ico[12] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                               {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                               {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    const int ico_faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                  {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                  {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                  {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (const auto& f : ico_faces) {
        for (int k = 0; k < 3; ++k) {
            faces.push_back(glm::normalize(ico[f[k]]));
        }
    }
    for (int s = 0; s < subdivisions; ++s) {
        std::vector<glm::vec3> finer;
        for (size_t i = 0; i < faces.size(); i += 3) {
            const glm::vec3 a = faces[i], b = faces[i + 1], c = faces[i + 2];
            const glm::vec3 ab = glm::normalize(a + b), bc = glm::normalize(b + c),
                            ca = glm::normalize(c + a);
            finer.insert(finer.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
        }
        faces = std::move(finer);
    }
    for (size_t i = 0; i < faces.size(); i += 3) {
        glm::vec3 a = faces[i], b = faces[i + 1], c = faces[i + 2];
        if (glm::dot(glm::cross(b - a, c - a), a + b + c) < 0.0f) {
            std::swap(b, c);
        }
        addTriangle(scene, centre + radius * a, centre + radius * b, centre + radius * c, material);
    }
}

// A rectangle origin + s edgeS + t edgeT (s, t in [0, 1]); its winding normal, once added with
// addQuad(polygon()), is edgeS x edgeT.
struct Rectangle {
    glm::dvec3 origin, edgeS, edgeT;
    std::vector<glm::dvec3> polygon() const {
        return {origin, origin + edgeS, origin + edgeS + edgeT, origin + edgeT};
    }
};

void computeBounds(Scene& scene) {
    if (scene.positions.empty()) {
        return;
    }
    scene.bounds.min = scene.bounds.max = scene.positions[0];
    for (const glm::vec3& p : scene.positions) {
        scene.bounds.min = glm::min(scene.bounds.min, p);
        scene.bounds.max = glm::max(scene.bounds.max, p);
    }
}

std::unique_ptr<RayTracer> buildTracer(const Scene& scene) {
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    EXPECT_TRUE(tracer.ok()) << (tracer.ok() ? "" : tracer.error().message);
    return tracer.ok() ? std::move(tracer).value() : nullptr;
}

// The scene's bounds, then its tracer (nullptr, and a failure, when that cannot be built).
std::unique_ptr<RayTracer> boundedTracer(Scene& scene) {
    computeBounds(scene);
    return buildTracer(scene);
}

// The rectangle as one quad of `material`, wound origin, +S, +S+T, +T.
void addRectangle(Scene& scene, const Rectangle& r, uint32_t material) {
    const auto p = r.polygon();
    addQuad(scene, glm::vec3(p[0]), glm::vec3(p[1]), glm::vec3(p[2]), glm::vec3(p[3]), material);
}

// A 10 x 10 m floor of `albedo` (no emission) centred under the origin; its rectangle.
Rectangle addWideFloor(Scene& scene, double albedo) {
    const Rectangle floor{{-5.0, 0.0, -5.0}, {0.0, 0.0, 10.0}, {10.0, 0.0, 0.0}};
    addRectangle(scene, floor, addMaterial(scene, glm::vec3(float(albedo)), glm::vec3(0.0f)));
    return floor;
}

// The mean of independent values and its standard error (from the sample variance).
struct MeanAndError {
    double mean;
    double standardError;
};

MeanAndError meanAndStandardError(const std::vector<double>& values) {
    double mean = 0.0, variance = 0.0;
    for (double v : values) {
        mean += v / values.size();
    }
    for (double v : values) {
        variance += (v - mean) * (v - mean) / (values.size() - 1);
    }
    return {mean, std::sqrt(variance / values.size())};
}

// Sum over the pixels of a lat-long image of texel x the pixel's exact solid angle.
glm::dvec3 pixelSum(const Image& image) {
    glm::dvec3 sum(0.0);
    for (uint32_t y = 0; y < image.height; ++y) {
        const double solid_angle =
            2.0 * kPi / image.width *
            (std::cos(kPi * y / image.height) - std::cos(kPi * (y + 1) / image.height));
        for (uint32_t x = 0; x < image.width; ++x) {
            sum += glm::dvec3(image.texels[size_t(y) * image.width + x]) * solid_angle;
        }
    }
    return sum;
}

// A lat-long image given by a function of the texel centre's world direction (before rotation).
Image latLongImage(uint32_t width, uint32_t height,
                   const std::function<glm::vec3(glm::dvec3, uint32_t, uint32_t)>& texel) {
    Image image;
    image.width = width;
    image.height = height;
    image.texels.resize(size_t(width) * height);
    for (uint32_t y = 0; y < height; ++y) {
        for (uint32_t x = 0; x < width; ++x) {
            const double phi = 2.0 * kPi * (x + 0.5) / width;
            const double theta = kPi * (y + 0.5) / height;
            const glm::dvec3 dir(std::sin(theta) * std::sin(phi), std::cos(theta),
                                 -std::sin(theta) * std::cos(phi));
            image.texels[size_t(y) * width + x] = glm::vec4(texel(dir, x, y), 1.0f);
        }
    }
    return image;
}

// ---------------------------------------------------------------------------------------------
// References.

std::array<double, sh::kMaxCoefficients> basis(glm::dvec3 d) {
    const sh::Coeffs y = sh::evalBasis(glm::vec3(glm::normalize(d)));
    std::array<double, sh::kMaxCoefficients> out{};
    for (int i = 0; i < sh::kMaxCoefficients; ++i) {
        out[i] = y[i];
    }
    return out;
}

// Integral of f over [a, b], split into `pieces` equal parts with 8 Gauss points each.
double integrate1d(const std::function<double(double)>& f, double a, double b, int pieces) {
    double sum = 0.0;
    const double h = (b - a) / pieces;
    for (int p = 0; p < pieces; ++p) {
        const double mid = a + (p + 0.5) * h;
        for (int k = 0; k < 8; ++k) {
            sum += kGaussWeights[k] * 0.5 * h * f(mid + 0.5 * h * kGaussNodes[k]);
        }
    }
    return sum;
}

// Radiance SH of a planar rectangle r(s, t) = origin + s edge_s + t edge_t (s, t in [0, 1]) of
// radiance L(x) seen from `probe`: the integral of L(x) Y(w) cos / r^2 dA, by tensor Gauss
// quadrature on cells x cells pieces.
ShDouble rectangleSh(glm::dvec3 probe, glm::dvec3 origin, glm::dvec3 edge_s, glm::dvec3 edge_t,
                     const std::function<glm::dvec3(glm::dvec3)>& radiance, int cells) {
    const glm::dvec3 normal = glm::cross(edge_s, edge_t);
    const double area = glm::length(normal);
    const glm::dvec3 unit_normal = normal / area;
    ShDouble out{};
    const double h = 1.0 / cells;
    for (int i = 0; i < cells; ++i) {
        for (int j = 0; j < cells; ++j) {
            for (int a = 0; a < 8; ++a) {
                for (int b = 0; b < 8; ++b) {
                    const double s = (i + 0.5 + 0.5 * kGaussNodes[a]) * h;
                    const double t = (j + 0.5 + 0.5 * kGaussNodes[b]) * h;
                    const double w = kGaussWeights[a] * kGaussWeights[b] * 0.25 * h * h * area;
                    const glm::dvec3 x = origin + s * edge_s + t * edge_t;
                    const glm::dvec3 v = x - probe;
                    const double r2 = glm::dot(v, v);
                    const double solid_angle =
                        w * std::abs(glm::dot(unit_normal, v)) / (r2 * std::sqrt(r2));
                    const glm::dvec3 l = radiance(x);
                    const auto y = basis(v);
                    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
                        out[c] += l * (y[c] * solid_angle);
                    }
                }
            }
        }
    }
    return out;
}

// Lambert's formula for a polygon of unit radiance: the vector irradiance
// Phi = integral of w dw over the polygon = 1/2 sum_i beta_i gamma_i, beta_i the angle edge i
// subtends at p and gamma_i the unit normal of the plane through p and the edge (Arvo, "The
// Irradiance Jacobian for Partially Occluded Polyhedral Sources", 1994). E(n) = n . Phi when
// the whole polygon lies above the plane of n.
glm::dvec3 polygonVectorIrradiance(glm::dvec3 p, const std::vector<glm::dvec3>& polygon) {
    glm::dvec3 phi(0.0);
    glm::dvec3 centroid(0.0);
    for (size_t i = 0; i < polygon.size(); ++i) {
        const glm::dvec3 a = glm::normalize(polygon[i] - p);
        const glm::dvec3 b = glm::normalize(polygon[(i + 1) % polygon.size()] - p);
        phi += std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0)) * glm::normalize(glm::cross(a, b));
        centroid += polygon[i];
    }
    phi *= 0.5;
    return glm::dot(phi, centroid / double(polygon.size()) - p) < 0.0 ? -phi : phi;
}

// Solid angle of triangle abc seen from p (Van Oosterom and Strackee 1983).
double triangleSolidAngle(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
    a -= p;
    b -= p;
    c -= p;
    const double la = glm::length(a), lb = glm::length(b), lc = glm::length(c);
    const double numerator = std::abs(glm::dot(a, glm::cross(b, c)));
    const double denominator =
        la * lb * lc + glm::dot(a, b) * lc + glm::dot(a, c) * lb + glm::dot(b, c) * la;
    return 2.0 * std::atan2(numerator, denominator);
}

// Radiance SH of a lat-long environment, integrating Environment::radiance itself (bilinear
// texels) over the sphere: cells between texel centres, where the reconstruction is smooth,
// with 8 x 8 Gauss points, in the image's (u, v) with dw = 2 pi^2 sin(pi v) du dv. `weight`
// multiplies the integrand (e.g. a clamped cosine); `v_end` limits the rows integrated.
ShDouble environmentSh(const Environment& env, const std::function<double(glm::dvec3)>& weight = {},
                       double v_end = 1.0) {
    const uint32_t w = env.image.width;
    const uint32_t h = env.image.height;
    // Kinks of the bilinear reconstruction sit at texel centres; split there (and at v_end).
    std::vector<double> v_edges = {0.0};
    for (uint32_t j = 0; j < h; ++j) {
        const double centre = (j + 0.5) / h;
        if (centre < v_end) {
            v_edges.push_back(centre);
        }
    }
    v_edges.push_back(v_end);
    const double angle = glm::radians(double(env.rotationDeg));
    ShDouble out{};
    for (size_t e = 0; e + 1 < v_edges.size(); ++e) {
        const double v0 = v_edges[e], v1 = v_edges[e + 1];
        for (uint32_t i = 0; i < w; ++i) {
            const double u0 = (i + 0.5) / w, u1 = (i + 1.5) / w;
            for (int a = 0; a < 8; ++a) {
                for (int b = 0; b < 8; ++b) {
                    const double u = 0.5 * (u0 + u1) + 0.5 * (u1 - u0) * kGaussNodes[a];
                    const double v = 0.5 * (v0 + v1) + 0.5 * (v1 - v0) * kGaussNodes[b];
                    const double theta = kPi * v, phi = 2.0 * kPi * u;
                    const glm::dvec3 local(std::sin(theta) * std::sin(phi), std::cos(theta),
                                           -std::sin(theta) * std::cos(phi));
                    const glm::dvec3 dir(std::cos(angle) * local.x + std::sin(angle) * local.z,
                                         local.y,
                                         -std::sin(angle) * local.x + std::cos(angle) * local.z);
                    double dw = kGaussWeights[a] * kGaussWeights[b] * 0.25 * (u1 - u0) * (v1 - v0) *
                                2.0 * kPi * kPi * std::sin(theta);
                    if (weight) {
                        dw *= weight(dir);
                    }
                    const glm::dvec3 l(env.radiance(glm::vec3(dir)));
                    const auto y = basis(dir);
                    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
                        out[c] += l * (y[c] * dw);
                    }
                }
            }
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Statistics.

struct ShEstimate {
    ShDouble mean{};
    ShDouble standardError{};
};

std::vector<ProbeSample> bakeProbes(const Scene& scene, const RayTracer& tracer,
                                    PathConfig settings, sh::Order order, glm::vec3 position,
                                    int count = kProbes, uint64_t seed = 1) {
    const PathIntegrator integrator(scene, tracer, settings, order);
    std::vector<ProbeSample> probes;
    for (int k = 0; k < count; ++k) {
        probes.push_back(integrator.bakeProbe(position, seed, 0, uint64_t(k)));
    }
    return probes;
}

ShEstimate estimate(const std::vector<ProbeSample>& probes) {
    ShEstimate e;
    const double n = double(probes.size());
    for (const ProbeSample& p : probes) {
        for (int c = 0; c < sh::kMaxCoefficients; ++c) {
            e.mean[c] += glm::dvec3(p.sh.rgb[c]) / n;
        }
    }
    for (const ProbeSample& p : probes) {
        for (int c = 0; c < sh::kMaxCoefficients; ++c) {
            const glm::dvec3 d = glm::dvec3(p.sh.rgb[c]) - e.mean[c];
            e.standardError[c] += d * d / (n - 1.0);
        }
    }
    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
        e.standardError[c] = glm::sqrt(e.standardError[c] / n);
    }
    return e;
}

void writeFailure(const std::string& what, const ShEstimate& e, const ShDouble& reference,
                  int count) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::filesystem::path dir(PROBEKIT_TEST_OUTPUT_DIR);
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    std::ofstream out(
        dir / (std::string(info->test_suite_name()) + "." + info->name() + "." + what + ".txt"));
    out << "# coefficient channel estimate standard_error reference\n";
    for (int c = 0; c < count; ++c) {
        for (int k = 0; k < 3; ++k) {
            out << c << ' ' << k << ' ' << e.mean[c][k] << ' ' << e.standardError[c][k] << ' '
                << reference[c][k] << '\n';
        }
    }
}

// Every coefficient (the first `count`) within kSigmas standard errors (+ float slack + a
// stated allowance) of the reference.
void expectCoefficientsMatch(const std::string& what, const ShEstimate& e,
                             const ShDouble& reference, int count, double allowance = 0.0) {
    double scale = 0.0;
    for (int c = 0; c < count; ++c) {
        for (int k = 0; k < 3; ++k) {
            scale = std::max(scale, std::abs(reference[c][k]));
        }
    }
    bool failed = false;
    for (int c = 0; c < count; ++c) {
        for (int k = 0; k < 3; ++k) {
            const double tolerance =
                kSigmas * e.standardError[c][k] + kFloatSlack * scale + allowance;
            const double error = std::abs(e.mean[c][k] - reference[c][k]);
            EXPECT_LE(error, tolerance)
                << what << ": coefficient " << c << " channel " << k << " estimate " << e.mean[c][k]
                << " reference " << reference[c][k] << " (standard error " << e.standardError[c][k]
                << ")";
            failed = failed || !(error <= tolerance);
        }
    }
    if (failed) {
        writeFailure(what, e, reference, count);
    }
}

void expectShMatches(const std::string& what, const ShEstimate& e, const ShDouble& reference,
                     sh::Order order) {
    expectCoefficientsMatch(what, e, reference, sh::coefficientCount(order));
}

// The estimate of a probe at the origin from 4096 directions.
ShEstimate estimateAtOrigin(const Scene& scene, const RayTracer& tracer, sh::Order order) {
    PathConfig settings;
    settings.samples = 4096;
    return estimate(bakeProbes(scene, tracer, settings, order, glm::vec3(0.0f)));
}

// A probe at `probe` baked with 4096 directions and up to 4 bounces matches `reference` (L2).
void expectBakeMatches(const Scene& scene, const RayTracer& tracer, glm::dvec3 probe,
                       const ShDouble& reference) {
    PathConfig settings;
    settings.samples = 4096;
    settings.maxBounces = 4;
    const ShEstimate e =
        estimate(bakeProbes(scene, tracer, settings, sh::Order::L2, glm::vec3(probe)));
    expectShMatches("sh", e, reference, sh::Order::L2);
}

ShDouble constantSh(glm::dvec3 l00) {
    ShDouble out{};
    out[0] = l00;
    return out;
}

double relativeError(double value, double reference) {
    return std::abs(value - reference) / std::abs(reference);
}

// ---------------------------------------------------------------------------------------------
// RayTracer.

TEST(RayTracerTest, HitReportsDistanceBarycentricsNormalAndFace) {
    Scene scene = emptyScene();
    addTriangle(scene, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0); // winding normal +z
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);

    const std::optional<Hit> front = tracer->intersect({0.25f, 0.5f, 2.0f}, {0, 0, -1});
    ASSERT_TRUE(front.has_value());
    EXPECT_FLOAT_EQ(front->t, 2.0f);
    EXPECT_EQ(front->triangle, 0u);
    EXPECT_FLOAT_EQ(front->bary.x, 0.25f); // weight of vertex 1 (1, 0, 0)
    EXPECT_FLOAT_EQ(front->bary.y, 0.5f);  // weight of vertex 2 (0, 1, 0)
    EXPECT_EQ(front->geometricNormal, glm::vec3(0, 0, 1));
    EXPECT_FALSE(front->backFace);
    const glm::vec3 p = tracer->surfacePoint(front->triangle, front->bary);
    EXPECT_FLOAT_EQ(p.x, 0.25f);
    EXPECT_FLOAT_EQ(p.y, 0.5f);
    EXPECT_FLOAT_EQ(p.z, 0.0f);

    const std::optional<Hit> back = tracer->intersect({0.25f, 0.25f, -1.0f}, {0, 0, 1});
    ASSERT_TRUE(back.has_value());
    EXPECT_TRUE(back->backFace);
    EXPECT_EQ(back->geometricNormal, glm::vec3(0, 0, 1));

    EXPECT_FALSE(tracer->intersect({2, 2, 1}, {0, 0, -1}).has_value());             // beside it
    EXPECT_FALSE(tracer->intersect({0.2f, 0.2f, 1}, {0, 0, -1}, 0.5f).has_value()); // short
    EXPECT_FALSE(tracer->intersect({0.2f, 0.2f, 1}, {0, 0, 1}).has_value());        // away
    EXPECT_FALSE(tracer->occluded({0.2f, 0.2f, 1}, {0, 0, -1}, 0.5f));
    EXPECT_TRUE(tracer->occluded({0.2f, 0.2f, 1}, {0, 0, -1}, 1.5f));
    EXPECT_TRUE(tracer->occluded({0.2f, 0.2f, -1}, {0, 0, 1}, kInfinity));
}

TEST(RayTracerTest, EmptySceneBuildsAndMisses) {
    const Scene scene = emptyScene();
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);
    EXPECT_EQ(tracer->triangleCount(), 0u);
    EXPECT_FALSE(tracer->intersect({0, 0, 0}, {0, 1, 0}).has_value());
    EXPECT_FALSE(tracer->occluded({0, 0, 0}, {0, 1, 0}, kInfinity));
}

TEST(RayTracerTest, RejectsOutOfRangeVertexIndex) {
    Scene scene = emptyScene();
    addTriangle(scene, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0);
    scene.triangles[0].z = 7;
    const Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    ASSERT_FALSE(tracer.ok());
    EXPECT_EQ(tracer.error().code, ErrorCode::OutOfRange);
    EXPECT_NE(tracer.error().message.find("triangle 0"), std::string::npos);
}

// Rays leaving points of a triangle from offsetOrigin never hit that triangle again, on either
// side, near the world origin and far from it; and the offset stays a few hundred ulps.
TEST(RayTracerTest, OffsetOriginPreventsSelfIntersection) {
    constexpr int kRays = 4000;
    // 256 ulps per axis (Ray Tracing Gems ch. 6) of a coordinate of magnitude m is 256 * 2^-23 m
    // ~= 3e-5 m; with the 1/65536 floor near the origin.
    constexpr float kMaxRelativeOffset = 1e-4f;
    for (const glm::vec3 shift : {glm::vec3(0.0f), glm::vec3(3e3f, -2e3f, 5e3f)}) {
        Scene scene = emptyScene();
        const glm::vec3 a = shift + glm::vec3(-1.0f, -0.3f, -0.7f);
        const glm::vec3 b = shift + glm::vec3(1.3f, 0.2f, -0.4f);
        const glm::vec3 c = shift + glm::vec3(-0.2f, 0.9f, 1.1f);
        addTriangle(scene, a, b, c, 0);
        const auto tracer = boundedTracer(scene);
        ASSERT_TRUE(tracer);
        const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
        Rng rng(42);
        int self_hits = 0;
        for (int i = 0; i < kRays; ++i) {
            glm::vec2 bary = rng.uniform2();
            if (bary.x + bary.y > 1.0f) {
                bary = glm::vec2(1.0f) - bary;
            }
            const glm::vec3 p = tracer->surfacePoint(0, bary);
            // Grazing to normal directions, on both sides.
            const float z = rng.uniform();
            const float phi = 2.0f * float(kPi) * rng.uniform();
            const glm::vec3 t1 = glm::normalize(b - a);
            const glm::vec3 t2 = glm::cross(n, t1);
            const float r = std::sqrt(1.0f - z * z);
            const float side = (i % 2 == 0) ? 1.0f : -1.0f;
            const glm::vec3 dir = glm::normalize(r * std::cos(phi) * t1 + r * std::sin(phi) * t2 +
                                                 side * std::max(z, 1e-3f) * n);
            const glm::vec3 origin = RayTracer::offsetOrigin(p, n, dir);
            EXPECT_GT(side * glm::dot(origin - p, n), 0.0f);
            EXPECT_LT(glm::length(origin - p), kMaxRelativeOffset * std::max(1.0f, glm::length(p)));
            self_hits += tracer->intersect(origin, dir).has_value() ? 1 : 0;
        }
        EXPECT_EQ(self_hits, 0) << "shift " << shift.x;
    }
}

// ---------------------------------------------------------------------------------------------
// PathTracer: furnace.

// Inside a closed surface of uniform albedo a and uniform emission Le every ray ends on a
// surface, so L = Le + a L everywhere: L = Le / (1 - a), whatever the shape. With the bounce
// cap B the path tracer converges to Le (1 - a^(B+1)) / (1 - a): B = 0, 1, 2 check the
// truncation and that the MIS weights of next-event estimation and the continuation sum to one
// at each vertex; B = 64 (a^65 < 1e-8 of the answer) checks Russian roulette (from vertex 3 on)
// adds no bias. L00 = sqrt(4 pi) L, every other coefficient 0.
TEST(PathTracerFurnace, ClosedSphereRadianceIsEmissionOverOneMinusAlbedo) {
    struct Case {
        glm::vec3 albedo;
        glm::vec3 emission;
    };
    for (const Case& test_case :
         {Case{glm::vec3(0.5f), glm::vec3(1.0f)},
          Case{glm::vec3(0.5f, 0.25f, 0.75f), glm::vec3(1.0f, 2.0f, 0.5f)}}) {
        Scene scene = emptyScene();
        addIcosphere(scene, glm::vec3(0.0f), 1.0f, 3,
                     addMaterial(scene, test_case.albedo, test_case.emission));
        const auto tracer = boundedTracer(scene);
        ASSERT_TRUE(tracer);
        for (const uint32_t bounces : {0u, 1u, 2u, 64u}) {
            PathConfig settings;
            settings.samples = 2048;
            settings.maxBounces = bounces;
            const auto probes =
                bakeProbes(scene, *tracer, settings, sh::Order::L2, glm::vec3(0.1f, -0.2f, 0.15f));
            glm::dvec3 radiance(0.0);
            for (int k = 0; k < 3; ++k) {
                const double a = test_case.albedo[k];
                radiance[k] = test_case.emission[k] * (1.0 - std::pow(a, bounces + 1)) / (1.0 - a);
            }
            expectShMatches("bounces" + std::to_string(bounces), estimate(probes),
                            constantSh(std::sqrt(4.0 * kPi) * radiance), sh::Order::L2);
            for (const ProbeSample& p : probes) {
                EXPECT_EQ(p.backFaceFraction, 1.0f); // outward winding, probe inside
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// PathTracer: delta lights at the probe.

// A point light of intensity I at distance d in direction dl is a delta of irradiance e = I/d^2,
// so the probe holds e Y(dl) exactly and its band-limited irradiance is
// E_L(n) = e sum_{l <= L} A_l (2l + 1) / (4 pi) P_l(n . dl) (addition theorem).
TEST(PathTracerPointLight, DeltaProjectionGivesBandLimitedIrradiance) {
    Scene scene = emptyScene();
    PunctualLight light;
    light.type = LightType::Point;
    light.position = glm::vec3(1.0f, 2.0f, -2.0f);
    light.intensity = glm::vec3(9.0f, 18.0f, 4.5f);
    scene.lights.push_back(light);
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);
    const glm::vec3 probe(0.0f);
    const glm::dvec3 to_light = glm::normalize(glm::dvec3(light.position) - glm::dvec3(probe));
    const double d2 = 9.0;
    const glm::dvec3 e = glm::dvec3(light.intensity) / d2;

    for (const sh::Order order : {sh::Order::L1, sh::Order::L2}) {
        PathConfig settings;
        settings.samples = 16;
        const PathIntegrator integrator(scene, *tracer, settings, order);
        const ProbeSample sample = integrator.bakeProbe(probe, 7, 0, 0);
        EXPECT_EQ(sample.rays, uint64_t(settings.samples) + 1); // misses + one shadow ray
        EXPECT_EQ(sample.backFaceFraction, 0.0f);
        const int bands = order == sh::Order::L1 ? 2 : 3;
        Rng rng(3);
        std::vector<glm::dvec3> normals = {to_light, -to_light, {0, 1, 0}, {1, 0, 0}};
        for (int i = 0; i < 8; ++i) {
            normals.push_back(glm::normalize(
                glm::dvec3(rng.uniform(), rng.uniform(), rng.uniform()) - glm::dvec3(0.5)));
        }
        for (const glm::dvec3& n : normals) {
            const double x = glm::dot(n, to_light);
            const double legendre[3] = {1.0, x, 0.5 * (3.0 * x * x - 1.0)};
            double factor = 0.0;
            for (int l = 0; l < bands; ++l) {
                factor += double(sh::kCosineLobe[l]) * (2 * l + 1) / (4.0 * kPi) * legendre[l];
            }
            const glm::dvec3 irradiance(sh::irradiance(sample.sh, order, glm::vec3(n)));
            for (int k = 0; k < 3; ++k) {
                EXPECT_NEAR(irradiance[k], e[k] * factor, kDeltaRelativeTolerance * e[k])
                    << "order " << bands - 1 << " n.d " << x;
            }
        }
        // Facing the light: (1 + 2 + 5/4) / 4 = 1.0625 e at L2, (1 + 2) / 4 = 0.75 e at L1.
        const double facing = order == sh::Order::L1 ? 0.75 : 1.0625;
        const glm::vec3 at_light = sh::irradiance(sample.sh, order, glm::vec3(to_light));
        EXPECT_LT(relativeError(at_light.y, facing * e.y), kDeltaRelativeTolerance);
    }
}

// glTF spot: I / d^2 x clamp((cos - cos_outer) / (cos_inner - cos_outer), 0, 1)^2 x
// clamp(1 - (d / range)^4, 0, 1)^2, delivered to the probe as a delta from the light.
TEST(PathTracerSpotLight, ConeFalloffAndRangeWindow) {
    Scene scene = emptyScene();
    PunctualLight spot;
    spot.type = LightType::Spot;
    spot.position = glm::vec3(0.0f);
    spot.direction = glm::vec3(0.0f, -1.0f, 0.0f);
    spot.intensity = glm::vec3(100.0f);
    spot.innerConeCos = std::cos(glm::radians(20.0f));
    spot.outerConeCos = std::cos(glm::radians(30.0f));
    spot.range = 10.0f;
    scene.lights.push_back(spot);
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);
    PathConfig settings;
    settings.samples = 4;
    const PathIntegrator integrator(scene, *tracer, settings, sh::Order::L2);

    struct Case {
        double angleDeg;
        double distance;
    };
    for (const Case c : {Case{0, 4}, Case{10, 4}, Case{25, 4}, Case{29, 6}, Case{35, 4}, Case{0, 9},
                         Case{0, 11}}) {
        const double angle = glm::radians(c.angleDeg);
        const glm::dvec3 offset(std::sin(angle) * c.distance, -std::cos(angle) * c.distance, 0.0);
        const ProbeSample sample = integrator.bakeProbe(glm::vec3(offset), 1, 0, 0);
        const double cone = std::clamp((std::cos(angle) - double(spot.outerConeCos)) /
                                           (double(spot.innerConeCos) - spot.outerConeCos),
                                       0.0, 1.0);
        const double window = std::clamp(1.0 - std::pow(c.distance / spot.range, 4.0), 0.0, 1.0);
        const double e = 100.0 / (c.distance * c.distance) * cone * cone * window * window;
        const double l00 = sample.sh.rgb[0].x;
        EXPECT_NEAR(l00, e * sh::kY00, kDeltaRelativeTolerance * 100.0 / 16.0 * sh::kY00)
            << "angle " << c.angleDeg << " distance " << c.distance;
        // The delta points from the probe back to the light: L1 = e Y1 (-offset / |offset|).
        EXPECT_NEAR(sample.sh.rgb[1].x, e * sh::kY1 * std::cos(angle),
                    kDeltaRelativeTolerance * 100.0 / 16.0);
    }
}

// The delta term at the probe is shadow-tested: an opaque quad between light and probe removes
// it. The quad's unlit side faces the probe, so nothing else reaches it either.
TEST(PathTracerPointLight, OccluderKillsDeltaTerm) {
    PunctualLight light;
    light.position = glm::vec3(0.0f, 3.0f, 0.0f);
    light.intensity = glm::vec3(9.0f);
    for (const bool occluder : {false, true}) {
        Scene scene = emptyScene();
        scene.lights.push_back(light);
        if (occluder) {
            addQuad(scene, {-1, 1.5f, -1}, {-1, 1.5f, 1}, {1, 1.5f, 1}, {1, 1.5f, -1},
                    addMaterial(scene, glm::vec3(0.5f), glm::vec3(0.0f)));
            computeBounds(scene);
        }
        const auto tracer = buildTracer(scene);
        ASSERT_TRUE(tracer);
        PathConfig settings;
        settings.samples = 64;
        const PathIntegrator integrator(scene, *tracer, settings, sh::Order::L2);
        const ProbeSample sample = integrator.bakeProbe(glm::vec3(0.0f), 1, 0, 0);
        if (occluder) {
            EXPECT_EQ(sample.sh, sh::ShRgb{});
        } else {
            EXPECT_NEAR(sample.sh.rgb[0].x, sh::kY00 * 1.0f, 1e-6f); // I / d^2 = 1
        }
    }
}

// Next-event estimation of delta lights at surface vertices: a 6 x 6 m floor of albedo 0.5 lit
// by a point light and a directional light. Floor radiance at x is
// (a / pi) (I cos / d^2 + E_sun cos_sun) (nothing shadows the floor); the probe above it also
// receives both lights as deltas. Reference: quadrature over the floor plus the two deltas.
TEST(PathTracerPointLight, PointAndDirectionalLightOnFloorMatchQuadrature) {
    Scene scene = emptyScene();
    const double albedo = 0.5;
    const Rectangle floor{{-3.0, 0.0, -3.0}, {0.0, 0.0, 6.0}, {6.0, 0.0, 0.0}};
    addRectangle(scene, floor, addMaterial(scene, glm::vec3(float(albedo)), glm::vec3(0.0f)));
    computeBounds(scene);
    PunctualLight point;
    point.type = LightType::Point;
    point.position = glm::vec3(0.5f, 2.0f, 0.3f);
    point.intensity = glm::vec3(8.0f, 4.0f, 2.0f);
    PunctualLight sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
    sun.intensity = glm::vec3(1.0f, 2.0f, 3.0f);
    scene.lights = {point, sun};
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);

    const glm::dvec3 probe(-0.4, 1.0, 0.2);
    const glm::dvec3 light_position(point.position);
    const glm::dvec3 to_sun = -glm::dvec3(sun.direction);
    ShDouble reference = rectangleSh(
        probe, floor.origin, floor.edgeS, floor.edgeT,
        [&](glm::dvec3 x) {
            const glm::dvec3 v = light_position - x;
            const double d2 = glm::dot(v, v);
            const glm::dvec3 e = glm::dvec3(point.intensity) * (v.y / std::sqrt(d2) / d2) +
                                 glm::dvec3(sun.intensity) * to_sun.y;
            return e * (albedo / kPi);
        },
        24);
    const glm::dvec3 v = light_position - probe;
    const auto y_point = basis(v);
    const auto y_sun = basis(to_sun);
    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
        reference[c] += glm::dvec3(point.intensity) / glm::dot(v, v) * y_point[c] +
                        glm::dvec3(sun.intensity) * y_sun[c];
    }
    expectBakeMatches(scene, *tracer, probe, reference);
}

// ---------------------------------------------------------------------------------------------
// PathTracer: environment only.

TEST(PathTracerEnvironment, ConstantSkyGivesPiLIrradiance) {
    Scene scene = emptyScene();
    const glm::dvec3 sky(0.5, 1.0, 2.0);
    scene.environment.constant = glm::vec3(sky);
    scene.environment.intensity = 1.0f;
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);
    PathConfig settings;
    settings.samples = 256;
    const auto probes = bakeProbes(scene, *tracer, settings, sh::Order::L2, glm::vec3(0.0f));
    const ShEstimate e = estimate(probes);
    // Every sample is L: L00 is exact up to float rounding, the other bands vanish on average.
    expectShMatches("sh", e, constantSh(std::sqrt(4.0 * kPi) * sky), sh::Order::L2);
    for (int k = 0; k < 3; ++k) {
        EXPECT_LT(relativeError(probes[0].sh.rgb[0][k], std::sqrt(4.0 * kPi) * sky[k]), 1e-5);
    }
    // E(n) = pi L for every n, within the Monte Carlo spread of the higher bands.
    for (const glm::vec3 n : {glm::vec3(0, 1, 0), glm::vec3(0, 0, -1), glm::vec3(0.6f, 0, 0.8f)}) {
        std::vector<double> values;
        for (const ProbeSample& p : probes) {
            values.push_back(sh::irradiance(p.sh, sh::Order::L2, n).z);
        }
        const MeanAndError m = meanAndStandardError(values);
        EXPECT_NEAR(m.mean, kPi * sky.z, kSigmas * m.standardError + kFloatSlack * kPi * sky.z);
    }
}

// A smooth sky with a bright sun and a dark ground, 48 x 24 texels, rotated.
Environment syntheticSky(bool black_below_horizon) {
    Environment env;
    env.type = Environment::Type::LatLong;
    env.intensity = 1.5f;
    env.rotationDeg = 30.0f;
    const glm::dvec3 sun = glm::normalize(glm::dvec3(0.4, 0.6, 0.3));
    env.image = latLongImage(48, 24, [&](glm::dvec3 d, uint32_t, uint32_t y) {
        if (black_below_horizon && (d.y < 0.0 || y == 0)) {
            return glm::vec3(0.0f);
        }
        const double sky = 0.3 + 0.5 * std::max(0.0, d.y) + 0.1 * d.x;
        const double sun_glow = 40.0 * std::pow(std::max(0.0, glm::dot(d, sun)), 200.0);
        return glm::vec3(float(sky + sun_glow), float(0.8 * sky + sun_glow),
                         float(0.6 * sky + 0.5 * sun_glow));
    });
    return env;
}

// No geometry: the probe sees the map itself. Reference: every coefficient by quadrature of
// Environment::radiance (the bilinear map the integrator samples); L00 also against the pixel
// sum of L Y00 over exact pixel solid angles, which differs from the bilinear integral by the
// reconstruction allowance computed here.
TEST(PathTracerEnvironment, LatLongSkyMatchesNumericalIntegration) {
    Scene scene = emptyScene();
    scene.environment = syntheticSky(false);
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);
    const ShEstimate e = estimateAtOrigin(scene, *tracer, sh::Order::L2);
    const ShDouble reference = environmentSh(scene.environment);
    expectShMatches("quadrature", e, reference, sh::Order::L2);

    glm::dvec3 pixel_sum = pixelSum(scene.environment.image);
    pixel_sum *= double(scene.environment.intensity) * sh::kY00;
    const double allowance = glm::length(pixel_sum - reference[0]);
    EXPECT_LT(allowance, 0.01 * reference[0].x); // the two integrals are close to begin with
    expectCoefficientsMatch("pixelSum", e, constantSh(pixel_sum), 1, allowance);
}

// ---------------------------------------------------------------------------------------------
// PathTracer: emitters and environment lighting a diffuse floor (next-event estimation + MIS).

// An emissive unit square seen directly from a probe below it and from one above it: its
// winding faces up, so the probe below sees its back. The L1 band holds the vector irradiance,
// L_1m = Y1 Phi_m with Phi = integral of L w dw, so E(n) = n . Phi must match Lambert's
// polygon formula, and L00 = Y00 L Omega the solid angle.
TEST(PathTracerEmissive, QuadSeenDirectlyMatchesLambertFormulaFromBothSides) {
    Scene scene = emptyScene();
    const glm::dvec3 radiance(2.0, 3.0, 4.0);
    const Rectangle quad{{-0.5, 1.0, -0.5}, {0.0, 0.0, 1.0}, {1.0, 0.0, 0.0}};
    const auto p = quad.polygon();
    addQuad(scene, glm::vec3(p[0]), glm::vec3(p[1]), glm::vec3(p[2]), glm::vec3(p[3]),
            addMaterial(scene, glm::vec3(0.0f), glm::vec3(radiance)));
    ASSERT_GT(glm::cross(quad.edgeS, quad.edgeT).y, 0.0); // winding faces +y
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    PathConfig settings;
    settings.samples = 4096;
    for (const glm::dvec3 probe : {glm::dvec3(0.2, 0.0, 0.1), glm::dvec3(0.2, 2.0, 0.1)}) {
        const auto probes = bakeProbes(scene, *tracer, settings, sh::Order::L1, glm::vec3(probe));
        const ShEstimate e = estimate(probes);
        const glm::dvec3 phi = polygonVectorIrradiance(probe, p);
        const double omega = triangleSolidAngle(probe, p[0], p[1], p[2]) +
                             triangleSolidAngle(probe, p[0], p[2], p[3]);
        ShDouble reference{};
        reference[0] = radiance * (sh::kY00 * omega);
        reference[1] = radiance * (sh::kY1 * phi.y);
        reference[2] = radiance * (sh::kY1 * phi.z);
        reference[3] = radiance * (sh::kY1 * phi.x);
        expectShMatches(probe.y < 1.0 ? "below" : "above", e, reference, sh::Order::L1);
        // Irradiance facing the quad: E = pi L F with F the form factor, i.e. L (n . Phi).
        const glm::dvec3 n(0.0, probe.y < 1.0 ? 1.0 : -1.0, 0.0);
        const double expected = glm::dot(n, phi) * radiance.y;
        std::vector<double> values;
        for (const ProbeSample& s : probes) {
            const glm::dvec3 l1(s.sh.rgb[3].y, s.sh.rgb[1].y, s.sh.rgb[2].y);
            values.push_back(glm::dot(n, l1) / sh::kY1);
        }
        const MeanAndError m = meanAndStandardError(values);
        EXPECT_NEAR(m.mean, expected, kSigmas * m.standardError) << "probe y " << probe.y;
    }
}

// quadOverFloor: the same square (emission only, black, winding facing away from the floor) 2 m
// above a 6 x 6 m floor of albedo 0.6; the probe sits between them. The floor is lit once: its
// radiance at x is (a / pi) E(x) with E(x) from Lambert's polygon formula; nothing else reflects
// (the quad is black, the floor flat, the sky black). Reference: Gauss quadrature of L Y dw over
// the quad and over the floor. Paths reach the quad's light by next-event estimation (its back
// face: two-sided emission) and by cosine sampling, MIS-weighted.
struct QuadOverFloor {
    Scene scene;
    glm::dvec3 probe;
    ShDouble reference;
};

QuadOverFloor quadOverFloor() {
    QuadOverFloor out{emptyScene(), glm::dvec3(0.4, 1.0, -0.3), {}};
    const glm::dvec3 radiance(2.0, 3.0, 4.0);
    const double albedo = 0.6;
    const Rectangle quad{{-0.5, 2.0, -0.5}, {0.0, 0.0, 1.0}, {1.0, 0.0, 0.0}};
    const Rectangle floor{{-3.0, 0.0, -3.0}, {0.0, 0.0, 6.0}, {6.0, 0.0, 0.0}};
    const auto q = quad.polygon();
    addRectangle(out.scene, quad, addMaterial(out.scene, glm::vec3(0.0f), glm::vec3(radiance)));
    addRectangle(out.scene, floor,
                 addMaterial(out.scene, glm::vec3(float(albedo)), glm::vec3(0.0f)));
    const ShDouble direct = rectangleSh(
        out.probe, quad.origin, quad.edgeS, quad.edgeT, [&](glm::dvec3) { return radiance; }, 4);
    const ShDouble reflected = rectangleSh(
        out.probe, floor.origin, floor.edgeS, floor.edgeT,
        [&](glm::dvec3 x) {
            const double e = glm::dot(glm::dvec3(0, 1, 0), polygonVectorIrradiance(x, q));
            return radiance * (albedo / kPi * e);
        },
        24);
    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
        out.reference[c] = direct[c] + reflected[c];
    }
    return out;
}

TEST(PathTracerEmissive, QuadLightingFloorMatchesQuadrature) {
    QuadOverFloor c = quadOverFloor();
    const auto tracer = boundedTracer(c.scene);
    ASSERT_TRUE(tracer);
    expectBakeMatches(c.scene, *tracer, c.probe, c.reference);
}

// A 10 x 10 m floor of albedo 0.6 under the synthetic sky, black below the horizon (and in the
// top row, so that the bilinear wrap at the poles adds nothing below). Every floor point sees
// the whole upper hemisphere of sky and nothing else, so the floor radiance is uniform:
// (a / pi) E with E = integral over y > 0 of L cos. The sky under the horizon that the
// bilinear reconstruction smears half a row downwards is far above the floor's edge as seen
// from the probe (> 11 degrees below the horizon), so the probe sees the whole map plus the
// floor: reference = environmentSh + (a / pi) E x quadrature of Y dw over the floor.
// Paths reach the sky by importance-sampled next-event estimation and by cosine sampling.
TEST(PathTracerEnvironment, SkyLightingFloorMatchesQuadrature) {
    Scene scene = emptyScene();
    scene.environment = syntheticSky(true);
    const double albedo = 0.6;
    const Rectangle floor = addWideFloor(scene, albedo);
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);

    const glm::dvec3 probe(0.3, 1.0, -0.2);
    const ShDouble sky = environmentSh(scene.environment);
    const ShDouble sky_cosine = environmentSh(
        scene.environment, [](glm::dvec3 d) { return d.y; }, 0.5);
    const glm::dvec3 floor_irradiance = sky_cosine[0] / double(sh::kY00);
    const ShDouble reflected = rectangleSh(
        probe, floor.origin, floor.edgeS, floor.edgeT,
        [&](glm::dvec3) { return floor_irradiance * (albedo / kPi); }, 24);
    ShDouble reference{};
    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
        reference[c] = sky[c] + reflected[c];
    }
    expectBakeMatches(scene, *tracer, probe, reference);
}

// Same floor under a constant sky (not importance sampled: the continuation alone finds it):
// floor radiance a L, sky L elsewhere.
TEST(PathTracerEnvironment, ConstantSkyLightingFloorMatchesQuadrature) {
    Scene scene = emptyScene();
    const glm::dvec3 sky(1.0, 0.5, 0.25);
    scene.environment.constant = glm::vec3(sky);
    const double albedo = 0.6;
    const Rectangle floor = addWideFloor(scene, albedo);
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    const glm::dvec3 probe(0.3, 1.0, -0.2);
    // Sky everywhere, minus the sky hidden by the floor, plus the floor.
    const ShDouble hidden = rectangleSh(
        probe, floor.origin, floor.edgeS, floor.edgeT,
        [&](glm::dvec3) { return sky * (1.0 - albedo); }, 24);
    ShDouble reference{};
    reference[0] = std::sqrt(4.0 * kPi) * sky;
    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
        reference[c] -= hidden[c];
    }
    expectBakeMatches(scene, *tracer, probe, reference);
}

// The Uffizi probe (if the shared data and the loader are present): L00 against the pixel sum
// over exact pixel solid angles, plus the bilinear-reconstruction allowance.
TEST(PathTracerEnvironment, UffiziL00MatchesPixelSum) {
    const std::filesystem::path file =
        std::filesystem::path(PROBEKIT_SHARED_DIR) / "env" / "uffizi.hdr";
    if (!std::filesystem::exists(file)) {
        GTEST_SKIP() << file << " not found";
    }
    Result<Environment> env = loadLatLongEnvironment(file, 1.0f, 0.0f);
    ASSERT_TRUE(env.ok()) << env.error().message;
    Scene scene = emptyScene();
    scene.environment = std::move(env).value();
    const auto tracer = buildTracer(scene);
    ASSERT_TRUE(tracer);
    const ShEstimate e = estimateAtOrigin(scene, *tracer, sh::Order::L1);

    const Image& image = scene.environment.image;
    glm::dvec3 pixel_sum = pixelSum(image);
    std::vector<glm::dvec3> row_mean(image.height, glm::dvec3(0.0));
    for (uint32_t y = 0; y < image.height; ++y) {
        for (uint32_t x = 0; x < image.width; ++x) {
            row_mean[y] +=
                glm::dvec3(image.texels[size_t(y) * image.width + x]) / double(image.width);
        }
    }
    pixel_sum *= sh::kY00;
    // The bilinear map integrates, over a full turn of u, to the piecewise-linear interpolation
    // of the row means in v (repeat-wrapped), so its L00 is a 1D integral against
    // 2 pi^2 sin(pi v) dv.
    const uint32_t h = image.height;
    const auto row_interpolated = [&](double v) {
        const double y = v * h - 0.5;
        const double fy = std::floor(y);
        const double t = y - fy;
        const auto wrap = [&](double i) { return uint32_t((long(i) % long(h) + long(h)) % h); };
        return glm::mix(row_mean[wrap(fy)], row_mean[wrap(fy + 1)], t);
    };
    glm::dvec3 bilinear(0.0);
    for (int k = 0; k < 3; ++k) {
        std::vector<double> edges = {0.0};
        for (uint32_t j = 0; j < h; ++j) {
            edges.push_back((j + 0.5) / h);
        }
        edges.push_back(1.0);
        for (size_t s = 0; s + 1 < edges.size(); ++s) {
            bilinear[k] += integrate1d(
                [&](double v) {
                    return row_interpolated(v)[k] * 2.0 * kPi * kPi * std::sin(kPi * v);
                },
                edges[s], edges[s + 1], 1);
        }
    }
    bilinear *= sh::kY00;
    const double allowance = glm::length(pixel_sum - bilinear);
    expectCoefficientsMatch("l00", e, constantSh(pixel_sum), 1, allowance);
}

// ---------------------------------------------------------------------------------------------
// PathTracer: validity, determinism, light sampler.

TEST(PathTracerValidity, BackFaceFractionInsideAndOutsideClosedBox) {
    Scene scene = emptyScene();
    addBox(scene, glm::vec3(-1.0f), glm::vec3(1.0f),
           addMaterial(scene, glm::vec3(0.5f), glm::vec3(0.0f)));
    scene.environment.constant = glm::vec3(1.0f);
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    PathConfig settings;
    settings.samples = 256;
    const PathIntegrator integrator(scene, *tracer, settings, sh::Order::L1);
    // Every primary ray from inside hits the inside of an outward-wound face.
    EXPECT_EQ(integrator.bakeProbe({0.1f, 0.2f, -0.3f}, 1, 0, 0).backFaceFraction, 1.0f);
    // From outside, rays that hit the box hit its front first.
    EXPECT_EQ(integrator.bakeProbe({3.0f, 0.5f, 0.0f}, 1, 0, 0).backFaceFraction, 0.0f);
}

// stopInsideGeometry decides validity from primary rays before any path. A box with outward
// walls and no lid, under a sky and beside a point light: inside it a probe sees back faces on
// a fraction of its sphere that falls with height (all of it at the floor, none far above the
// rim), so a column of probes crosses the 0.25 threshold. Every probe must get the verdict the
// full trace gives; valid probes the full trace's bits; invalid ones no path (rays <= N).
TEST(PathTracerValidity, InsideGeometryFoundFromPrimaryRaysAlone) {
    Scene scene = emptyScene();
    const uint32_t wall = addMaterial(scene, glm::vec3(0.6f), glm::vec3(0.0f));
    const glm::vec3 lo(-1.0f, 0.0f, -1.0f), hi(1.0f, 1.0f, 1.0f);
    addQuad(scene, {lo.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, lo.y, lo.z},
            wall); // -z
    addQuad(scene, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z},
            wall); // +z
    addQuad(scene, {lo.x, lo.y, lo.z}, {lo.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {lo.x, hi.y, lo.z},
            wall); // -x
    addQuad(scene, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z}, {hi.x, lo.y, hi.z},
            wall); // +x
    addQuad(scene, {lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, lo.y, hi.z}, {lo.x, lo.y, hi.z},
            wall); // -y
    scene.environment.constant = glm::vec3(0.5f);
    PunctualLight light;
    light.position = glm::vec3(0.3f, 2.5f, 0.2f);
    light.intensity = glm::vec3(4.0f);
    scene.lights.push_back(light);
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    constexpr float kThreshold = 0.25f;
    // Fixed sampling, and adaptive sampling with a target every probe meets at its minimum (8
    // batches of 16), where the full trace's verdict is the minimum's.
    for (const float noise_target : {0.0f, 1e6f}) {
        SCOPED_TRACE(noise_target);
        PathConfig settings;
        settings.samples = 128;
        settings.noiseTarget = noise_target;
        const PathIntegrator full(scene, *tracer, settings, sh::Order::L2);
        PathIntegrator stopping(scene, *tracer, settings, sh::Order::L2);
        stopping.stopInsideGeometry(kThreshold);

        int valid = 0, invalid = 0;
        uint64_t full_rays_invalid = 0;
        for (int k = 0; k < 40; ++k) {
            const glm::vec3 p(0.35f, 0.05f + 0.05f * float(k), -0.25f);
            SCOPED_TRACE(p.y);
            const ProbeSample a = full.bakeProbe(p, 3, 0, uint64_t(k));
            const ProbeSample b = stopping.bakeProbe(p, 3, 0, uint64_t(k));
            ASSERT_EQ(probeValidity(b, kThreshold), probeValidity(a, kThreshold));
            if (probeValidity(a, kThreshold) == kProbeValid) {
                ++valid;
                EXPECT_EQ(b.sh, a.sh);
                // The check's primary rays on top of the full trace's, at most N of them.
                EXPECT_GE(b.rays, a.rays);
                EXPECT_LE(b.rays, a.rays + settings.samples);
                EXPECT_EQ(b.backFaceFraction, a.backFaceFraction);
                EXPECT_EQ(b.samples, settings.samples);
            } else {
                ++invalid;
                full_rays_invalid += a.rays;
                EXPECT_LE(b.rays, settings.samples);
                EXPECT_EQ(b.samples, 0u);
                EXPECT_GT(b.backFaceFraction, kThreshold);
                EXPECT_EQ(b.sh, sh::ShRgb{});
            }
        }
        // The column crosses the threshold: both verdicts occur, several times each.
        EXPECT_GE(valid, 5);
        EXPECT_GE(invalid, 5);
        // A full trace of an invalid probe adds a shadow ray to the light (and a continuation) at
        // every wall it hits: more than the N primary rays that bound the check.
        EXPECT_GT(full_rays_invalid, uint64_t(invalid) * settings.samples);
    }
}

// path.shadow_rays: Russian roulette on the shadow rays to punctual lights. A black floor
// point under 24 point lights of spread intensities and distances, half of them behind a black
// wall: nothing reflects, so every sample of the surface estimator is the vertex's direct light
// alone, exact (zero variance) when every light gets its ray. With 4 shadow rays per vertex
// the mean must agree with it within kSigmas standard errors, the roulette must add noise (it
// ran), and the rays per sample must fall to at most the continuation plus 4 on average.
TEST(PathTracerShadowRays, RouletteOnManyLightsIsUnbiasedAndBoundsTheRays) {
    Scene scene = emptyScene();
    const uint32_t black = addMaterial(scene, glm::vec3(0.0f), glm::vec3(0.0f));
    addQuad(scene, {-8, 0, -8}, {-8, 0, 8}, {8, 0, 8}, {8, 0, -8}, black); // floor, facing +y
    addBox(scene, {1.0f, 0.0f, -8.0f}, {1.2f, 3.0f, 8.0f}, black);         // wall at x = 1.1
    constexpr int kLights = 24;
    for (int i = 0; i < kLights; ++i) {
        PunctualLight light;
        const float side = i % 2 == 0 ? -1.0f : 1.0f; // odd lights beyond the wall
        light.position = glm::vec3(side * (1.5f + 0.25f * float(i)), 0.5f + 0.1f * float(i),
                                   -3.0f + 0.25f * float(i));
        light.intensity = glm::vec3(0.5f + float(i % 5), 1.0f, 0.2f * float(i % 3) + 0.3f);
        scene.lights.push_back(light);
    }
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    const glm::vec3 point(0.0f, 0.0f, 0.5f), up(0.0f, 1.0f, 0.0f);
    constexpr uint32_t kSamples = 4096;

    PathConfig every;
    every.shadowRays = 0;
    const PathIntegrator exact(scene, *tracer, every, sh::Order::L2);
    const PathIntegrator::SurfaceEstimate e = exact.surfaceIrradiance(point, up, up, kSamples, 9);
    ASSERT_EQ(e.varianceOfMean, glm::vec3(0.0f));
    ASSERT_GT(e.irradiance.x, 0.0f);

    PathConfig roulette;
    roulette.shadowRays = 4;
    const PathIntegrator rr(scene, *tracer, roulette, sh::Order::L2);
    const PathIntegrator::SurfaceEstimate r = rr.surfaceIrradiance(point, up, up, kSamples, 9);
    for (int c = 0; c < 3; ++c) {
        SCOPED_TRACE(c);
        const double sigma = std::sqrt(double(r.varianceOfMean[c]));
        EXPECT_GT(sigma, 0.0);
        EXPECT_NEAR(r.irradiance[c], e.irradiance[c],
                    kSigmas * sigma + kFloatSlack * double(e.irradiance[c]));
    }
    // Every light is above the floor: the exact estimator traces a continuation and 24 shadow
    // rays per sample. The roulette's mean of at most 4 shadow rays carries a 5-sigma allowance
    // for the draws (each ray is a Bernoulli draw, variance <= 1/4 each).
    EXPECT_EQ(e.rays, uint64_t(kSamples) * (1 + kLights));
    const double allowance = kSigmas * std::sqrt(kLights * 0.25 / kSamples);
    EXPECT_LE(double(r.rays) / kSamples, 1.0 + 4.0 + allowance);
}

// --verify's and --target-error's reference points follow the bake's path.shadow_rays: a
// bake that asks for a shadow ray to every light gets a reference traced the same way.
TEST(PathTracerShadowRays, ReferencePointsFollowTheBakesSetting) {
    Scene scene = emptyScene();
    addQuad(scene, {-8, 0, -8}, {-8, 0, 8}, {8, 0, 8}, {8, 0, -8},
            addMaterial(scene, glm::vec3(0.5f), glm::vec3(0.0f))); // floor, facing +y
    constexpr int kLights = 12;
    for (int i = 0; i < kLights; ++i) {
        PunctualLight light;
        light.position = glm::vec3(-3.0f + 0.5f * float(i), 1.0f + 0.1f * float(i), 0.0f);
        light.intensity = glm::vec3(1.0f);
        scene.lights.push_back(light);
    }
    const std::vector<glm::vec3> points = {{0.0f, 0.5f, 1.0f}, {1.0f, 0.3f, -1.0f}};
    constexpr uint32_t kSamples = 256;
    BakeConfig every;
    every.path.shadowRays = 0;
    BakeConfig four;
    four.path.shadowRays = 4;
    const Result<PointBake> a = bakePoints(scene, every, points, kSamples, 0, 1);
    const Result<PointBake> b = bakePoints(scene, four, points, kSamples, 0, 1);
    ASSERT_TRUE(a.ok() && b.ok());
    // Each path's first vertex (every direction below the horizon hits the floor) traces a
    // shadow ray to each of the 12 lights with 0, about 4 with 4: at least 6 x 128 rays apart
    // per point.
    const uint64_t floor_hits = points.size() * kSamples / 2;
    EXPECT_GE(a.value().rays, b.value().rays + 6 * floor_hits)
        << a.value().rays << " rays with shadow_rays 0, " << b.value().rays << " with 4";
}

// Russian roulette's weight window (path.roulette_weight). In thin-wall's unlit room about half
// the light has bounced three times or more, so cutting paths as soon as their throughput
// falls (a window of 1) leaves a few survivors to carry that light at large weights. 32 probes
// of that room, 8 seeds each, windows 1 and 0.25: the pooled relative variance of their axis
// irradiance times the rays traced (the cost of a given noise) must fall by at least 1.4x
// (measured 1.9x), and the two means must agree within kSigmas standard errors.
TEST(PathTracerRoulette, WeightWindowLowersTheCostOfNoiseInARoomLitThroughADoorway) {
    Scene scene = test::generatedScene("thin-wall");
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    constexpr int kSeeds = 8;
    std::vector<glm::vec3> probes;
    for (int i = 0; i < 32; ++i) {
        const glm::vec3 t((float(i % 4) + 0.5f) / 4.0f, (float((i / 4) % 2) + 0.5f) / 2.0f,
                          (float(i / 8) + 0.5f) / 4.0f);
        probes.push_back(glm::vec3(0.3f, 0.2f, -1.8f) + t * glm::vec3(3.4f, 2.0f, 3.6f));
    }
    struct Measured {
        double variance = 0.0, mean2 = 0.0;
        // Per seed: the axis irradiance summed over the probes (compared through its mean and
        // standard error: the probes' normals share samples).
        std::vector<double> seedTotal = std::vector<double>(kSeeds, 0.0);
        uint64_t rays = 0;
    };
    const auto measure = [&](float window) {
        PathConfig settings;
        settings.samples = 512;
        settings.rouletteWeight = window;
        const PathIntegrator integrator(scene, *tracer, settings, sh::Order::L2);
        Measured m;
        for (size_t p = 0; p < probes.size(); ++p) {
            std::vector<double> x[6];
            for (int seed = 0; seed < kSeeds; ++seed) {
                const ProbeSample s = integrator.bakeProbe(probes[p], uint64_t(seed), 0, p);
                m.rays += s.rays;
                for (int a = 0; a < 6; ++a) {
                    const glm::vec3 e = sh::irradiance(s.sh, sh::Order::L2, kAxisNormals[a]);
                    x[a].push_back(double(e.x + e.y + e.z));
                    m.seedTotal[seed] += double(e.x + e.y + e.z);
                }
            }
            for (const std::vector<double>& v : x) {
                const MeanAndError e = meanAndStandardError(v);
                m.variance += e.standardError * e.standardError * kSeeds;
                m.mean2 += e.mean * e.mean;
            }
        }
        return m;
    };
    const Measured cut = measure(1.0f);
    const Measured window = measure(0.25f);
    const double cost_cut = cut.variance / cut.mean2 * double(cut.rays);
    const double cost_window = window.variance / window.mean2 * double(window.rays);
    std::printf("relative variance x rays: window 1 %.4g, 0.25 %.4g (%.2fx); rays %.3g, %.3g\n",
                cost_cut, cost_window, cost_cut / cost_window, double(cut.rays),
                double(window.rays));
    EXPECT_GT(cost_cut / cost_window, 1.4);
    const MeanAndError total_cut = meanAndStandardError(cut.seedTotal);
    const MeanAndError total_window = meanAndStandardError(window.seedTotal);
    EXPECT_NEAR(total_window.mean, total_cut.mean,
                kSigmas * std::hypot(total_cut.standardError, total_window.standardError));
}

TEST(PathTracerDeterminism, SameInputsBitIdenticalAcrossThreads) {
    Scene scene = emptyScene();
    addBox(scene, glm::vec3(-1.0f), glm::vec3(1.0f),
           addMaterial(scene, glm::vec3(0.6f), glm::vec3(0.0f)));
    addQuad(scene, {-0.3f, 0.99f, -0.3f}, {-0.3f, 0.99f, 0.3f}, {0.3f, 0.99f, 0.3f},
            {0.3f, 0.99f, -0.3f}, addMaterial(scene, glm::vec3(0.0f), glm::vec3(5.0f)));
    PunctualLight light;
    light.position = glm::vec3(0.2f, 0.5f, 0.1f);
    light.intensity = glm::vec3(1.0f);
    scene.lights.push_back(light);
    const auto tracer = boundedTracer(scene);
    ASSERT_TRUE(tracer);
    // Fixed sampling, and adaptive sampling whose probes stop after different batch counts.
    for (const float noise_target : {0.0f, 0.02f}) {
        SCOPED_TRACE(noise_target);
        PathConfig settings;
        settings.samples = 64;
        settings.noiseTarget = noise_target;
        const PathIntegrator integrator(scene, *tracer, settings, sh::Order::L2);
        const glm::vec3 position(0.1f, -0.2f, 0.3f);

        const ProbeSample a = integrator.bakeProbe(position, 5, 2, 11);
        const ProbeSample b = integrator.bakeProbe(position, 5, 2, 11);
        EXPECT_EQ(a.sh, b.sh);
        EXPECT_EQ(a.rays, b.rays);
        EXPECT_NE(a.sh, integrator.bakeProbe(position, 5, 2, 12).sh); // other probe: other noise
        EXPECT_NE(a.sh, integrator.bakeProbe(position, 5, 3, 11).sh); // other volume
        EXPECT_NE(a.sh, integrator.bakeProbe(position, 6, 2, 11).sh); // other seed

        // Probes baked on four threads in interleaved order equal those baked in sequence.
        constexpr int kCount = 16;
        std::vector<ProbeSample> sequential;
        for (int i = 0; i < kCount; ++i) {
            sequential.push_back(integrator.bakeProbe(position, 5, 0, uint64_t(i)));
        }
        std::vector<ProbeSample> parallel(kCount);
        std::vector<std::thread> threads;
        for (int t = 0; t < 4; ++t) {
            threads.emplace_back([&, t] {
                for (int i = kCount - 1 - t; i >= 0; i -= 4) {
                    parallel[i] = integrator.bakeProbe(position, 5, 0, uint64_t(i));
                }
            });
        }
        for (std::thread& thread : threads) {
            thread.join();
        }
        for (int i = 0; i < kCount; ++i) {
            EXPECT_EQ(parallel[i].sh, sequential[i].sh) << "probe " << i;
            EXPECT_EQ(parallel[i].rays, sequential[i].rays) << "probe " << i;
            EXPECT_EQ(parallel[i].samples, sequential[i].samples) << "probe " << i;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Adaptive sampling (PathConfig::noiseTarget).

// Irradiance at the six axis normals, three channels: the error measure adaptive sampling
// estimates its noise in (irradiance_error.hpp).
std::array<double, 18> axisIrradiance(const sh::ShRgb& sh) {
    std::array<double, 18> out{};
    for (size_t a = 0; a < std::size(kAxisNormals); ++a) {
        const glm::vec3 e = sh::irradiance(sh, sh::Order::L2, kAxisNormals[a]);
        for (int c = 0; c < 3; ++c) {
            out[3 * a + size_t(c)] = e[c];
        }
    }
    return out;
}

sh::ShRgb toFloat(const ShDouble& d) {
    sh::ShRgb out{};
    for (int c = 0; c < sh::kMaxCoefficients; ++c) {
        out.rgb[c] = glm::vec3(d[c]);
    }
    return out;
}

// kCalibrationProbes independent adaptive probes at `position` against the exact `reference`:
//  * the noise each probe reports is unbiased given where it stopped: D_i = |E_i - E*|^2 -
//    noise_i^2 |E_i|^2 (squared error minus the variance it claims, summed over the 18 axis
//    components) has mean 0; checked as a z-score, |mean D| <= kSigmas x its standard error.
//    (Measured: without stopping the ratio of measured to claimed variance is 1.01 and 1.08;
//    with it 0.85 on the square over the floor, z = -2.8: a probe that drew a rare bright path
//    early keeps it in its spread while it traces on, so stopping errs towards more samples);
//  * the stopped estimates themselves are unbiased (expectShMatches on their mean: stopping
//    on a low noise estimate must not pull the mean);
//  * every probe below the cap met the target.
// Returns the mean directions per probe.
constexpr int kCalibrationProbes = 256;
double expectAdaptiveCalibrated(const std::string& what, const Scene& scene,
                                const RayTracer& tracer, const PathConfig& settings,
                                glm::vec3 position, const ShDouble& reference) {
    const auto probes =
        bakeProbes(scene, tracer, settings, sh::Order::L2, position, kCalibrationProbes, 7);
    const std::array<double, 18> exact = axisIrradiance(toFloat(reference));
    std::vector<double> d;
    double claimed = 0.0, samples = 0.0;
    for (const ProbeSample& p : probes) {
        const std::array<double, 18> e = axisIrradiance(p.sh);
        double error2 = 0.0, magnitude2 = 0.0;
        for (size_t c = 0; c < e.size(); ++c) {
            error2 += (e[c] - exact[c]) * (e[c] - exact[c]);
            magnitude2 += e[c] * e[c];
        }
        const double variance = double(p.noise) * double(p.noise) * magnitude2;
        d.push_back(error2 - variance);
        claimed += variance / kCalibrationProbes;
        samples += double(p.samples) / kCalibrationProbes;
        if (p.samples < settings.maxSamples) {
            EXPECT_LE(p.noise, settings.noiseTarget) << what;
        }
    }
    double mean = 0.0, spread = 0.0;
    for (double x : d) {
        mean += x / double(d.size());
    }
    for (double x : d) {
        spread += (x - mean) * (x - mean) / double(d.size() - 1);
    }
    const double standard_error = std::sqrt(spread / double(d.size()));
    EXPECT_LE(std::abs(mean), kSigmas * standard_error)
        << what << ": mean squared error " << mean + claimed << " against the claimed variance "
        << claimed << " (ratio " << (mean + claimed) / claimed << ")";
    expectShMatches(what, estimate(probes), reference, sh::Order::L2);
    std::printf("%s: measured / claimed variance %.3f (z %.2f), %.0f directions per probe\n",
                what.c_str(), (mean + claimed) / claimed, mean / standard_error, samples);
    return samples;
}

// The furnace (every direction sees radiance Le / (1 - a), all noise from Russian roulette)
// and the emissive square over a floor (noise from next-event estimation, MIS and the
// floor's reflection); references as in their fixed-sampling tests above.
TEST(PathTracerAdaptive, NoiseEstimateUnbiasedOnAnalyticScenes) {
    {
        Scene scene = emptyScene();
        addIcosphere(scene, glm::vec3(0.0f), 1.0f, 3,
                     addMaterial(scene, glm::vec3(0.8f), glm::vec3(1.0f)));
        const auto tracer = boundedTracer(scene);
        ASSERT_TRUE(tracer);
        PathConfig settings;
        settings.samples = 128;
        // Low enough that the furnace's probes need about four times their minimum (the
        // roulette's weight window, path.roulette_weight, left 0.03 met near the minimum).
        settings.noiseTarget = 0.02f;
        const double mean_samples = expectAdaptiveCalibrated(
            "furnace", scene, *tracer, settings, glm::vec3(0.1f, -0.2f, 0.15f),
            constantSh(glm::dvec3(std::sqrt(4.0 * kPi) * 5.0)));
        EXPECT_GT(mean_samples, 2.0 * settings.samples); // the target, not the minimum, ruled
    }
    {
        QuadOverFloor c = quadOverFloor();
        const auto tracer = boundedTracer(c.scene);
        ASSERT_TRUE(tracer);
        const Scene& scene = c.scene;
        const glm::dvec3 probe = c.probe;
        const ShDouble& reference = c.reference;
        PathConfig settings;
        settings.samples = 128;
        settings.maxBounces = 4;
        // The estimate alone: every probe held at its minimum (8 batches of 16, then of 128),
        // so no stopping decision is involved.
        settings.noiseTarget = 1e-6f;
        settings.maxSamples = 128;
        expectAdaptiveCalibrated("quad over floor, 8 x 16", scene, *tracer, settings,
                                 glm::vec3(probe), reference);
        settings.samples = 1024;
        settings.maxSamples = 1024;
        expectAdaptiveCalibrated("quad over floor, 8 x 128", scene, *tracer, settings,
                                 glm::vec3(probe), reference);
        // With the stopping rule.
        settings.samples = 128;
        settings.maxSamples = 65536;
        settings.noiseTarget = 0.01f;
        const double mean_samples = expectAdaptiveCalibrated("quad over floor", scene, *tracer,
                                                             settings, glm::vec3(probe), reference);
        EXPECT_GT(mean_samples, 2.0 * settings.samples);
    }
}

// Batch plan: kMinBatches batches of a power of two from the minimum, the cap in whole batches.
TEST(PathTracerAdaptive, BatchPlanFollowsTheMinimumAndTheCap) {
    PathConfig s;
    s.samples = 1024;
    s.maxSamples = 65536;
    BatchPlan p = batchPlan(s);
    EXPECT_EQ(p.size, 128u);
    EXPECT_EQ(p.minBatches, 8u);
    EXPECT_EQ(p.maxBatches, 512u);
    s.samples = 100; // 12.5 per batch: the smallest batch, 8 of them
    p = batchPlan(s);
    EXPECT_EQ(p.size, kMinBatchSize);
    EXPECT_EQ(p.minBatches, 8u);
    s.samples = 1u << 20; // the largest batch, as many as the minimum needs
    s.maxSamples = 1000;  // a cap under the minimum gives way to it
    p = batchPlan(s);
    EXPECT_EQ(p.size, kMaxBatchSize);
    EXPECT_EQ(p.minBatches, 1024u);
    EXPECT_EQ(p.maxBatches, 1024u);
}

// The environment pdf is constant per pixel and sums to one over the pixels; a sampled
// direction reports the pdf that environmentPdf gives it. Emitter area pdfs sum to one.
TEST(PathTracerLightSampler, PdfsAreNormalisedAndConsistentWithSampling) {
    Scene scene = emptyScene();
    scene.environment = syntheticSky(true);
    addQuad(scene, {0, 0, 0}, {0, 0, 1}, {2, 0, 1}, {2, 0, 0},
            addMaterial(scene, glm::vec3(0.0f), glm::vec3(1.0f, 2.0f, 3.0f)));
    addTriangle(scene, {0, 1, 0}, {0, 1, 3}, {1, 1, 0},
                addMaterial(scene, glm::vec3(0.0f), glm::vec3(4.0f)));
    addTriangle(scene, {0, 2, 0}, {0, 2, 3}, {1, 2, 0}, 0); // not emissive
    const LightSampler sampler(scene);
    ASSERT_TRUE(sampler.hasEmitters());
    ASSERT_TRUE(sampler.hasEnvironmentSampling());

    double emitter_total = 0.0;
    for (uint32_t tri = 0; tri < scene.triangles.size(); ++tri) {
        const glm::uvec3 t = scene.triangles[tri];
        const double area =
            0.5 * glm::length(glm::cross(scene.positions[t.y] - scene.positions[t.x],
                                         scene.positions[t.z] - scene.positions[t.x]));
        emitter_total += sampler.emitterPdfArea(tri) * area;
    }
    EXPECT_NEAR(emitter_total, 1.0, 1e-6);
    EXPECT_EQ(sampler.emitterPdfArea(3), 0.0f);

    const Image& image = scene.environment.image;
    const double rotation = glm::radians(double(scene.environment.rotationDeg));
    double env_total = 0.0;
    for (uint32_t y = 0; y < image.height; ++y) {
        const double solid_angle =
            2.0 * kPi / image.width *
            (std::cos(kPi * y / image.height) - std::cos(kPi * (y + 1) / image.height));
        for (uint32_t x = 0; x < image.width; ++x) {
            const double theta = kPi * (y + 0.5) / image.height;
            const double phi = 2.0 * kPi * (x + 0.5) / image.width;
            const glm::dvec3 l(std::sin(theta) * std::sin(phi), std::cos(theta),
                               -std::sin(theta) * std::cos(phi));
            const glm::dvec3 d(std::cos(rotation) * l.x + std::sin(rotation) * l.z, l.y,
                               -std::sin(rotation) * l.x + std::cos(rotation) * l.z);
            env_total += sampler.environmentPdf(glm::vec3(d)) * solid_angle;
        }
    }
    EXPECT_NEAR(env_total, 1.0, 1e-5);

    Rng rng(9);
    int mismatches = 0;
    for (int i = 0; i < 2000; ++i) {
        const double u_row = rng.uniformDouble();
        const double u_column = rng.uniformDouble();
        const LightSampler::DirectionSample s =
            sampler.sampleEnvironment(u_row, u_column, rng.uniform2());
        EXPECT_NEAR(glm::length(s.direction), 1.0f, 1e-5f);
        EXPECT_GT(s.pdf, 0.0f);
        // Directions within float rounding of a pixel edge may be looked up in the neighbour.
        mismatches += std::abs(sampler.environmentPdf(s.direction) - s.pdf) > 1e-4f * s.pdf;
    }
    EXPECT_LE(mismatches, 2);

    for (int i = 0; i < 200; ++i) {
        const LightSampler::EmitterSample s =
            sampler.sampleEmitter(rng.uniformDouble(), rng.uniform2());
        ASSERT_LT(s.triangle, 3u);
        EXPECT_EQ(s.pdfArea, sampler.emitterPdfArea(s.triangle));
        EXPECT_GE(s.bary.x, 0.0f);
        EXPECT_GE(s.bary.y, 0.0f);
        EXPECT_LE(s.bary.x + s.bary.y, 1.0f + 1e-6f);
    }
}

// The table-driven Sobol dimensions equal the textbook definition (XOR of direction numbers
// over the index bits).
TEST(PathTracerSampling, SobolDimensionsMatchDirectionNumbers) {
    Rng rng(17);
    for (int i = 0; i < 2000; ++i) {
        const auto index = uint32_t(rng.nextBits());
        uint32_t x0 = 0, x1 = 0;
        uint32_t v1 = 0x80000000u;
        for (uint32_t bit = 0; bit < 32; ++bit, v1 ^= v1 >> 1) {
            if (index & (1u << bit)) {
                x0 ^= 0x80000000u >> bit;
                x1 ^= v1;
            }
        }
        EXPECT_EQ(sobolDimension0(index), x0);
        EXPECT_EQ(sobolDimension1(index), x1);
    }
    // The first points of dimension 1: 0, 1/2, 3/4, 1/4, 5/8, 1/8.
    const double expected[6] = {0.0, 0.5, 0.75, 0.25, 0.625, 0.125};
    for (uint32_t i = 0; i < 6; ++i) {
        EXPECT_EQ(sobolDimension1(i) * 0x1p-32, expected[i]);
    }
}

// The scrambled Sobol points: the first 2^k stratify the square in every elementary interval.
TEST(PathTracerSampling, ScrambledSobolIsANet) {
    constexpr uint32_t kLog2 = 8;
    for (const uint32_t seed : {1u, 0xdeadbeefu}) {
        for (uint32_t a = 0; a <= kLog2; ++a) {
            const uint32_t nx = 1u << a;
            const uint32_t ny = 1u << (kLog2 - a);
            std::vector<int> counts(size_t(nx) * ny, 0);
            for (uint32_t i = 0; i < (1u << kLog2); ++i) {
                const glm::vec2 p = scrambledSobol2d(i, seed);
                ASSERT_GE(p.x, 0.0f);
                ASSERT_LT(p.x, 1.0f);
                counts[uint32_t(p.y * ny) * nx + uint32_t(p.x * nx)] += 1;
            }
            for (int c : counts) {
                EXPECT_EQ(c, 1) << "elementary intervals " << nx << " x " << ny;
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// bench-rays.

TEST(BenchRays, PositiveThroughputOnSmallScene) {
    Scene scene = emptyScene();
    addIcosphere(scene, glm::vec3(0.0f), 1.0f, 2, 0);
    addBox(scene, glm::vec3(-3.0f), glm::vec3(3.0f), 0);
    computeBounds(scene);
    const Result<RayThroughput> result = measureRayThroughput(scene, 20000, 2);
    ASSERT_TRUE(result.ok()) << result.error().message;
    EXPECT_GT(result.value().closestHitMraysPerSec, 0.0);
    EXPECT_GT(result.value().occlusionMraysPerSec, 0.0);
    EXPECT_EQ(result.value().rays, 20000u);
    EXPECT_EQ(result.value().threads, 2u);
    EXPECT_FALSE(measureRayThroughput(scene, 0, 2).ok());
}

} // namespace
} // namespace probekit::baker
