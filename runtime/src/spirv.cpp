// The SPIR-V of shaders/, embedded: runtime/CMakeLists.txt compiles each shader with glslc at
// build time into a comma-separated word list (glslc -mfmt=num) that is included here.
#include <cstdint>
#include <span>

#include "vk_util.hpp"

namespace probekit::runtime::detail::spirv {
namespace {

constexpr uint32_t kGbufferVert[] = {
#include "gbuffer.vert.inc"
};
constexpr uint32_t kProbeSphereVert[] = {
#include "probe_sphere.vert.inc"
};
constexpr uint32_t kGbufferFrag[] = {
#include "gbuffer.frag.inc"
};
constexpr uint32_t kBackgroundVert[] = {
#include "background.vert.inc"
};
constexpr uint32_t kBackgroundFrag[] = {
#include "background.frag.inc"
};
constexpr uint32_t kShadeComp[] = {
#include "shade.comp.inc"
};
constexpr uint32_t kShadeProbeViewsComp[] = {
#include "shade_probe_views.comp.inc"
};
constexpr uint32_t kShadeFetchOnlyComp[] = {
#include "shade_fetch_only.comp.inc"
};
constexpr uint32_t kIrradiancePointsComp[] = {
#include "irradiance_points.comp.inc"
};

} // namespace

std::span<const uint32_t> gbufferVert() {
    return kGbufferVert;
}
std::span<const uint32_t> probeSphereVert() {
    return kProbeSphereVert;
}
std::span<const uint32_t> gbufferFrag() {
    return kGbufferFrag;
}
std::span<const uint32_t> backgroundVert() {
    return kBackgroundVert;
}
std::span<const uint32_t> backgroundFrag() {
    return kBackgroundFrag;
}
std::span<const uint32_t> shadeComp() {
    return kShadeComp;
}
std::span<const uint32_t> shadeProbeViewsComp() {
    return kShadeProbeViewsComp;
}
std::span<const uint32_t> shadeFetchOnlyComp() {
    return kShadeFetchOnlyComp;
}
std::span<const uint32_t> irradiancePointsComp() {
    return kIrradiancePointsComp;
}

} // namespace probekit::runtime::detail::spirv
