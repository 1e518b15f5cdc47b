// `probekit synth`: writes an analytic example volume without baking anything. Each probe
// holds the exact SH of a uniform sky plus one point light (a directional delta of irradiance
// I / d^2 towards the light), so irradiance anywhere is known in closed form. Useful as the
// bundled example before a scene is baked, and for runtime tests that need no baker.
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "probekit/formats/pvol.hpp"
#include "terminal_text.hpp"

namespace probekit::cli {
namespace {

struct SynthOptions {
    std::string output;
    std::vector<uint32_t> resolution{8, 8, 8};
    std::string position = "center";
    std::string format = "float";
    int shOrder = 2;
    std::vector<float> sky{0.3f, 0.4f, 0.6f};   // uniform sky radiance, W/(sr m^2)
    std::vector<float> light{0.0f, 2.5f, 0.0f}; // point light position, metres
    float intensity = 10.0f;                    // point light intensity, W/sr
};

int runSynth(const SynthOptions& o) {
    const grid::PositionMode mode =
        o.position == "corner" ? grid::PositionMode::Corner : grid::PositionMode::Center;
    Result<grid::GridLayout> layout = grid::GridLayout::make(
        grid::Aabb{glm::vec3(-2.0f, 0.0f, -2.0f), glm::vec3(2.0f, 2.0f, 2.0f)},
        glm::uvec3(o.resolution[0], o.resolution[1], o.resolution[2]), mode);
    if (!layout) {
        printError("synth", "--resolution: " + layout.error().message);
        return kExitFailure;
    }
    VolumeDesc desc;
    desc.name = "synthetic";
    desc.grid = layout.value();
    desc.shOrder = o.shOrder == 1 ? sh::Order::L1 : sh::Order::L2;
    desc.storage = o.format == "half" ? Storage::Float16 : Storage::Float32;

    const glm::vec3 sky(o.sky[0], o.sky[1], o.sky[2]);
    const glm::vec3 light(o.light[0], o.light[1], o.light[2]);
    std::vector<sh::ShRgb> probes(desc.grid.probeCount());
    for (size_t i = 0; i < probes.size(); ++i) {
        const glm::vec3 p = desc.grid.probeWorld(desc.grid.probeCoords(i));
        const glm::vec3 to_light = light - p;
        const float d2 = glm::dot(to_light, to_light);
        probes[i] =
            sh::projectDelta(glm::normalize(to_light), glm::vec3(o.intensity / d2), desc.shOrder);
        // A uniform sky only has a band-0 term: L00 = sqrt(4 pi) * L.
        probes[i].rgb[0] += sky * (2.0f * std::sqrt(sh::kPi));
    }
    Result<Volume> volume = makeVolume(desc, probes);
    if (!volume) {
        printError("synth", volume.error().message);
        return kExitFailure;
    }
    PvolFile file;
    file.metadata.toolVersion = "probekit " PROBEKIT_VERSION_STRING;
    file.metadata.method = "synthetic";
    file.metadata.parametersJson =
        nlohmann::json{{"sky_radiance", o.sky},
                       {"point_light", {{"position", o.light}, {"intensity", o.intensity}}}}
            .dump();
    // No wall time in the file (bakeSeconds stays 0): the same flags give the same bytes.
    file.volumes.push_back(std::move(volume).value());
    if (auto w = writePvol(o.output, file); !w) {
        printError("synth", w.error().message);
        return kExitFailure;
    }
    std::printf("wrote %s: %ux%ux%u %s probes, L%d, %s\n", o.output.c_str(), o.resolution[0],
                o.resolution[1], o.resolution[2], o.position.c_str(), o.shOrder, o.format.c_str());
    return kExitOk;
}

} // namespace

void addSynthCommand(CLI::App& app, Command& selected) {
    auto o = std::make_shared<SynthOptions>();
    CLI::App* cmd = app.add_subcommand(
        "synth", "Write an analytic example volume (uniform sky + one point light, exact SH)");
    cmd->add_option("-o,--output", o->output, "output .pvol")->required();
    cmd->add_option("--resolution", o->resolution, "probes per axis X,Y,Z (powers of two)")
        ->delimiter(',')
        ->expected(3)
        ->capture_default_str();
    cmd->add_option("--position", o->position, "probe placement")
        ->check(CLI::IsMember({"center", "corner"}))
        ->capture_default_str();
    cmd->add_option("--format", o->format, "texel storage")
        ->check(CLI::IsMember({"float", "half"}))
        ->capture_default_str();
    cmd->add_option("--sh-order", o->shOrder, "SH order")
        ->check(CLI::IsMember({1, 2}))
        ->capture_default_str();
    cmd->add_option("--sky", o->sky, "uniform sky radiance R,G,B (W/sr/m^2)")
        ->delimiter(',')
        ->expected(3);
    cmd->add_option("--light", o->light, "point light position X,Y,Z (m)")
        ->delimiter(',')
        ->expected(3);
    cmd->add_option("--intensity", o->intensity, "point light intensity (W/sr)")
        ->capture_default_str();
    cmd->callback([o, &selected] { selected = [o] { return runSynth(*o); }; });
}

} // namespace probekit::cli
