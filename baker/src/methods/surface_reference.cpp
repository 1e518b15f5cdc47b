#include "probekit/baker/surface_reference.hpp"

#include <atomic>
#include <chrono>
#include <cmath>

#include <glm/geometric.hpp>

#include "methods/path_integrator.hpp"
#include "trace/parallel.hpp"
#include "trace/ray_tracer.hpp"
#include "trace/rng.hpp"

namespace probekit::baker {

namespace {

// Keys the per-pixel random numbers apart from every probe's (rng.hpp's keys are
// (seed, volume, probe)).
constexpr uint64_t kSurfaceStream = 0x5f7f'ace0ull;

// Pixels handed to a thread at a time: a row of a small image.
constexpr size_t kChunk = 64;

glm::vec3 shadingNormal(const Scene& scene, const Hit& hit) {
    if (scene.normals.size() == scene.positions.size()) {
        const glm::uvec3 t = scene.triangles[hit.triangle];
        const float w0 = 1.0f - hit.bary.x - hit.bary.y;
        const glm::vec3 n = w0 * scene.normals[t.x] + hit.bary.x * scene.normals[t.y] +
                            hit.bary.y * scene.normals[t.z];
        const float length = glm::length(n);
        if (length > 1e-12f && std::isfinite(length)) {
            return n / length;
        }
    }
    return hit.geometricNormal;
}

} // namespace

Result<SurfaceReference>
traceSurfaceReference(const Scene& scene, std::span<const SurfaceRay> rays,
                      const SurfaceReferenceSettings& settings,
                      const std::function<void(size_t, size_t)>& progress) {
    if (settings.samples < 1) {
        return makeError(ErrorCode::InvalidArgument, "surface reference: samples must be >= 1");
    }
    Result<std::unique_ptr<RayTracer>> tracer = RayTracer::create(scene);
    if (!tracer) {
        return tracer.error();
    }
    PathConfig path;
    path.samples = settings.samples;
    path.maxBounces = settings.maxBounces;
    const PathIntegrator integrator(scene, *tracer.value(), path, sh::Order::L2);

    SurfaceReference result;
    result.samples.resize(rays.size());
    std::vector<uint64_t> chunk_rays((rays.size() + kChunk - 1) / kChunk, 0);
    std::atomic<size_t> done{0};
    const auto body = [&](size_t begin, size_t end) {
        uint64_t traced = 0;
        for (size_t i = begin; i < end; ++i) {
            const SurfaceRay& ray = rays[i];
            const std::optional<Hit> hit = tracer.value()->intersect(ray.origin, ray.direction);
            ++traced;
            if (!hit || glm::dot(hit->geometricNormal, hit->geometricNormal) == 0.0f) {
                continue;
            }
            SurfaceSample& s = result.samples[i];
            s.hit = true;
            s.triangle = hit->triangle;
            s.position = tracer.value()->surfacePoint(hit->triangle, hit->bary);
            const glm::vec3 facing = glm::dot(hit->geometricNormal, ray.direction) > 0.0f
                                         ? -hit->geometricNormal
                                         : hit->geometricNormal;
            glm::vec3 n = shadingNormal(scene, *hit);
            if (glm::dot(n, ray.direction) > 0.0f) {
                n = -n;
            }
            s.normal = n;
            const PathIntegrator::SurfaceEstimate e =
                integrator.surfaceIrradiance(s.position, facing, n, settings.samples,
                                             hashKeys(settings.seed, kSurfaceStream, uint64_t(i)));
            s.irradiance = e.irradiance;
            s.standardError = glm::sqrt(e.varianceOfMean);
            traced += e.rays;
        }
        chunk_rays[begin / kChunk] = traced;
        done.fetch_add(end - begin);
    };
    if (progress) {
        parallelForWatched(rays.size(), settings.threads, kChunk, body,
                           std::chrono::milliseconds(500),
                           [&] { progress(done.load(), rays.size()); });
        progress(rays.size(), rays.size());
    } else {
        parallelFor(rays.size(), settings.threads, kChunk, body);
    }
    for (uint64_t r : chunk_rays) {
        result.rays += r;
    }
    return result;
}

} // namespace probekit::baker
