// denseAxisAligned: a volume as a dense, axis-aligned float grid (resample.hpp).
#include "probekit/exporters/resample.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>
#include <vector>

#include "probekit/formats/brick.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit::exporters {
namespace {

bool axisAligned(const Volume& v) {
    const glm::quat q = v.desc.grid.frame().rotation;
    return q.x == 0.0f && q.y == 0.0f && q.z == 0.0f;
}

glm::uvec3 defaultResolution(const Volume& v) {
    if (v.desc.layout == VolumeLayout::Dense)
        return v.desc.grid.resolution();
    // Bricked: a brick's 4 probes span one of its cells in 3 steps, so the finest bricks put
    // probes 1/3 of a finest cell apart.
    const glm::uvec3 cells = brick::finestCells(v.desc.grid.resolution(), v.desc.bricks.maxLevel);
    glm::uvec3 r;
    for (int a = 0; a < 3; ++a)
        r[a] = std::min(64u, std::bit_ceil(3u * cells[a]));
    return r;
}

// The source converted to float32 storage, bounds moved into world space (identity frame).
Result<Volume> copyAsFloat(const Volume& source) {
    const grid::GridLayout& g = source.desc.grid;
    const glm::vec3 t = g.frame().translation;
    Result<grid::GridLayout> layout =
        grid::GridLayout::make({g.bounds().min + t, g.bounds().max + t}, g.resolution(), g.mode());
    if (!layout)
        return layout.error();
    VolumeDesc desc = source.desc;
    desc.grid = layout.value();
    desc.storage = Storage::Float32;
    std::vector<sh::ShRgb> probes(source.probeCount());
    for (size_t i = 0; i < probes.size(); ++i)
        probes[i] = source.probe(i);
    return makeVolume(desc, probes, source.validity, source.visibility);
}

// Irradiance of `test` against `source` at seeded random points and normals (resample.hpp).
void measureError(const Volume& source, Resampled& r) {
    const grid::Aabb box = r.volume.desc.grid.bounds();
    std::mt19937 rng(12345u);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    double sumErr2 = 0.0, sumRef2 = 0.0, maxErr = 0.0;
    constexpr int kPoints = 4096;
    for (int i = 0; i < kPoints; ++i) {
        const glm::vec3 p = box.min + glm::vec3(u(rng), u(rng), u(rng)) * (box.max - box.min);
        const float z = 2.0f * u(rng) - 1.0f, phi = 6.2831853f * u(rng);
        const float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const glm::vec3 n(s * std::cos(phi), s * std::sin(phi), z);
        const sh::Order order = source.desc.shOrder;
        const glm::vec3 ref = sh::irradiance(runtime::sampleVolumeSh(source, p), order, n);
        const glm::vec3 got = sh::irradiance(runtime::sampleVolumeSh(r.volume, p), order, n);
        const double e = glm::length(got - ref);
        sumErr2 += e * e;
        sumRef2 += double(glm::dot(ref, ref));
        maxErr = std::max(maxErr, e);
    }
    const double rms = std::sqrt(sumRef2 / kPoints);
    r.relRms = rms > 0.0 ? std::sqrt(sumErr2 / kPoints) / rms : 0.0;
    r.relMax = rms > 0.0 ? maxErr / rms : 0.0;
}

} // namespace

Result<Resampled> denseAxisAligned(const Volume& source, glm::uvec3 resolution) {
    const bool asIs = source.desc.layout == VolumeLayout::Dense && axisAligned(source) &&
                      (resolution == glm::uvec3(0) || resolution == source.desc.grid.resolution());
    if (asIs) {
        Result<Volume> copy = copyAsFloat(source);
        if (!copy)
            return copy.error();
        return Resampled{std::move(copy.value()), false, 0.0, 0.0};
    }
    if (resolution == glm::uvec3(0))
        resolution = defaultResolution(source);
    Result<grid::GridLayout> layout = grid::GridLayout::make(
        source.desc.grid.worldBounds(), resolution, grid::PositionMode::Center);
    if (!layout)
        return Error{layout.error().code, "export resolution: " + layout.error().message};
    VolumeDesc desc = source.desc;
    desc.grid = layout.value();
    desc.layout = VolumeLayout::Dense;
    desc.bricks = {};
    desc.storage = Storage::Float32;
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        const glm::vec3 p = desc.grid.probeWorld(desc.grid.probeCoords(i));
        probes[i] = runtime::sampleVolumeSh(source, p);
    }
    Result<Volume> dense = makeVolume(desc, probes);
    if (!dense)
        return dense.error();
    Resampled r{std::move(dense.value()), true, 0.0, 0.0};
    measureError(source, r);
    return r;
}

} // namespace probekit::exporters
