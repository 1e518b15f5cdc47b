#include "methods/vpl_integrator.hpp"

namespace probekit::baker {

PathConfig VplProbeIntegrator::directConfig(const VplConfig& config, uint32_t samples,
                                            const PathConfig* adaptive) {
    PathConfig path = adaptive != nullptr ? *adaptive : PathConfig{};
    path.samples = samples;
    path.maxBounces = config.bounces;
    return path;
}

VplProbeIntegrator::VplProbeIntegrator(const Scene& scene, const RayTracer& tracer,
                                       const VplGatherer& gatherer, const VplConfig& config,
                                       const PathConfig& path, sh::Order order)
    : m_direct(scene, tracer, directConfig(config, config.directSamples, &path), order,
               *config.nearField),
      m_boosted(scene, tracer,
                directConfig(config, config.directSamples * kNearFieldBoost, nullptr), order,
                *config.nearField),
      m_gatherer(gatherer), m_order(order) {}

VplProbeSample VplProbeIntegrator::bakeProbe(glm::vec3 position, uint64_t seed,
                                             uint32_t volume_index, uint64_t probe_index) const {
    VplProbeSample result;
    if (m_direct.config().noiseTarget > 0.0f) {
        const VplGatherResult g = m_gatherer.gather(position, m_order, sh::ShRgb{});
        result.probe = m_direct.bakeProbe(position, seed, volume_index, probe_index, &g.sh);
        result.probe.sh += g.sh;
        result.probe.rays += g.rays;
        result.cutSize = g.cutSize;
        return result;
    }
    result.probe = m_direct.bakeProbe(position, seed, volume_index, probe_index);
    if (result.probe.nearFraction > kNearFieldBoostFraction) {
        const uint64_t first_rays = result.probe.rays;
        result.probe = m_boosted.bakeProbe(position, seed, volume_index, probe_index);
        result.probe.rays += first_rays;
    }
    const VplGatherResult g = m_gatherer.gather(position, m_order, result.probe.sh);
    result.probe.sh += g.sh;
    result.probe.rays += g.rays;
    result.cutSize = g.cutSize;
    return result;
}

} // namespace probekit::baker
