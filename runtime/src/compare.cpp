#include "probekit/runtime/compare.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace probekit::runtime {

Result<VolumeError> compareVolumes(std::span<const Volume> test,
                                   std::span<const Volume> reference) {
    if (test.size() != reference.size()) {
        return makeError(ErrorCode::InconsistentSize,
                         std::to_string(test.size()) + " volumes compared against " +
                             std::to_string(reference.size()) + " reference volumes");
    }
    static const std::array<glm::vec3, kCompareNormals> normals = [] {
        std::array<glm::vec3, kCompareNormals> n{};
        for (int i = 0; i < kCompareNormals; ++i) {
            n[i] = sh::fibonacciDirection(i, kCompareNormals);
        }
        return n;
    }();

    VolumeError out;
    double sum_diff2 = 0.0;
    double sum_ref2 = 0.0;
    // Per-probe squared error sums, to find the worst probe once the global RMS is known.
    struct ProbeError {
        double diff2;
        size_t volume;
        size_t probe;
    };
    std::vector<ProbeError> probes;
    for (size_t v = 0; v < test.size(); ++v) {
        const Volume& a = test[v];
        const Volume& b = reference[v];
        if (a.desc.grid.resolution() != b.desc.grid.resolution()) {
            return makeError(ErrorCode::InconsistentSize,
                             "volume " + std::to_string(v) + " ('" + a.desc.name +
                                 "'): resolution differs from the reference volume '" +
                                 b.desc.name + "'");
        }
        // Probe i must be the same place in both: bricked volumes need the same bricks.
        if (a.desc.layout != b.desc.layout || a.desc.bricks != b.desc.bricks) {
            return makeError(ErrorCode::InconsistentSize,
                             "volume " + std::to_string(v) + " ('" + a.desc.name +
                                 "'): layout or bricks differ from the reference volume '" +
                                 b.desc.name + "' (compare bricked bakes with bake --verify)");
        }
        for (size_t i = 0; i < a.probeCount(); ++i) {
            if (a.validity[i] != kProbeValid || b.validity[i] != kProbeValid) {
                continue;
            }
            const sh::ShRgb sa = a.probe(i);
            const sh::ShRgb sb = b.probe(i);
            double diff2 = 0.0;
            for (const glm::vec3& n : normals) {
                const glm::vec3 ea = sh::irradiance(sa, a.desc.shOrder, n);
                const glm::vec3 eb = sh::irradiance(sb, b.desc.shOrder, n);
                for (int c = 0; c < 3; ++c) {
                    const double d = double(ea[c]) - double(eb[c]);
                    diff2 += d * d;
                    sum_ref2 += double(eb[c]) * double(eb[c]);
                    out.maxAbsErr = std::max(out.maxAbsErr, std::abs(d));
                }
            }
            sum_diff2 += diff2;
            probes.push_back({diff2, v, i});
        }
    }
    out.probesCompared = probes.size();
    if (probes.empty() || sum_ref2 <= 0.0) {
        return out;
    }
    out.relRmse = std::sqrt(sum_diff2 / sum_ref2);
    const auto worst = std::max_element(
        probes.begin(), probes.end(),
        [](const ProbeError& x, const ProbeError& y) { return x.diff2 < y.diff2; });
    // rms over one probe's values / rms over all values of the reference.
    out.maxProbeErr = std::sqrt(worst->diff2 / sum_ref2 * double(probes.size()));
    out.worstVolume = worst->volume;
    out.worstProbe = worst->probe;
    return out;
}

} // namespace probekit::runtime
