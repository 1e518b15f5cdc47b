// probekit::baker::LightSampler — next-event-estimation distributions for the path integrator.
//
// Built once per integrator from a Scene, immutable, thread-safe:
//  * Emissive triangles: one triangle is picked with probability proportional to
//    area x luminance(material emission factor) (for textured emission the factor stands in for
//    the texture average: any positive weight keeps the estimator unbiased), then a point is
//    sampled uniformly on its area. Emitters are two-sided (Scene's convention), so the
//    solid-angle pdf uses |cos| at the emitter.
//  * Lat-long environment: a 2D piecewise-constant distribution over the image pixels. A pixel's
//    weight is the luminance of Environment::radiance averaged over the pixel (the bilinear
//    reconstruction averages to 1/8, 3/4, 1/8 of the neighbouring texels per axis) times the
//    pixel's exact solid angle; inside the pixel the direction is uniform in solid angle
//    (phi uniform, cos theta uniform), so the solid-angle pdf is constant per pixel.
//    Constant environments are not importance sampled (cosine sampling already matches them).
//
// Probabilities are kept as CDFs whose differences are the pdfs returned, and CDFs are inverted
// with 53-bit uniforms, so the pdf reported is the probability actually sampled: the estimators
// that divide by it are unbiased even for entries far below float resolution.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "probekit/baker/scene.hpp"

namespace probekit::baker {

class LightSampler {
public:
    // Copies what it samples from `scene` (emitter geometry, environment CDFs and rotation).
    explicit LightSampler(const Scene& scene);

    struct EmitterSample {
        uint32_t triangle = 0;
        glm::vec2 bary{0.0f};     // Embree (u, v) of the point
        glm::vec3 position{0.0f}; // world
        glm::vec3 normal{0.0f};   // unit geometric normal of the triangle (winding)
        float pdfArea = 0.0f;     // pick probability / triangle area, 1/m^2
    };

    bool hasEmitters() const { return !m_emitters.empty(); }
    // Precondition: hasEmitters(). `u_pick` and `u_area` uniform in [0, 1).
    EmitterSample sampleEmitter(double u_pick, glm::vec2 u_area) const;
    // Area pdf of sampling a point on `triangle` (0 for non-emitters).
    float emitterPdfArea(uint32_t triangle) const {
        return m_pdfArea.empty() ? 0.0f : m_pdfArea[triangle];
    }

    struct DirectionSample {
        glm::vec3 direction{0.0f}; // unit, world, pointing away from the scene
        float pdf = 0.0f;          // solid angle, 1/sr
    };

    bool hasEnvironmentSampling() const { return !m_rowCdf.empty(); }
    // Precondition: hasEnvironmentSampling(). Uniforms in [0, 1).
    DirectionSample sampleEnvironment(double u_row, double u_column, glm::vec2 u_pixel) const;
    // Solid-angle pdf with which sampleEnvironment returns `dir` (unit, world).
    float environmentPdf(glm::vec3 dir) const;

private:
    // The emitter table: emissive triangles weighted by area x luminance, and each one's pdf.
    void buildEmitterTable(const Scene& scene);
    // The environment's row and column CDFs; leaves them empty for a black or constant sky.
    void buildEnvironmentTables(const Environment& env);

    // Emitters: their geometry (kept together for cache locality when sampling), CDF over them
    // (size + 1 entries, last exactly 1), and a dense per-triangle area pdf (empty when the
    // scene has no emitter).
    struct Emitter {
        glm::vec3 p0, edge1, edge2; // p0 + u edge1 + v edge2
        glm::vec3 normal;           // unit, winding
        uint32_t triangle;
    };
    std::vector<Emitter> m_emitters;
    std::vector<double> m_emitterCdf;
    std::vector<float> m_pdfArea;

    // Environment: row CDF (height + 1), per-row column CDFs (height x (width + 1), float to
    // halve the memory of large maps; the pdf is their difference, so still exact), cos(theta)
    // at the row edges (height + 1), and the solid angle of one pixel of each row.
    uint32_t m_width = 0;
    uint32_t m_height = 0;
    std::vector<double> m_rowCdf;
    std::vector<float> m_columnCdf;
    std::vector<double> m_edgeCos;
    std::vector<double> m_pixelSolidAngle;
    float m_rotationCos = 1.0f;
    float m_rotationSin = 0.0f;
};

} // namespace probekit::baker
