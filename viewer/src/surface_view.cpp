// The per-pixel surface reference of a view (viewer/include/probekit/viewer/surface_view.hpp).
#include "probekit/viewer/surface_view.hpp"

namespace probekit::viewer {

std::vector<baker::SurfaceRay> viewRays(const runtime::Camera& camera, uint32_t w, uint32_t h) {
    std::vector<baker::SurfaceRay> rays;
    rays.reserve(size_t(w) * h);
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; ++x) {
            rays.push_back(
                {camera.eye, runtime::pixelDirection(camera, w, h, glm::vec2(x + 0.5f, y + 0.5f))});
        }
    }
    return rays;
}

runtime::SurfaceReferenceImage referenceImage(const baker::SurfaceReference& traced, uint32_t w,
                                              uint32_t h) {
    runtime::SurfaceReferenceImage image;
    image.width = w;
    image.height = h;
    for (const baker::SurfaceSample& s : traced.samples) {
        image.hit.push_back(s.hit ? 1 : 0);
        image.position.push_back(s.position);
        image.normal.push_back(s.normal);
        image.irradiance.push_back(s.irradiance);
        image.standardError.push_back(s.standardError);
    }
    return image;
}

} // namespace probekit::viewer
