// Shared pieces of the baker benchmarks: the Cornell reference and how a bake is scored
// against it (bench_bake_common.hpp).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "bench_bake_common.hpp"
#include "probekit/runtime/sampler.hpp"

namespace probekit::bench {

using namespace probekit::baker;

const CornellReference& cornellReference() {
    static const CornellReference reference = [] {
        const auto path = std::filesystem::path(PROBEKIT_SHARED_DIR) / "scenes" / "cornell-box" /
                          "reference.json";
        std::ifstream in(path);
        if (!in) {
            std::fprintf(stderr, "bench: missing %s\n", path.string().c_str());
            std::exit(1);
        }
        const nlohmann::json j = nlohmann::json::parse(in);
        CornellReference r;
        for (const auto& p : j["points"]) {
            r.points.emplace_back(p[0].get<float>(), p[1].get<float>(), p[2].get<float>());
        }
        for (const auto& n : j["normals"]) {
            r.normals.emplace_back(n[0].get<float>(), n[1].get<float>(), n[2].get<float>());
        }
        for (const auto& per_point : j["E_L2"]) {
            std::vector<glm::dvec3> row;
            for (const auto& e : per_point) {
                row.emplace_back(e[0].get<double>(), e[1].get<double>(), e[2].get<double>());
            }
            r.irradianceL2.push_back(row);
        }
        return r;
    }();
    return reference;
}

BakeConfig referenceProbes() {
    BakeConfig c;
    for (size_t i = 0; i < cornellReference().points.size(); ++i) {
        VolumeConfig v;
        // Built by insertion: GCC 12 reports a false -Wrestrict for "p" + ... here.
        v.name = std::to_string(i);
        v.name.insert(v.name.begin(), 'p');
        v.bounds.mode = BoundsMode::Custom;
        v.bounds.min = cornellReference().points[i] - glm::vec3(0.05f);
        v.bounds.max = cornellReference().points[i] + glm::vec3(0.05f);
        v.resolution = glm::uvec3(1);
        v.storage = Storage::Float32;
        c.volumes.push_back(v);
    }
    return c;
}

std::vector<std::vector<glm::dvec3>> probeIrradiance(const BakeResult& r) {
    const CornellReference& ref = cornellReference();
    std::vector<std::vector<glm::dvec3>> out;
    for (size_t p = 0; p < ref.points.size(); ++p) {
        const runtime::VolumeSet set({r.file.volumes[p]});
        std::vector<glm::dvec3> row;
        for (const glm::vec3& n : ref.normals) {
            row.emplace_back(set.irradiance(ref.points[p], n));
        }
        out.push_back(row);
    }
    return out;
}

double relRmse(const std::vector<std::vector<glm::dvec3>>& e,
               const std::vector<std::vector<glm::dvec3>>& reference) {
    double num = 0.0, den = 0.0;
    for (size_t p = 0; p < e.size(); ++p) {
        for (size_t k = 0; k < e[p].size(); ++k) {
            const glm::dvec3 d = e[p][k] - reference[p][k];
            num += glm::dot(d, d);
            den += glm::dot(reference[p][k], reference[p][k]);
        }
    }
    return std::sqrt(num / den);
}

Result<BakeResult> bakeCornell(const BakeConfig& config) {
    BakeOptions options;
    options.threads = benchThreads();
    return bake(cornellScene(), config, options);
}

std::optional<VersusPath> timeAgainstPath(benchmark::State& state, const std::string& method,
                                          int digits, const std::string& ratio_key,
                                          const BakeConfig& config, const BakeConfig& path_config,
                                          int rounds,
                                          const std::function<void(const BakeResult&)>& each) {
    VersusPath out;
    for (int round = 0; round < rounds; ++round) {
        Result<BakeResult> result = bakeCornell(config);
        Result<BakeResult> path = bakeCornell(path_config);
        if (!result || !path) {
            state.SkipWithError((result ? path : result).error().message.c_str());
            return std::nullopt;
        }
        out.seconds += result.value().stats.seconds;
        out.pathSeconds += path.value().stats.seconds;
        if (each) {
            each(result.value());
        }
        std::printf("[%s cornell] 16^3 round %d: %s %.*f s, path at 4096 samples %.2f s\n",
                    method.c_str(), round + 1, method.c_str(), digits, result.value().stats.seconds,
                    path.value().stats.seconds);
    }
    out.ratio = out.seconds / out.pathSeconds;
    state.counters[method + "_s"] = out.seconds / rounds;
    state.counters["path4096_s"] = out.pathSeconds / rounds;
    state.counters["time_ratio"] = out.ratio;
    results()[ratio_key] = out.ratio;
    return out;
}

} // namespace probekit::bench
