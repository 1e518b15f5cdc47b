// Placeholder until the bevy exporter lands (issue 28).
#include "probekit/exporters/bevy.hpp"

namespace probekit::exporters {

Result<ExportResult> exportBevy(const Volume&, const BevyOptions&, const std::filesystem::path&) {
    return Error{ErrorCode::InvalidArgument, "export bevy: not implemented yet"};
}

} // namespace probekit::exporters
