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

// Files OUT.json (header) and OUT.bin (atlas) for `out` = OUT.json.
Result<ExportResult> exportThree(const Volume& volume, const ThreeOptions& options,
                                 const std::filesystem::path& out);

} // namespace probekit::exporters
