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
constexpr uint32_t kShadeGiComp[] = {
#include "shade_gi.comp.inc"
};
constexpr uint32_t kIrradiancePointsComp[] = {
#include "irradiance_points.comp.inc"
};

constexpr uint32_t kGiGeometryComp[] = {
#include "gi_geometry.comp.inc"
};
constexpr uint32_t kGiSurfaceComp[] = {
#include "gi_surface.comp.inc"
};
constexpr uint32_t kGiInjectComp[] = {
#include "gi_inject.comp.inc"
};
constexpr uint32_t kGiPropagateComp[] = {
#include "gi_propagate.comp.inc"
};
constexpr uint32_t kGiKeepComp[] = {
#include "gi_keep.comp.inc"
};
constexpr uint32_t kGiReduceComp[] = {
#include "gi_reduce.comp.inc"
};
constexpr uint32_t kGiResolveComp[] = {
#include "gi_resolve.comp.inc"
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
std::span<const uint32_t> shadeGiComp() {
    return kShadeGiComp;
}
std::span<const uint32_t> irradiancePointsComp() {
    return kIrradiancePointsComp;
}
std::span<const uint32_t> giGeometryComp() {
    return kGiGeometryComp;
}
std::span<const uint32_t> giSurfaceComp() {
    return kGiSurfaceComp;
}
std::span<const uint32_t> giInjectComp() {
    return kGiInjectComp;
}
std::span<const uint32_t> giPropagateComp() {
    return kGiPropagateComp;
}
std::span<const uint32_t> giKeepComp() {
    return kGiKeepComp;
}
std::span<const uint32_t> giReduceComp() {
    return kGiReduceComp;
}
std::span<const uint32_t> giResolveComp() {
    return kGiResolveComp;
}

} // namespace probekit::runtime::detail::spirv
