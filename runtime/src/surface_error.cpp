#include "probekit/runtime/surface_error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <glm/geometric.hpp>

namespace probekit::runtime {

namespace {

double medianOf(std::vector<double> values) {
    if (values.empty()) {
        return 0.0;
    }
    const size_t mid = values.size() / 2;
    std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(mid), values.end());
    const double upper = values[mid];
    if (values.size() % 2 == 1) {
        return upper;
    }
    return 0.5 * (upper + *std::max_element(values.begin(), values.begin() + std::ptrdiff_t(mid)));
}

} // namespace

std::vector<uint8_t> surfaceEdges(const SurfaceReferenceImage& r) {
    const float min_dot = std::cos(kEdgeNormalDegrees * std::numbers::pi_v<float> / 180.0f);
    std::vector<uint8_t> edge(size_t(r.width) * r.height, 0);
    for (uint32_t y = 0; y < r.height; ++y) {
        for (uint32_t x = 0; x < r.width; ++x) {
            const size_t i = x + size_t(r.width) * y;
            if (!r.hit[i]) {
                continue;
            }
            bool is_edge = false;
            for (int dy = -kEdgePixels; dy <= kEdgePixels && !is_edge; ++dy) {
                for (int dx = -kEdgePixels; dx <= kEdgePixels && !is_edge; ++dx) {
                    const int64_t qx = int64_t(x) + dx, qy = int64_t(y) + dy;
                    if (qx < 0 || qy < 0 || qx >= int64_t(r.width) || qy >= int64_t(r.height)) {
                        continue; // the image border is not an edge of the geometry
                    }
                    const size_t j = size_t(qx) + size_t(r.width) * size_t(qy);
                    if (!r.hit[j] || glm::dot(r.normal[i], r.normal[j]) < min_dot) {
                        is_edge = true;
                        break;
                    }
                    const glm::vec3 d = r.position[j] - r.position[i];
                    if (std::abs(glm::dot(r.normal[i], d)) > kEdgePlaneSlope * glm::length(d)) {
                        is_edge = true;
                    }
                }
            }
            edge[i] = is_edge ? 1 : 0;
        }
    }
    return edge;
}

Result<SurfaceError> compareSurface(const std::vector<glm::vec3>& test,
                                    const SurfaceReferenceImage& r) {
    const size_t n = size_t(r.width) * r.height;
    if (r.hit.size() != n || r.position.size() != n || r.normal.size() != n ||
        r.irradiance.size() != n || r.standardError.size() != n) {
        return makeError(ErrorCode::InvalidArgument,
                         "compareSurface: the reference's arrays do not hold width x height "
                         "pixels");
    }
    if (test.size() != n) {
        return makeError(ErrorCode::InvalidArgument,
                         "compareSurface: the test image has " + std::to_string(test.size()) +
                             " pixels, the reference " + std::to_string(n));
    }
    SurfaceError out;
    out.log2Ratio.assign(n, 0.0f);
    out.category.assign(n, 0);
    const std::vector<uint8_t> edge = surfaceEdges(r);

    std::vector<double> reference_y;
    size_t negative = 0;
    for (size_t i = 0; i < n; ++i) {
        if (!r.hit[i]) {
            continue;
        }
        ++out.surfacePixels;
        if (test[i].x < 0.0f || test[i].y < 0.0f || test[i].z < 0.0f) {
            ++negative;
        }
        reference_y.push_back(surfaceLuminance(r.irradiance[i]));
    }
    const double dark_below = kDarkShare * medianOf(reference_y);

    std::vector<double> abs_errors, noise;
    double ratio_sum = 0.0;
    size_t under = 0, over = 0;
    for (size_t i = 0; i < n; ++i) {
        if (!r.hit[i]) {
            continue;
        }
        const double y_ref = surfaceLuminance(r.irradiance[i]);
        if (edge[i]) {
            ++out.edgePixels;
            out.category[i] = 2;
            out.log2Ratio[i] = std::numeric_limits<float>::quiet_NaN();
            continue;
        }
        if (!(y_ref > dark_below) || !(y_ref > 0.0)) {
            ++out.darkPixels;
            out.category[i] = 3;
            out.log2Ratio[i] = std::numeric_limits<float>::quiet_NaN();
            continue;
        }
        out.category[i] = 1;
        const double y = surfaceLuminance(test[i]);
        const double ratio = y / y_ref;
        abs_errors.push_back(std::abs(ratio - 1.0));
        ratio_sum += ratio;
        under += ratio < 0.5 ? 1 : 0;
        over += ratio > 2.0 ? 1 : 0;
        out.log2Ratio[i] =
            y > 0.0 ? float(std::log2(ratio)) : -std::numeric_limits<float>::infinity();
        noise.push_back(surfaceLuminance(r.standardError[i]) / y_ref);
    }
    out.compared = abs_errors.size();
    if (out.compared > 0) {
        const double count = double(out.compared);
        out.medianAbsError = medianOf(abs_errors);
        out.meanRatio = ratio_sum / count;
        out.shareUnderHalf = double(under) / count;
        out.shareOverTwo = double(over) / count;
        out.referenceNoise = medianOf(noise);
        out.noiseFloor = 0.6745 * out.referenceNoise;
    }
    if (out.surfacePixels > 0) {
        out.shareNegative = double(negative) / double(out.surfacePixels);
    }
    return out;
}

} // namespace probekit::runtime
