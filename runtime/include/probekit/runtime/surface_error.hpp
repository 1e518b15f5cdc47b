// Per-pixel error of a volume's shading against a path-traced surface reference
// (docs/accuracy.md#surface-accuracy): what a user sees, where every other accuracy figure of
// probekit is taken at points in free space.
//
// Both images are the same view, pixel for pixel: the reference holds, per pixel, the surface
// point, its shading normal, the path-traced irradiance and that estimate's standard error
// (baker/include/probekit/baker/surface_reference.hpp; the EXR `probekit render --view
// irradiance-reference` writes); the test holds E per pixel (`probekit render --view irradiance`,
// or the CPU sampler at the reference's own points). Values compare by luminance,
// Y = 0.2126 R + 0.7152 G + 0.0722 B of E in W/m^2.
//
// Which pixels count:
//  * surface pixels: those the reference hit;
//  * edge pixels are left out of the ratios: a surface pixel with, within `edgePixels` pixels
//    (the square around it), a background pixel, a normal more than kEdgeNormalDegrees away,
//    or a point off its own tangent plane (|n . (q - p)| > kEdgePlaneSlope |q - p|: a step in
//    depth). A rasteriser and a ray tracer disagree there by a pixel, and a one-pixel shift
//    across a silhouette is no shading error;
//  * dark pixels (reference Y below kDarkShare x the median reference Y) are left out of the
//    ratios too (a ratio to nothing); they still count for negative light.
// Figures, over the compared pixels (surface, not edge, not dark):
//  * medianAbsError: median |Y - Y_ref| / Y_ref;  meanRatio: mean of Y / Y_ref;
//  * shareUnderHalf / shareOverTwo: share with Y < 0.5 Y_ref / Y > 2 Y_ref;
// and over every surface pixel: shareNegative, the share with E < 0 in any channel.
// Reference noise: referenceNoise is the median relative standard error of Y_ref over the
// compared pixels; a perfect test image would still measure a median abs error of about
// noiseFloor = 0.6745 x referenceNoise (the median of |N(0, s)| is 0.6745 s), so a figure near
// noiseFloor is noise of the reference, not error of the volume.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/result.hpp"

namespace probekit::runtime {

constexpr int kEdgePixels = 2;
constexpr float kEdgeNormalDegrees = 20.0f;
constexpr float kEdgePlaneSlope = 0.25f;
constexpr float kDarkShare = 1e-3f;

// Pixel (x, y) at x + width * y, row 0 at the top.
struct SurfaceReferenceImage {
    uint32_t width = 0;
    uint32_t height = 0;
    std::vector<uint8_t> hit;             // 1 where the view sees a surface
    std::vector<glm::vec3> position;      // metres, world
    std::vector<glm::vec3> normal;        // unit shading normal
    std::vector<glm::vec3> irradiance;    // E, W/m^2
    std::vector<glm::vec3> standardError; // of irradiance, W/m^2
};

struct SurfaceError {
    size_t surfacePixels = 0;
    size_t edgePixels = 0;
    size_t darkPixels = 0;
    size_t compared = 0;
    double medianAbsError = 0.0;
    double meanRatio = 0.0;
    double shareUnderHalf = 0.0;
    double shareOverTwo = 0.0;
    double shareNegative = 0.0;
    double referenceNoise = 0.0;
    double noiseFloor = 0.0;
    // Per pixel: log2(Y / Y_ref) where compared; NaN on edge and dark pixels and -inf where
    // Y <= 0 (compared pixels only); 0 on background. For the heat map.
    std::vector<float> log2Ratio;
    std::vector<uint8_t> category; // 0 background, 1 compared, 2 edge, 3 dark
};

// The edge mask above (1 = edge) for a reference image.
std::vector<uint8_t> surfaceEdges(const SurfaceReferenceImage& reference);

// Fails with InvalidArgument when `test` does not hold width x height pixels or the reference's
// arrays disagree in size.
Result<SurfaceError> compareSurface(const std::vector<glm::vec3>& test,
                                    const SurfaceReferenceImage& reference);

// Y of an RGB irradiance (Rec. 709 weights).
inline double surfaceLuminance(glm::vec3 e) {
    return 0.2126 * double(e.x) + 0.7152 * double(e.y) + 0.0722 * double(e.z);
}

} // namespace probekit::runtime
