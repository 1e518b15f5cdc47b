// Subcommands of the probekit CLI. Each registers its options on the app and returns the
// function to run when it is chosen; the function returns the process exit code.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace probekit::cli {

// Exit codes (documented in docs/commands.md#exit-codes):
constexpr int kExitOk = 0;
constexpr int kExitFailure = 1; // the operation failed (bad input, invalid file, I/O error)
constexpr int kExitUsage = 2;   // bad command line (CLI11 parse error)

using Command = std::function<int()>;

// --asset-root DIR, repeatable (probekit bake and info): a folder, besides the scene file's own,
// whose regular files the glTF's buffer and image URIs may name (baker::LoadOptions::assetRoots).
inline void addAssetRootOption(CLI::App* cmd, std::vector<std::string>& roots) {
    cmd->add_option("--asset-root", roots,
                    "also let buffer and image URIs name files under DIR (repeatable; by default "
                    "only files under the scene's own folder are read)")
        ->check(CLI::ExistingDirectory)
        ->type_name("DIR");
}

void addInfoCommand(CLI::App& app, Command& selected);
void addValidateCommand(CLI::App& app, Command& selected);
void addSynthCommand(CLI::App& app, Command& selected);
void addSampleCommand(CLI::App& app, Command& selected);
void addRenderCommand(CLI::App& app, Command& selected);
void addBakeCommand(CLI::App& app, Command& selected);
void addDiffCommand(CLI::App& app, Command& selected);
void addSceneCommand(CLI::App& app, Command& selected);
void addBenchRaysCommand(CLI::App& app, Command& selected);
void addBenchCommand(CLI::App& app, Command& selected);
void addBenchNoiseCommand(CLI::App& app, Command& selected);
void addSurfaceCommands(CLI::App& app, Command& selected);
void addExportCommand(CLI::App& app, Command& selected);

} // namespace probekit::cli
