// Bevy: a volume as a KTX2 irradiance volume of ambient cubes (docs/engines.md#bevy).
//
// What Bevy reads (bevy_pbr's light_probe/irradiance_volume.wesl and .rs): an RGBA16F (or
// RGB9E5) 3D texture of (Rx, 2 Ry, 3 Rz) texels for Rx x Ry x Rz voxels. The value of voxel
// (x, y, z) for the face along axis a (0 = X, 1 = Y, 2 = Z) is at texel
//   (x, y + (face negative ? Ry : 0), z + a Rz)
// (the shader's layout: its doc comment puts the positive faces in the second half instead).
// The light probe is a unit cube, -0.5..0.5 on each axis, placed by its Transform; voxel i's
// centre is at (i + 0.5) / R - 0.5 (the shader clamps to the outer voxel centres and filters
// linearly between them). The shader shades a normal n with sum_a n_a^2 face(a, sign n_a),
// faces in world axes, times the volume's intensity and the diffuse colour: so a face holds
// E / pi (W/(sr m^2)), the radiance a white Lambertian receiver reflects, as Bevy's own
// Lambert term (diffuse colour x E / pi) does for direct light.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "probekit/exporters/export.hpp"
#include "probekit/formats/grid.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/sh.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::exporters {

struct BevyOptions {
    glm::uvec3 resolution{
        0}; // dense grid for bricked or rotated volumes (0: resample.hpp's default)
};

// One file, `out` (OUT.ktx2): RGBA16F texels (alpha 1), key/value entries KTXwriter and
// probekit.transform (JSON: the LightProbe's translation and scale in metres, rotation
// the identity quaternion as (x, y, z, w), intensity 1, and the units of the texels). The notes
// give the transform, the projection error and, for a resampled volume, the resampling error. Fails
// (OutOfRange, naming the voxel and face) where E / pi exceeds binary16's 65504.
Result<ExportResult> exportBevy(const Volume& volume, const BevyOptions& options,
                                const std::filesystem::path& out);

// ---- The projection from SH to an ambient cube ----

// Faces in the order +X, -X, +Y, -Y, +Z, -Z; each RGB in W/(sr m^2) (E / pi).
using AmbientCube = std::array<glm::vec3, 6>;

// The least-squares fit, over the unit sphere with uniform measure, of Bevy's ambient-cube
// reconstruction to g(n) = E(n) / pi, E the SH irradiance (sh.hpp). Even and odd parts
// decouple: the even part of g (bands 0 and 2) is c0 + sum_a q_a n_a^2 on the sphere plus the
// xy, yz, zx terms that no ambient cube can hold, and the n_a^2 basis fits the former exactly,
// so its face value is g_even(+-axis); the odd part b.n (band 1) projects on n_a |n_a| with
// weight (int |n_a|^3) / (int n_a^4) = pi / (4 pi / 5) = 5/4. With the constants of sh.hpp:
//   face(a, +-) = kY00 L00 + (1/4) q_a +- (5/6) kY1 L1a
//   q = kY20 L20 (-1, -1, 2) + kY22 L22 (1, -1, 0), L1a = (L11, L1-1, L10)[a]
// A face that comes out negative is set to 0 (so Bevy's sum never goes below zero).
AmbientCube ambientCubeFromSh(const sh::ShRgb& sh, sh::Order order);

// Bevy's reconstruction at unit world normal n: sum_a n_a^2 face(a, sign n_a) (a zero
// component picks the positive face, as the shader's n < 0 test does).
glm::vec3 evalAmbientCube(const AmbientCube& cube, glm::vec3 normal);

// Where the projection error is measured: `count` seeded random points of `box` (uniform) with
// random unit normals (uniform on the sphere).
struct ErrorSample {
    glm::vec3 position{0.0f};
    glm::vec3 normal{0.0f, 1.0f, 0.0f};
};
std::vector<ErrorSample> errorSamples(const grid::Aabb& box, uint32_t seed, int count);

// The projection's error on a dense volume at `samples`: pi x evalAmbientCube of
// ambientCubeFromSh(SH at p) against sh::irradiance of the same SH, both from
// runtime::sampleVolumeSh with plain trilinear interpolation (visibility ignored, as Bevy
// filters): RMS of |delta E| (RGB length) over RMS of |E|, and the largest |delta E| over RMS
// of |E|. The exporter's notes give it at errorSamples(box, 2028, 4096); zeros when E is zero.
struct ProjectionError {
    double relRms = 0.0;
    double relMax = 0.0;
};
ProjectionError ambientCubeError(const Volume& dense, std::span<const ErrorSample> samples);

} // namespace probekit::exporters
