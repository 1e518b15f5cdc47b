// What every exporter returns: the files to write (the CLI writes each atomically) and the
// lines to print (resampling and projection errors, what was converted).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace probekit::exporters {

struct OutputFile {
    std::filesystem::path path;
    std::vector<uint8_t> bytes;
};

struct ExportResult {
    std::vector<OutputFile> files;
    std::vector<std::string> notes; // one line each, printed by the CLI unless -q
};

} // namespace probekit::exporters
