#include "trace/ray_tracer.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>

#include "probekit/formats/check.hpp"
#include "scene/coordinate_range.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace probekit::baker {

namespace {

// Every Embree error of the device lands here (ARCHITECTURE.md: one callback, no check after each
// call). create() turns what was collected into its Result.
void onDeviceError(void* user, RTCError code, const char* message) {
    auto* log = static_cast<RayTracer::ErrorLog*>(user);
    const std::lock_guard lock(log->mutex);
    if (!log->messages.empty()) {
        log->messages += "; ";
    }
    log->messages += "Embree error " + std::to_string(int(code)) + ": " + (message ? message : "");
}

// Embree calls this before each allocation (bytes > 0) and after each release (bytes < 0).
bool onMemory(void* user, ssize_t bytes, bool /*post*/) {
    auto* log = static_cast<RayTracer::MemoryLog*>(user);
    const int64_t now = log->current.fetch_add(bytes) + bytes;
    int64_t peak = log->peak.load();
    while (now > peak && !log->peak.compare_exchange_weak(peak, now)) {
    }
    return true; // never refuse: bake() checked the memory model before building
}

Error embreeFailure(RayTracer::ErrorLog& log) {
    const std::lock_guard lock(log.mutex);
    return makeError(ErrorCode::InvalidArgument, "ray tracer: " + log.messages);
}

bool hasErrors(RayTracer::ErrorLog& log) {
    const std::lock_guard lock(log.mutex);
    return !log.messages.empty();
}

// Embree's rule for a ray it can trace (RayK::valid, checked only in its debug builds; a release
// build traces such a ray into garbage): every origin and direction component at most
// FLT_LARGE (1.844e18) in magnitude and not NaN, and t_max >= 0. Input is held within
// kMaxCoordinate (coordinate_range.hpp) before anything is traced, so a ray failing it is an
// integrator's NaN. It runs on every ray, so without branches: glm::abs would branch on each
// sign (mispredicted half the time for random directions: 20-30% of bench-rays' throughput),
// and vectors assembled in memory stall on store forwarding. As written it costs 2.7% of
// closest-hit and 3.8% of occlusion throughput (probekit bench-rays on engine-mm, one thread,
// medians of 8 runs alternating with a build without it, on a shared 2-core machine).
bool validRay(glm::vec3 origin, glm::vec3 dir, float t_max) {
    constexpr float kLarge = 1.844e18f;
#if defined(__SSE2__)
    const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 large = _mm_set1_ps(kLarge);
    const __m128 o = _mm_and_ps(_mm_setr_ps(origin.x, origin.y, origin.z, dir.x), magnitude);
    const __m128 d = _mm_and_ps(_mm_setr_ps(dir.y, dir.z, 0.0f, 0.0f), magnitude);
    const __m128 within = _mm_and_ps(_mm_cmple_ps(o, large), _mm_cmple_ps(d, large));
    return (_mm_movemask_ps(within) == 0xf) & (t_max >= 0.0f);
#else
    const auto ok = [&](float x) { return std::abs(x) <= kLarge; };
    return ok(origin.x) && ok(origin.y) && ok(origin.z) && ok(dir.x) && ok(dir.y) && ok(dir.z) &&
           t_max >= 0.0f;
#endif
}

RTCRay makeRay(glm::vec3 origin, glm::vec3 dir, float t_max) {
    RTCRay ray;
    ray.org_x = origin.x;
    ray.org_y = origin.y;
    ray.org_z = origin.z;
    ray.tnear = 0.0f;
    ray.dir_x = dir.x;
    ray.dir_y = dir.y;
    ray.dir_z = dir.z;
    ray.time = 0.0f;
    ray.tfar = t_max;
    ray.mask = 0xffffffffu;
    ray.id = 0;
    ray.flags = 0;
    PK_CHECK(validRay(origin, dir, t_max));
    return ray;
}

} // namespace

namespace {

// Every triangle's corners index a vertex the scene has.
Result<void> checkTriangleIndices(const Scene& scene) {
    const size_t vertex_count = scene.positions.size();
    for (size_t i = 0; i < scene.triangles.size(); ++i) {
        const glm::uvec3 t = scene.triangles[i];
        if (t.x >= vertex_count || t.y >= vertex_count || t.z >= vertex_count) {
            return makeError(ErrorCode::OutOfRange, "ray tracer: triangle " + std::to_string(i) +
                                                        " indexes a vertex past the " +
                                                        std::to_string(vertex_count) + " given");
        }
    }
    return {};
}

} // namespace

