// probekit: command-line front end. argv -> options struct -> one library call per subcommand.
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
#include <limits>
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

// Refuses a number that is not finite: "nan", "inf", "-infinity" or "1e999" (which the
// conversion takes as infinity). CLI11 converts floating-point text with strtold, which accepts
// all of them, and a NaN exposure or normal offset went on to write a black image. Beyond the
// float range (3.4e38) is refused too: most options are float, where 1e39 becomes infinity.
std::string refuseNonFinite(const std::string& text) {
    const char* begin = text.c_str();
    char* end = nullptr;
    const double value = std::strtod(begin, &end);
    if (end == begin || *end != '\0') {
        return {}; // not a number: left to the option's own conversion and checks
    }
    if (!std::isfinite(value)) {
        return "\"" + text + "\" is not a finite number";
    }
    if (std::abs(value) > double(std::numeric_limits<float>::max())) {
        return "\"" + text + "\" is beyond the float range (3.4e38)";
    }
    return {};
}

// Every floating-point option of every command (CLI11 names their type FLOAT, vectors of them
// included) gets the finite check, so that a new option cannot miss it. Options that take
// numbers inside a string (--env R,G,B) check them where they are parsed.
void requireFiniteNumbers(CLI::App& app) {
    static const CLI::Validator finite(refuseNonFinite, "FINITE", "finite");
    for (CLI::Option* option : app.get_options()) {
        if (option->get_type_name().find("FLOAT") != std::string::npos) {
            option->check(finite);
        }
    }
    for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
        requireFiniteNumbers(*sub);
    }
}

// Output a command printed that never reached its destination (a full disk, a closed pipe
// read by nothing) fails the command: `probekit info x.pvol > /dev/full` exited 0 with nothing
// written. stdout is fully buffered when redirected, so most of a short output is written here,
// by the flush; a write that failed earlier left the stream's error flag set. std::cout shares
// stdout's buffer (sync_with_stdio is never turned off). Returns the exit status to use.
int checkStandardOutput(const std::string& command, int status) {
    errno = 0;
    std::cout.flush();
    const bool flushed = std::fflush(stdout) == 0;
    const int error = errno;
    if (flushed && !std::ferror(stdout) && !std::cout.fail()) {
        return status;
    }
    probekit::cli::printError(command, std::string("cannot write standard output: ") +
                                           (error != 0 ? std::strerror(error) : "a write failed"));
    return status == probekit::cli::kExitOk ? probekit::cli::kExitFailure : status;
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
    requireFiniteNumbers(app);

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
        return checkStandardOutput(command, selected());
    } catch (const std::exception& e) {
        probekit::cli::printError(command, std::string("internal error: ") + e.what());
    } catch (...) {
        probekit::cli::printError(command, "internal error: an unknown exception");
    }
    return probekit::cli::kExitFailure;
}
