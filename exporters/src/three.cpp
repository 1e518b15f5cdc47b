// Placeholder until the three exporter lands (issue 28).
#include "probekit/exporters/three.hpp"

namespace probekit::exporters {

Result<ExportResult> exportThree(const Volume&, const ThreeOptions&, const std::filesystem::path&) {
    return Error{ErrorCode::InvalidArgument, "export three: not implemented yet"};
}

} // namespace probekit::exporters