void RayTracer::copyGeometry(const Scene& scene) {
    const size_t vertex_count = scene.positions.size();
    // The per-triangle data the queries need, kept in our own arrays so that Embree shares them
    // instead of copying. The vertex array is padded by one element: Embree reads the last
    // vertex with a 16-byte load.
    m_vertices.reserve(vertex_count + 1);
    m_vertices.assign(scene.positions.begin(), scene.positions.end());
    m_vertices.push_back(glm::vec3(0.0f));
    m_indices.reserve(scene.triangles.size() + 1);
    m_indices.assign(scene.triangles.begin(), scene.triangles.end());
    m_indices.push_back(glm::uvec3(0));
    m_normals.resize(scene.triangles.size());
    for (size_t i = 0; i < scene.triangles.size(); ++i) {
        const glm::uvec3 t = scene.triangles[i];
        const glm::vec3 p0 = scene.positions[t.x];
        const glm::vec3 n = glm::cross(scene.positions[t.y] - p0, scene.positions[t.z] - p0);
        const float length = glm::length(n);
        // Zero-area triangles are never hit; their normal stays zero rather than NaN.
        m_normals[i] = length > 0.0f ? n / length : glm::vec3(0.0f);
    }
}

Result<std::unique_ptr<RayTracer>> RayTracer::create(const Scene& scene) {
    // Every tracer, not only the bake's, refuses coordinates its rays cannot leave surfaces at.
    if (Result<void> inside = checkSceneCoordinates(scene); !inside) {
        return inside.error();
    }
    if (Result<void> indexed = checkTriangleIndices(scene); !indexed) {
        return indexed.error();
    }
    const size_t vertex_count = scene.positions.size();

    std::unique_ptr<RayTracer> tracer(new RayTracer());
    // A device of its own per tracer: default configuration (Embree picks the ISA and its TBB
    // build threads); verbose output stays off because libraries never print.
    tracer->m_device = rtcNewDevice("verbose=0");
    if (tracer->m_device == nullptr) {
        // No device means no callback to report through: ask Embree for the creation error.
        return makeError(ErrorCode::InvalidArgument,
                         "ray tracer: Embree could not create a device (error " +
                             std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    }
    // Route every later error of this device to the log that create() reports from.
    rtcSetDeviceErrorFunction(tracer->m_device, onDeviceError, tracer->m_errors.get());
    rtcSetDeviceMemoryMonitorFunction(tracer->m_device, onMemory, tracer->m_memory.get());

    // Two-sided surfaces and validity (back-face counts) both need back-face hits; a build with
    // EMBREE_BACKFACE_CULLING would silently drop half of them.
    if (rtcGetDeviceProperty(tracer->m_device, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED)) {
        return makeError(ErrorCode::InvalidArgument,
                         "ray tracer: this Embree build culls back faces; the baker needs "
                         "two-sided triangles (rebuild Embree without EMBREE_BACKFACE_CULLING)");
    }

    tracer->copyGeometry(scene);

    // One scene per tracer; the bake traces far more rays than the build costs, so spend build
    // time on a better BVH (the scene-level HIGH quality enables the spatial-split builder for
    // triangles; per-geometry quality only matters for two-level LOW builds).
    tracer->m_scene = rtcNewScene(tracer->m_device);
    rtcSetSceneBuildQuality(tracer->m_scene, RTC_BUILD_QUALITY_HIGH);
    if (!scene.triangles.empty()) {
        // All triangles go into one geometry: materials are looked up per triangle index, so a
        // single primitive-ID space is all the integrators need.
        RTCGeometry geometry = rtcNewGeometry(tracer->m_device, RTC_GEOMETRY_TYPE_TRIANGLE);
        // Share our arrays (which outlive the scene) rather than copying them into Embree.
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                   tracer->m_vertices.data(), 0, sizeof(glm::vec3), vertex_count);
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                   tracer->m_indices.data(), 0, sizeof(glm::uvec3),
                                   scene.triangles.size());
        // Finalise the geometry's buffers before the scene references it.
        rtcCommitGeometry(geometry);
        // Geometry ID 0; the scene keeps its own reference, so ours can go at once.
        rtcAttachGeometry(tracer->m_scene, geometry);
        rtcReleaseGeometry(geometry);
    }
    // Build the BVH now, once, so that queries never trigger a build (an empty scene commits to
    // a scene every ray misses).
    rtcCommitScene(tracer->m_scene);

    if (hasErrors(*tracer->m_errors)) {
        return embreeFailure(*tracer->m_errors);
    }
    return Result<std::unique_ptr<RayTracer>>(std::move(tracer));
}

