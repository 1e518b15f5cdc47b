// Bevy: a volume as a KTX2 irradiance volume of ambient cubes (docs/engines.md#bevy).
#pragma once

#include <filesystem>

#include <glm/vec3.hpp>

#include "probekit/exporters/export.hpp"
#include "probekit/formats/result.hpp"
#include "probekit/formats/volume.hpp"

namespace probekit::exporters {

struct BevyOptions {
    glm::uvec3 resolution{
        0}; // dense grid for bricked or rotated volumes (0: resample.hpp's default)
};

// One file, `out` (OUT.ktx2).
Result<ExportResult> exportBevy(const Volume& volume, const BevyOptions& options,
                                const std::filesystem::path& out);

} // namespace probekit::exporters
