// probekit::viewer — the per-pixel surface reference of a view: the baker traces it
// (baker/surface_reference.hpp) along the renderer's pixel rays, and the runtime compares a
// render or a volume against it (runtime/surface_error.hpp).
#pragma once

#include <cstdint>
#include <vector>

#include "probekit/baker/surface_reference.hpp"
#include "probekit/runtime/renderer.hpp"
#include "probekit/runtime/surface_error.hpp"

namespace probekit::viewer {

// One ray per pixel centre of a w x h view (runtime::pixelDirection), row 0 at the top: traced
// by the surface reference, its pixels are the renderer's.
std::vector<baker::SurfaceRay> viewRays(const runtime::Camera& camera, uint32_t w, uint32_t h);

// A traced surface reference (one sample per ray of viewRays) as the image
// runtime::compareSurface takes.
runtime::SurfaceReferenceImage referenceImage(const baker::SurfaceReference& traced, uint32_t w,
                                              uint32_t h);

} // namespace probekit::viewer
