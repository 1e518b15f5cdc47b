// probekit::runtime CPU reference sampler — the specification the GPU path must match.
//
// shaders/probe_volume.glsl's pk_irradiance mirrors VolumeSet::irradiance term for term; the GPU
// tests (tests/gpu/) compare against this code. It needs no Vulkan and no baker.
//
// Sampling one dense volume at world position p:
//   1. g = volume.grid.worldToGrid(p) (continuous grid coordinates, probe i at i).
//   2. Clamp addressing: g = clamp(g, 0, res - 1) per axis. This is what a 3D texture with
//      linear filtering and clamp-to-edge addressing does at texture coordinate (g + 0.5) / res.
//   3. Trilinear interpolation of the stored RGBA texels of every plane (half texels are
//      decoded to float first) between probes floor(g) and floor(g) + 1 (an axis with one probe
//      uses it alone), weights fract(g).
//   4. Unpack to SH (volume.hpp's packing) and evaluate sh::irradiance with the world normal
//      (coefficients are stored in the world frame, whatever the volume's own frame).
//
// Sampling one bricked volume (formats/.../brick.hpp) at world position p; pk_brick_uvw in
// shaders/probe_volume.glsl mirrors B1-B3, hardware trilinear filtering inside the brick's atlas
// slot (runtime/.../gpu_volumes.hpp) B4:
//   B1. local = frame.toLocal(p); f = (local - box.min) / box.size() * N, the point in
//       finest-cell units (N = brick::finestCells(grid.resolution(), maxLevel)).
//   B2. brick::locate(f): clamp f to [0, N] (NaN -> 0), finest cell c = min(floor(f), N - 1),
//       brick b = indirection[c], span s = 2^(maxLevel - level of b), origin = (c / s) * s,
//       brick-local coordinates l = clamp((f - origin) * (3 / s), 0, 3).
//   B3. Trilinear interpolation, as step 3, of the stored texels of brick b's 4 x 4 x 4 probes
//       (volume probe b * 64 + x + 4 (y + 4 z)) at l: probes floor(l) and floor(l) + 1
//       (an axis at l = 3 uses probe 3 alone), weights fract(l).
//   B4. Unpack and evaluate as step 4.
// Visibility (step V, when the volume has visibility data: formats/.../visibility.hpp): in step
// 3 (B3) each of the (up to 8) taps' trilinear weight is multiplied by vis_i + kFloor, where
// vis_i is the probe's visibility at the tap offset (clamped coordinate minus the tap's probe
// coordinate, grid or brick-local units), and the weighted sum is divided by the sum of the
// weights. Without visibility data this is step 3 unchanged. The GPU cannot use its
// trilinear filter for this; pk_volume_texels fetches the taps one by one.
// Outside the box this clamps to the nearest border brick's values, as step 2 does for dense
// volumes. Fades, blending and the nearest-volume rule below use the box alone, whatever the
// layout.
//
// Blending overlapping volumes at p:
//   * A volume's weight w(p) is 1 deeper than fadeDistance inside its box, falls linearly to 0
//     at the box border (distance to the nearest face of the local box / fadeDistance, clamped
//     to [0, 1]; fadeDistance 0 means a hard border), and is 0 outside the box.
//   * Volumes are visited by descending blendPriority (ties: file order). Each takes
//     a = w * remaining of what is left (remaining starts at 1), so a higher-priority volume
//     fully covering p hides the others and its fade band lets the next one show through.
//   * E(p) = sum a_v E_v(p) / sum a_v: at the outer border of the last volume the result does
//     not fade to black.
//   * If no volume covers p (sum a_v = 0), the volume whose box is nearest to p is sampled
//     with clamp addressing (ties: highest priority, then file order).
#pragma once

#include <filesystem>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/formats/pvol.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::runtime {

// The radiance SH of one volume at world position p (steps 1-4 above, before the normal).
sh::ShRgb sampleVolumeSh(const Volume& volume, glm::vec3 world_position);

// The visible share of the trilinear weight at p, sum trilinear_i * vis_i in [0, 1] (step V;
// 1 for a volume without visibility data): 1 where no tap is hidden, near 0 where interpolation
// would otherwise pull light through a wall. What `probekit render --view leak` shows.
float visibleWeight(const Volume& volume, glm::vec3 world_position);

// The blend weight w(p) of one volume (see above), in [0, 1].
float volumeWeight(const Volume& volume, glm::vec3 world_position);

// Distance from p to the volume's box in metres (0 inside).
float distanceToVolume(const Volume& volume, glm::vec3 world_position);

class VolumeSet {
public:
    VolumeSet() = default;
    // Precondition (checked in every build type; a failure prints validateVolume's message and
    // aborts, ARCHITECTURE.md "Preconditions"): every volume passes validateVolume. Use make()
    // for volumes that may not.
    explicit VolumeSet(std::vector<Volume> volumes);

    // Validating constructor: fails with validateVolume's error, prefixed "volumes[i]: ".
    static Result<VolumeSet> make(std::vector<Volume> volumes);
    static Result<VolumeSet> load(const std::filesystem::path& path);

    const std::vector<Volume>& volumes() const { return m_volumes; }
    bool empty() const { return m_volumes.empty(); }

    // Irradiance E in W/m^2 (not divided by pi) for a receiver at world position p with unit
    // world normal n, blended over all volumes as described above. Precondition (checked in
    // every build type, aborting): !empty().
    glm::vec3 irradiance(glm::vec3 world_position, glm::vec3 normal) const;

    // The same at the sample point p + normal_offset * n (metres along the normal; n is still
    // the receiver normal). Moving off the surface keeps a receiver from interpolating probes
    // that sit behind it (self-leaking). pk_irradiance mirrors this with
    // GpuVolumeSet::setNormalOffset; normal_offset 0 is irradiance(p, n) exactly.
    glm::vec3 irradiance(glm::vec3 world_position, glm::vec3 normal, float normal_offset) const;

private:
    // What make() and load() use once every volume has been validated: no second pass.
    struct Validated {};
    VolumeSet(std::vector<Volume> volumes, Validated);

    std::vector<Volume> m_volumes;
    std::vector<size_t> m_byPriority; // indices into m_volumes, descending priority
};

} // namespace probekit::runtime
