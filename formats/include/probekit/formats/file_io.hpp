// probekit::formats — the file rules every library and tool follows.
//
// Input: only regular files are read, and only up to a stated size. A file is opened
// non-blocking and checked with fstat before the first read, so a FIFO, a device, a socket or a
// directory is refused at once ("not a regular file (it is a FIFO)") instead of blocking forever
// or reading without end (/dev/zero).
//
// Output: writeFileAtomic writes a temporary file beside the target, flushes it to disk and
// renames it over the target. It replaces only a regular file or creates a new one: an existing
// target that is a directory, a device, a FIFO or a socket is refused before anything is
// written. A symbolic link is followed (to its final target, up to 40 links deep): the target
// file is replaced atomically in the target's own directory and the link stays, so a link the
// user set up to redirect an output keeps working. A dangling link creates its target, as a
// shell's `>` does.
//
// Interrupts: the temporary files being written at any moment are listed in a fixed-size,
// lock-free registry; removeTemporaryFilesForSignal() removes them from a signal handler. The
// library never installs a handler itself: the probekit CLI does, for SIGINT, SIGTERM and SIGHUP.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "probekit/formats/result.hpp"

namespace probekit {

// Reads a whole regular file of at most `max_bytes` bytes. `what` names the file's role in the
// messages ("config file", "points file"). Errors (ErrorCode::Io unless said otherwise):
//   "<path>: cannot open the <what>: <reason>"
//   "<path>: the <what> is not a regular file (it is a directory)"   (or FIFO, device, socket)
//   "<path>: the <what> is <n> bytes, more than the limit of <max_bytes> bytes"  (OutOfRange)
Result<std::string> readRegularFile(const std::filesystem::path& path, uint64_t max_bytes,
                                    std::string_view what);

// What kind of file an st_mode names, for messages: "a directory", "a FIFO", "a character
// device", "a block device", "a socket", "a symbolic link", "a regular file".
std::string_view fileTypeText(uint32_t st_mode);

// Checks that `path` may be written by writeFileAtomic and returns the file that would be
// replaced or created: `path` itself, or the final target of the symbolic links it names.
// Fails, naming the path and what it is, when the target exists and is not a regular file, or
// the links loop or run deeper than 40. Commands call it before long work so that a bad -o fails
// at once; writeFileAtomic checks again when it writes.
Result<std::filesystem::path> resolveOutputPath(const std::filesystem::path& path);

// A command's file, named for messages: {"out.pvol", "-o"}, {"scene.gltf", "the scene"}.
struct NamedPath {
    std::filesystem::path path;
    std::string role;
};

// Checks, before any long work, everything about a command's outputs that can be known before
// they are written, so that a bake does not end in a failed write or destroy what it read:
//   * each output is a file path (not empty, no trailing slash) that resolveOutputPath accepts;
//   * its folder exists, is a folder, and takes the temporary file writeFileAtomic would create
//     there (created and removed now: a read-only folder or file system, a name too long, no
//     permission);
//   * no output is an input (same file, through links or hard links) and no two outputs are
//     the same file.
// Errors name the path and its role: "scene.gltf: -o is the scene; it would be overwritten".
Result<void> checkOutputs(std::span<const NamedPath> outputs, std::span<const NamedPath> inputs);

// Writes bytes atomically: a temporary file in the target's directory, fsync, rename over the
// target (resolveOutputPath's rule above). If anything fails the temporary file is removed, the
// target is untouched (an existing file keeps its old contents) and the error names the path.
Result<void> writeFileAtomic(const std::filesystem::path& path, std::span<const uint8_t> bytes);
// The same for text (CSV, JSON, glTF).
inline Result<void> writeFileAtomic(const std::filesystem::path& path, std::string_view text) {
    return writeFileAtomic(path,
                           std::span(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

// Removes every temporary file that writeFileAtomic is writing at this moment, in any thread.
// Async-signal-safe (atomic loads and unlink() only): meant for a signal handler that then lets
// the signal end the process. Up to kMaxTrackedTemporaries writes at once, with absolute paths
// of up to kMaxTrackedPathBytes bytes, are tracked; a write beyond either limit still works but
// its temporary may survive a signal.
void removeTemporaryFilesForSignal() noexcept;
constexpr size_t kMaxTrackedTemporaries = 32;
constexpr size_t kMaxTrackedPathBytes = 4096;

} // namespace probekit
