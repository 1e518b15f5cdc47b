// The folder rule for files that an untrusted file names (ARCHITECTURE.md, "Rules that hold
// everywhere"): such a file is opened only when it resolves under a folder the user chose. The
// glTF loader holds every URI to it (its scene folder and LoadOptions::assetRoots); `probekit
// render` holds the environment file a .pvol records to it.
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

namespace probekit::baker {

// Where `named` leads (against the working directory when relative; `..` and symbolic links
// resolved) when that is under one of `roots`: the canonical path of an existing file, or the
// normalised path of a missing one (opening it then fails, naming it). std::nullopt when it
// leads outside every root, by its own components or through a link, and when no root is an
// existing folder (roots that are not are skipped). Whether a path outside exists is never
// looked at.
std::optional<std::filesystem::path>
pathUnderRoots(const std::filesystem::path& named, const std::vector<std::filesystem::path>& roots);

} // namespace probekit::baker
