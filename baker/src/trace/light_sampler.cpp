#include "trace/light_sampler.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

#include <glm/geometric.hpp>

#include "trace/sampling.hpp"

namespace probekit::baker {

namespace {

// Index i with cdf[i] <= u < cdf[i + 1] for u in [0, 1): never an empty interval.
template <class T>
uint32_t invertCdf(const T* cdf, uint32_t count, double u) {
    const T* upper = std::upper_bound(cdf, cdf + count + 1, u);
    const auto index = uint32_t(upper - cdf) - 1;
    return std::min(index, count - 1);
}

// The texels' luminance, each the average of the bilinear reconstruction over its pixel along the
// row, with the repeat wrapping that Image::sampleBilinear uses: the filter (1/8, 3/4, 1/8).
constexpr double kSide = 0.125;
constexpr double kCentre = 0.75;

std::vector<double> rowFilteredLuminance(const Image& image) {
    const uint32_t w = image.width;
    const uint32_t h = image.height;
    std::vector<double> texel_luminance(size_t(w) * h);
    for (size_t i = 0; i < texel_luminance.size(); ++i) {
        texel_luminance[i] = std::max(0.0, luminance(glm::vec3(image.texels[i])));
    }
    std::vector<double> rows_filtered(texel_luminance.size());
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; ++x) {
            const uint32_t left = (x + w - 1) % w;
            const uint32_t right = (x + 1) % w;
            const double* row = &texel_luminance[size_t(y) * w];
            rows_filtered[size_t(y) * w + x] =
                kSide * row[left] + kCentre * row[x] + kSide * row[right];
        }
    }
    return rows_filtered;
}

} // namespace

LightSampler::LightSampler(const Scene& scene) {
    buildEmitterTable(scene);
    buildEnvironmentTables(scene.environment);
}

void LightSampler::buildEmitterTable(const Scene& scene) {
    // Emissive triangles, weighted by area x luminance of the emission factor.
    std::vector<double> weights;
    for (uint32_t tri = 0; tri < uint32_t(scene.triangles.size()); ++tri) {
        const Material& material = scene.materials[scene.triangleMaterial[tri]];
        if (!material.isEmissive()) {
            continue;
        }
        const glm::uvec3 t = scene.triangles[tri];
        const glm::vec3 p0 = scene.positions[t.x];
        const glm::vec3 e1 = scene.positions[t.y] - p0;
        const glm::vec3 e2 = scene.positions[t.z] - p0;
        const glm::vec3 cross = glm::cross(e1, e2);
        const double area = 0.5 * double(glm::length(cross));
        const double weight = area * luminance(material.emission);
        if (weight > 0.0 && std::isfinite(weight)) {
            m_emitters.push_back(Emitter{p0, e1, e2, glm::normalize(cross), tri});
            weights.push_back(weight);
        }
    }
    if (!m_emitters.empty()) {
        m_emitterCdf.resize(m_emitters.size() + 1);
        m_emitterCdf[0] = 0.0;
        for (size_t i = 0; i < weights.size(); ++i) {
            m_emitterCdf[i + 1] = m_emitterCdf[i] + weights[i];
        }
        const double total = m_emitterCdf.back();
        for (double& c : m_emitterCdf) {
            c /= total;
        }
        m_emitterCdf.back() = 1.0;
        m_pdfArea.assign(scene.triangles.size(), 0.0f);
        for (size_t i = 0; i < m_emitters.size(); ++i) {
            const Emitter& e = m_emitters[i];
            const double area = 0.5 * double(glm::length(glm::cross(e.edge1, e.edge2)));
            m_pdfArea[e.triangle] = float((m_emitterCdf[i + 1] - m_emitterCdf[i]) / area);
        }
    }
}

void LightSampler::buildEnvironmentTables(const Environment& env) {
    // Lat-long environment: piecewise-constant over pixels (see the header for the weights).
    if (env.type != Environment::Type::LatLong || env.isBlack() || env.image.width == 0 ||
        env.image.height == 0) {
        return;
    }
    const uint32_t w = env.image.width;
    const uint32_t h = env.image.height;
    // Then along columns below: the separable average over each pixel.
    const std::vector<double> rows_filtered = rowFilteredLuminance(env.image);
    m_edgeCos.resize(h + 1);
    for (uint32_t y = 0; y <= h; ++y) {
        m_edgeCos[y] = std::cos(std::numbers::pi * double(y) / double(h));
    }
    m_edgeCos[0] = 1.0;
    m_edgeCos[h] = -1.0;
    m_pixelSolidAngle.resize(h);
    for (uint32_t y = 0; y < h; ++y) {
        m_pixelSolidAngle[y] =
            2.0 * std::numbers::pi / double(w) * (m_edgeCos[y] - m_edgeCos[y + 1]);
    }

    std::vector<double> row_weight(h, 0.0);
    m_columnCdf.resize(size_t(h) * (w + 1));
    std::vector<double> column(w + 1);
    for (uint32_t y = 0; y < h; ++y) {
        const uint32_t up = (y + h - 1) % h;
        const uint32_t down = (y + 1) % h;
        column[0] = 0.0;
        for (uint32_t x = 0; x < w; ++x) {
            const double average = kSide * rows_filtered[size_t(up) * w + x] +
                                   kCentre * rows_filtered[size_t(y) * w + x] +
                                   kSide * rows_filtered[size_t(down) * w + x];
            column[x + 1] = column[x] + average;
        }
        float* cdf = &m_columnCdf[size_t(y) * (w + 1)];
        const double total = column[w];
        for (uint32_t x = 0; x <= w; ++x) {
            cdf[x] = total > 0.0 ? float(column[x] / total) : float(x) / float(w);
        }
        cdf[w] = 1.0f;
        row_weight[y] = total * m_pixelSolidAngle[y];
    }
    double row_total = 0.0;
    for (double r : row_weight) {
        row_total += r;
    }
    if (!(row_total > 0.0) || !std::isfinite(row_total)) {
        m_columnCdf.clear();
        m_edgeCos.clear();
        m_pixelSolidAngle.clear();
        return;
    }
    m_rowCdf.resize(h + 1);
    m_rowCdf[0] = 0.0;
    for (uint32_t y = 0; y < h; ++y) {
        m_rowCdf[y + 1] = m_rowCdf[y] + row_weight[y] / row_total;
    }
    m_rowCdf[h] = 1.0;
    m_width = w;
    m_height = h;
    const float angle = env.rotationDeg * std::numbers::pi_v<float> / 180.0f;
    m_rotationCos = std::cos(angle);
    m_rotationSin = std::sin(angle);
}

