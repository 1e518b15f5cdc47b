// A volume as a dense, axis-aligned grid of probes: what engines whose probe grids have no bricks
// and no rotation (three.js, Bevy) can hold.
#pragma once

#include <glm/vec3.hpp>

#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::exporters {

struct Resampled {
    Volume volume;          // dense, identity frame, float32 storage, the source's SH order
    bool resampled = false; // false: the source was already dense and axis-aligned (copied)
    // Irradiance error of the resampled volume against the source at random points of the box
    // and random normals (runtime's CPU sampler for both): RMS of |E - E_src| over RMS of
    // |E_src|, and the largest |E - E_src| over RMS |E_src|. 0 when not resampled.
    double relRms = 0.0;
    double relMax = 0.0;
};

// A dense, axis-aligned volume is returned as it is (float32; its visibility kept). Otherwise
// (bricked, or rotated by its frame) the source is sampled with runtime::sampleVolumeSh at the
// probes of a centre-mode grid of `resolution` over the source's world-space bounding box (a
// power of two per axis, 1..256); visibility is dropped (it belongs to the source's probes), and
// validity is 1 everywhere. resolution (0,0,0) means the source's own grid resolution for dense
// volumes and its finest brick resolution (capped at 64 per axis) for bricked ones.
Result<Resampled> denseAxisAligned(const Volume& source, glm::uvec3 resolution);

} // namespace probekit::exporters