RayTracer::~RayTracer() {
    // The scene holds references into the device, so it goes first.
    if (m_scene != nullptr) {
        rtcReleaseScene(m_scene);
    }
    if (m_device != nullptr) {
        rtcReleaseDevice(m_device);
    }
}

std::optional<Hit> RayTracer::intersect(glm::vec3 origin, glm::vec3 dir, float t_max) const {
    RTCIntersectContext context;
    // Default context: incoherent single rays, no filter callbacks.
    rtcInitIntersectContext(&context);
    RTCRayHit ray_hit;
    ray_hit.ray = makeRay(origin, dir, t_max);
    ray_hit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    ray_hit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    // Closest hit: the integrators shade the first surface along the ray.
    rtcIntersect1(m_scene, &context, &ray_hit);
    if (ray_hit.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
        return std::nullopt;
    }
    Hit hit;
    hit.t = ray_hit.ray.tfar;
    hit.triangle = ray_hit.hit.primID;
    hit.bary = glm::vec2(ray_hit.hit.u, ray_hit.hit.v);
    hit.geometricNormal = m_normals[hit.triangle];
    hit.backFace = glm::dot(dir, hit.geometricNormal) > 0.0f;
    return hit;
}

bool RayTracer::occluded(glm::vec3 origin, glm::vec3 dir, float t_max) const {
    RTCIntersectContext context;
    // Default context: incoherent single rays, no filter callbacks.
    rtcInitIntersectContext(&context);
    RTCRay ray = makeRay(origin, dir, t_max);
    // Any hit is enough for visibility; Embree marks one by setting tfar to -inf.
    rtcOccluded1(m_scene, &context, &ray);
    return ray.tfar < 0.0f;
}

void RayTracer::occluded(std::span<const OcclusionRay> rays, std::span<uint8_t> occluded,
                         bool coherent) const {
    assert(occluded.size() == rays.size());
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    // Coherent rays (one origin) let the stream regroup them into packets that traverse the BVH
    // together; incoherent ones are better served one by one inside the stream.
    context.flags =
        coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    // Chunks on the stack: large enough for Embree to fill its packets, small enough to stay
    // in L1/L2.
    constexpr size_t kChunk = 256;
    RTCRay chunk[kChunk];
    for (size_t begin = 0; begin < rays.size(); begin += kChunk) {
        const size_t count = std::min(kChunk, rays.size() - begin);
        for (size_t i = 0; i < count; ++i) {
            const OcclusionRay& r = rays[begin + i];
            chunk[i] = makeRay(r.origin, r.dir, r.tMax);
        }
        // Any hit is enough; Embree marks one by setting tfar to -inf.
        rtcOccluded1M(m_scene, &context, chunk, unsigned(count), sizeof(RTCRay));
        for (size_t i = 0; i < count; ++i) {
            occluded[begin + i] = chunk[i].tfar < 0.0f ? 1 : 0;
        }
    }
}

#if defined(__SSE__)
namespace {
constexpr unsigned kDefaultMxcsr = 0x1f80u; // all exceptions masked, round to nearest
constexpr unsigned kFlushToZero = 0x8000u;
constexpr unsigned kDenormalsAreZero = 0x0040u;
} // namespace

ScopedFloatMode::ScopedFloatMode() : m_saved(_mm_getcsr()) {
    _mm_setcsr(kDefaultMxcsr | kFlushToZero | kDenormalsAreZero);
}
ScopedFloatMode::~ScopedFloatMode() {
    _mm_setcsr(m_saved);
}
#else
// Other architectures: no denormal control is touched (ARM's default mode is used as is).
ScopedFloatMode::ScopedFloatMode() = default;
ScopedFloatMode::~ScopedFloatMode() = default;
#endif

} // namespace probekit::baker