LightSampler::EmitterSample LightSampler::sampleEmitter(double u_pick, glm::vec2 u_area) const {
    assert(hasEmitters());
    const uint32_t k = invertCdf(m_emitterCdf.data(), uint32_t(m_emitters.size()), u_pick);
    const Emitter& e = m_emitters[k];
    EmitterSample s;
    s.triangle = e.triangle;
    // Uniform on the triangle: b = (sqrt(u1) (1 - u2), sqrt(u1) u2) (Turk, Graphics Gems 1990).
    const float su = std::sqrt(u_area.x);
    s.bary = glm::vec2(su * (1.0f - u_area.y), su * u_area.y);
    s.position = e.p0 + s.bary.x * e.edge1 + s.bary.y * e.edge2;
    s.normal = e.normal;
    s.pdfArea = m_pdfArea[s.triangle];
    return s;
}

LightSampler::DirectionSample LightSampler::sampleEnvironment(double u_row, double u_column,
                                                              glm::vec2 u_pixel) const {
    assert(hasEnvironmentSampling());
    const uint32_t y = invertCdf(m_rowCdf.data(), m_height, u_row);
    const float* cdf = &m_columnCdf[size_t(y) * (m_width + 1)];
    const uint32_t x = invertCdf(cdf, m_width, u_column);
    // Uniform in solid angle inside the pixel: phi and cos(theta) uniform over its extent.
    const double phi = 2.0 * std::numbers::pi * (double(x) + double(u_pixel.x)) / double(m_width);
    const double cos_theta = m_edgeCos[y] + double(u_pixel.y) * (m_edgeCos[y + 1] - m_edgeCos[y]);
    const double sin_theta = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
    // Image frame (scene.hpp): dir = (sin t sin p, cos t, -sin t cos p); then the rotation about
    // +Y that Environment::radiance undoes.
    const glm::vec3 local(float(sin_theta * std::sin(phi)), float(cos_theta),
                          float(-sin_theta * std::cos(phi)));
    DirectionSample s;
    s.direction = glm::vec3(m_rotationCos * local.x + m_rotationSin * local.z, local.y,
                            -m_rotationSin * local.x + m_rotationCos * local.z);
    const double probability =
        (m_rowCdf[y + 1] - m_rowCdf[y]) * (double(cdf[x + 1]) - double(cdf[x]));
    s.pdf = float(probability / m_pixelSolidAngle[y]);
    return s;
}

float LightSampler::environmentPdf(glm::vec3 dir) const {
    assert(hasEnvironmentSampling());
    // Into the image frame (the inverse of the rotation in sampleEnvironment).
    const glm::vec3 d(m_rotationCos * dir.x - m_rotationSin * dir.z, dir.y,
                      m_rotationSin * dir.x + m_rotationCos * dir.z);
    const double cos_theta = std::clamp(double(d.y), -1.0, 1.0);
    // Row from theta, then nudged so that edgeCos[y] >= cos_theta >= edgeCos[y + 1] holds with
    // the same edges the sampler used.
    auto y = uint32_t(
        std::min(double(m_height - 1), std::acos(cos_theta) / std::numbers::pi * double(m_height)));
    while (y > 0 && cos_theta > m_edgeCos[y]) {
        --y;
    }
    while (y + 1 < m_height && cos_theta < m_edgeCos[y + 1]) {
        ++y;
    }
    double phi = std::atan2(double(d.x), -double(d.z));
    if (phi < 0.0) {
        phi += 2.0 * std::numbers::pi;
    }
    const auto x =
        uint32_t(std::min(double(m_width - 1), phi / (2.0 * std::numbers::pi) * double(m_width)));
    const float* cdf = &m_columnCdf[size_t(y) * (m_width + 1)];
    const double probability =
        (m_rowCdf[y + 1] - m_rowCdf[y]) * (double(cdf[x + 1]) - double(cdf[x]));
    return float(probability / m_pixelSolidAngle[y]);
}

} // namespace probekit::baker
