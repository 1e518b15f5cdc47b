// probekit: command-line front end. argv -> options struct -> one library call per subcommand.
#include <csignal>
#include <cstdio>
#include <exception>
#include <string>

#include <signal.h>

#include "commands.hpp"
#include "distributed.hpp"
#include "probekit/formats/file_io.hpp"
#include "terminal_text.hpp"

namespace {

// An interrupt or hangup during a write must not leave the write's temporary file behind: the
// handler removes every temporary being written (formats' registry, async-signal-safe), then
// lets the signal end the process as it would have without the handler (exit status 128 + n).
extern "C" void removeTemporariesAndDie(int signal_number) {
    probekit::removeTemporaryFilesForSignal();
    ::signal(signal_number, SIG_DFL);
    ::raise(signal_number);
}

void installSignalHandlers() {
    for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) {
        struct sigaction current {};
        // A signal ignored at start stays ignored: nohup ignores SIGHUP, and a shell starts
        // background jobs with SIGINT ignored.
        if (::sigaction(signal_number, nullptr, &current) != 0 || current.sa_handler == SIG_IGN) {
            continue;
        }
        struct sigaction action {};
        action.sa_handler = removeTemporariesAndDie;
        ::sigemptyset(&action.sa_mask);
        ::sigaddset(&action.sa_mask, SIGINT);
        ::sigaddset(&action.sa_mask, SIGTERM);
        ::sigaddset(&action.sa_mask, SIGHUP);
        ::sigaction(signal_number, &action, nullptr);
    }
}

} // namespace

int main(int argc, char** argv) {
    // Under an MPI launcher, join the job first (MPI may rewrite argv); MPI ends with `job`.
    const std::unique_ptr<probekit::cli::DistributedBake> job =
        probekit::cli::DistributedBake::join(argc, argv);
    probekit::cli::setCurrentJob(job.get());
    installSignalHandlers();
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
    probekit::cli::addBenchNoiseCommand(app, selected);
    probekit::cli::addSurfaceCommands(app, selected);
    probekit::cli::addExportCommand(app, selected);

    std::string command = "(command line)";
    // No exception may end the process with SIGABRT: one that escapes a command is a bug,
    // reported as such with exit code 1.
    try {
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            const int code = app.exit(e);
            return code == 0 ? probekit::cli::kExitOk : probekit::cli::kExitUsage;
        }
        if (!app.get_subcommands().empty()) {
            command = app.get_subcommands().front()->get_name();
        }
        return selected();
    } catch (const std::exception& e) {
        probekit::cli::printError(command, std::string("internal error: ") + e.what());
    } catch (...) {
        probekit::cli::printError(command, "internal error: an unknown exception");
    }
    return probekit::cli::kExitFailure;
}
