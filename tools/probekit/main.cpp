// probekit: command-line front end. argv -> options struct -> one library call per subcommand.
#include <cstdio>

#include "commands.hpp"

int main(int argc, char** argv) {
    CLI::App app{"probekit " PROBEKIT_VERSION_STRING
                 ": offline light-probe-volume baker and runtime sampler"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "probekit " PROBEKIT_VERSION_STRING);

    probekit::cli::Command selected;
    probekit::cli::addInfoCommand(app, selected);
    probekit::cli::addValidateCommand(app, selected);
    probekit::cli::addSynthCommand(app, selected);
    probekit::cli::addSceneCommand(app, selected);
    probekit::cli::addBakeCommand(app, selected);
    probekit::cli::addBenchRaysCommand(app, selected);
    probekit::cli::addSampleCommand(app, selected);
    probekit::cli::addRenderCommand(app, selected);
    probekit::cli::addDiffCommand(app, selected);
    probekit::cli::addBenchCommand(app, selected);

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int code = app.exit(e);
        return code == 0 ? probekit::cli::kExitOk : probekit::cli::kExitUsage;
    }
    return selected();
}
