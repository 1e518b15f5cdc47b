// three.js: a volume as the atlas of three.js's LightProbeGrid (docs/engines.md#threejs).
#pragma once

#include <filesystem>

#include <glm/vec3.hpp>

#include "probekit/exporters/export.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::exporters {

struct ThreeOptions {
    glm::uvec3 resolution{
        0};           // dense grid for bricked or rotated volumes (0: resample.hpp's default)
    bool half = true; // atlas texels as binary16 (else float32)
};

// Files OUT.json (header) and OUT.bin (the SH atlas, then the visibility texture when the
// exported grid has visibility) for `out` = OUT.json; integrations/three/probekit-three.js reads
// them. Fails when a coefficient exceeds half range with options.half (export as float), when
// `out` ends in .bin, and as denseAxisAligned fails.
Result<ExportResult> exportThree(const Volume& volume, const ThreeOptions& options,
                                 const std::filesystem::path& out);

} // namespace probekit::exporters
