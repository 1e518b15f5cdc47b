#include "probekit/formats/file_io.hpp"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <string>
#include <system_error>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "posix_file.hpp"

namespace probekit {

namespace detail {

std::string errnoText(int error) {
    return std::generic_category().message(error);
}

namespace {

std::string notRegularMessage(const std::filesystem::path& path, std::string_view what,
                              uint32_t mode) {
    const std::string kind = "not a regular file (it is " + std::string(fileTypeText(mode)) + ")";
    return path.string() + ": " +
           (what.empty() ? kind : "the " + std::string(what) + " is " + kind);
}

std::string openFailedMessage(const std::filesystem::path& path, std::string_view what, int error) {
    return path.string() + ": cannot open" + (what.empty() ? "" : " the " + std::string(what)) +
           ": " + errnoText(error);
}

} // namespace

Result<OpenedFile> openRegularFile(const std::filesystem::path& path, std::string_view what) {
    // stat first, so that a device is never opened at all (opening one can have effects, and a
    // FIFO's open blocks until a writer comes); the non-blocking open and fstat below close the
    // window in which the path could be swapped for one.
    struct stat info {};
    if (::stat(path.c_str(), &info) != 0) {
        return makeError(ErrorCode::Io, openFailedMessage(path, what, errno));
    }
    if (!S_ISREG(info.st_mode)) {
        return makeError(ErrorCode::Io, notRegularMessage(path, what, info.st_mode));
    }
    FileDescriptor fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC));
    if (fd.get() < 0) {
        return makeError(ErrorCode::Io, openFailedMessage(path, what, errno));
    }
    if (::fstat(fd.get(), &info) != 0) {
        return makeError(ErrorCode::Io, path.string() + ": cannot stat: " + errnoText(errno));
    }
    if (!S_ISREG(info.st_mode)) {
        return makeError(ErrorCode::Io, notRegularMessage(path, what, info.st_mode));
    }
    // Regular files ignore O_NONBLOCK today; clearing it keeps reads blocking if that changes.
    const int flags = ::fcntl(fd.get(), F_GETFL);
    if (flags < 0 || ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK) != 0) {
        return makeError(ErrorCode::Io,
                         path.string() + ": cannot set blocking reads: " + errnoText(errno));
    }
    OpenedFile opened;
    opened.bytes = uint64_t(info.st_size);
    opened.fd = std::move(fd);
    return opened;
}

} // namespace detail

using detail::errnoText;
using detail::FileDescriptor;

std::string_view fileTypeText(uint32_t st_mode) {
    if (S_ISREG(st_mode)) {
        return "a regular file";
    }
    if (S_ISDIR(st_mode)) {
        return "a directory";
    }
    if (S_ISFIFO(st_mode)) {
        return "a FIFO";
    }
    if (S_ISCHR(st_mode)) {
        return "a character device";
    }
    if (S_ISBLK(st_mode)) {
        return "a block device";
    }
    if (S_ISSOCK(st_mode)) {
        return "a socket";
    }
    if (S_ISLNK(st_mode)) {
        return "a symbolic link";
    }
    return "an unknown kind of file";
}

Result<std::string> readRegularFile(const std::filesystem::path& path, uint64_t max_bytes,
                                    std::string_view what) {
    auto opened = detail::openRegularFile(path, what);
    if (!opened) {
        return opened.error();
    }
    const std::string role = what.empty() ? std::string("file") : std::string(what);
    auto too_large = [&](uint64_t bytes, bool at_least) {
        return makeError(ErrorCode::OutOfRange,
                         path.string() + ": the " + role + " is " + (at_least ? "over " : "") +
                             std::to_string(bytes) + " bytes, more than the limit of " +
                             std::to_string(max_bytes) + " bytes");
    };
    if (opened.value().bytes > max_bytes) {
        return too_large(opened.value().bytes, false);
    }
    std::string text;
    text.resize(size_t(opened.value().bytes));
    size_t done = 0;
    // Reads to end of file, not to the size fstat gave, so a file that grows while being read is
    // still held to the limit.
    const uint64_t read_cap = max_bytes == UINT64_MAX ? max_bytes : max_bytes + 1;
    while (true) {
        if (done == text.size()) {
            if (done >= read_cap) {
                return too_large(max_bytes, true);
            }
            text.resize(size_t(std::min<uint64_t>(read_cap, done + (size_t(64) << 10))));
        }
        const ssize_t n = ::read(opened.value().fd.get(), text.data() + done, text.size() - done);
        if (n < 0) {
            const int error = errno;
            if (error == EINTR) {
                continue;
            }
            return makeError(ErrorCode::Io, path.string() + ": reading the " + role +
                                                " failed: " + errnoText(error));
        }
        if (n == 0) {
            break;
        }
        done += size_t(n);
    }
    if (done > max_bytes) {
        return too_large(max_bytes, true);
    }
    text.resize(done);
    return text;
}

namespace {

// --- the registry of temporary files, for signal handlers ---------------------------------------
//
// A slot is claimed with a compare-exchange from Free, filled, then published as Active. The
// writer releases it with a compare-exchange from Active back to Free once the temporary is
// renamed or removed; a signal handler takes it with a compare-exchange from Active to Removing
// before reading the path, so no writer can refill the buffer under it. A slot left Removing is
// never reused, which is fine: the handler runs because the process is about to end.
enum SlotState : int { kFree = 0, kFilling = 1, kActive = 2, kRemoving = 3 };

struct TemporarySlot {
    std::atomic<int> state{kFree};
    char path[kMaxTrackedPathBytes];
};
static_assert(std::atomic<int>::is_always_lock_free,
              "the signal handler may only use lock-free atomics");

TemporarySlot g_temporaries[kMaxTrackedTemporaries];

// Lists a temporary path for removeTemporaryFilesForSignal from before the file is created until
// after it is renamed or removed (so the handler may find no file there, never an unlisted one).
class TemporaryRegistration {
public:
    explicit TemporaryRegistration(const std::filesystem::path& temp_path) {
        std::error_code error;
        const std::string absolute = std::filesystem::absolute(temp_path, error).string();
        if (error || absolute.size() >= kMaxTrackedPathBytes) {
            return; // untracked: the write still works, the temporary may outlive a signal
        }
        for (size_t i = 0; i < kMaxTrackedTemporaries; ++i) {
            int expected = kFree;
            if (g_temporaries[i].state.compare_exchange_strong(expected, kFilling,
                                                               std::memory_order_acquire)) {
                std::memcpy(g_temporaries[i].path, absolute.c_str(), absolute.size() + 1);
                g_temporaries[i].state.store(kActive, std::memory_order_release);
                m_slot = int(i);
                return;
            }
        }
    }
    TemporaryRegistration(const TemporaryRegistration&) = delete;
    TemporaryRegistration& operator=(const TemporaryRegistration&) = delete;
    ~TemporaryRegistration() {
        if (m_slot >= 0) {
            int expected = kActive;
            g_temporaries[m_slot].state.compare_exchange_strong(expected, kFree,
                                                                std::memory_order_release);
        }
    }

private:
    int m_slot = -1;
};

Error ioError(const std::filesystem::path& path, const std::string& what, int error) {
    return makeError(ErrorCode::Io, path.string() + ": " + what + ": " + errnoText(error));
}

// Links followed at most, as the kernel's own limit (MAXSYMLINKS).
constexpr int kMaxSymlinkHops = 40;

Result<std::string> readLink(const std::filesystem::path& link, const std::filesystem::path& path,
                             size_t size_hint) {
    std::string target(std::max<size_t>(size_hint, 255) + 1, '\0');
    while (true) {
        const ssize_t n = ::readlink(link.c_str(), target.data(), target.size());
        if (n < 0) {
            return ioError(path, "cannot read the symbolic link " + link.string(), errno);
        }
        if (size_t(n) < target.size()) {
            target.resize(size_t(n));
            return target;
        }
        target.resize(target.size() * 2); // the link grew since lstat
    }
}

} // namespace

void removeTemporaryFilesForSignal() noexcept {
    for (TemporarySlot& slot : g_temporaries) {
        int expected = kActive;
        if (slot.state.compare_exchange_strong(expected, kRemoving, std::memory_order_acquire)) {
            ::unlink(slot.path);
        }
    }
}

Result<std::filesystem::path> resolveOutputPath(const std::filesystem::path& path) {
    // stat follows every link, /proc's magic ones included (/dev/stdout to a pipe), so it alone
    // says what would be written over.
    struct stat info {};
    if (::stat(path.c_str(), &info) == 0) {
        if (!S_ISREG(info.st_mode)) {
            struct stat link_info {};
            const bool is_link =
                ::lstat(path.c_str(), &link_info) == 0 && S_ISLNK(link_info.st_mode);
            return makeError(ErrorCode::Io, path.string() + ": not a regular file (it is " +
                                                (is_link ? "a symbolic link to " : "") +
                                                std::string(fileTypeText(info.st_mode)) +
                                                "); only a regular file is replaced");
        }
    } else if (errno != ENOENT) {
        return ioError(path, "cannot write there", errno);
    }
    // The file to replace or create: the path, or the last link's target. Renaming over a link
    // would replace the link itself.
    std::filesystem::path current = path;
    for (int hop = 0; hop <= kMaxSymlinkHops; ++hop) {
        struct stat link_info {};
        if (::lstat(current.c_str(), &link_info) != 0) {
            if (errno == ENOENT) {
                return current; // a new file, or the missing target of a dangling link
            }
            return ioError(path, "cannot write there", errno);
        }
        if (!S_ISLNK(link_info.st_mode)) {
            if (!S_ISREG(link_info.st_mode)) { // changed since the stat above
                return makeError(ErrorCode::Io, path.string() + ": not a regular file (it is " +
                                                    std::string(fileTypeText(link_info.st_mode)) +
                                                    "); only a regular file is replaced");
            }
            return current;
        }
        auto target = readLink(current, path, size_t(link_info.st_size));
        if (!target) {
            return target.error();
        }
        const std::filesystem::path next(target.value());
        current = next.is_absolute() ? next : current.parent_path() / next;
    }
    return ioError(path, "cannot write there", ELOOP);
}

namespace {

std::filesystem::path folderOf(const std::filesystem::path& target) {
    return target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
}

// writeFileAtomic's temporary for `target`: ".NAME.tmp.PID.TAG" beside it.
std::string temporaryName(const std::filesystem::path& target, const std::string& tag) {
    std::string name = ".";
    name += target.filename().string();
    name += ".tmp." + std::to_string(::getpid()) + "." + tag;
    return name;
}

// One output of checkOutputs: its path, folder and writability. Returns the file it would write.
Result<std::filesystem::path> checkOneOutput(const NamedPath& output) {
    const std::filesystem::path& path = output.path;
    if (path.empty() || !path.has_filename()) {
        std::string message = "'";
        message += path.string();
        message += "': ";
        message += output.role;
        message += " must name a file (it is empty or ends in a slash)";
        return makeError(ErrorCode::InvalidArgument, message);
    }
    Result<std::filesystem::path> target = resolveOutputPath(path);
    if (!target) {
        return target.error();
    }
    const std::filesystem::path folder = folderOf(target.value());
    struct stat info {};
    if (::stat(folder.c_str(), &info) != 0) {
        return ioError(path, "cannot write in the folder " + folder.string(), errno);
    }
    if (!S_ISDIR(info.st_mode)) {
        return makeError(ErrorCode::Io, path.string() + ": " + folder.string() +
                                            " is not a folder (it is " +
                                            std::string(fileTypeText(info.st_mode)) + ")");
    }
    // The temporary the write will create, with as long a name ("check" is as long as the
    // counter of a write will be in any run of fewer than 100,000 writes).
    const std::filesystem::path probe = folder / temporaryName(target.value(), "check");
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
        const int error = errno;
        return ioError(path, "cannot create a file in the folder " + folder.string(), error);
    }
    ::close(fd);
    ::unlink(probe.c_str());
    return target;
}

// The same file: the same inode when both exist, else the same canonical path.
bool sameFile(const std::filesystem::path& a, const std::filesystem::path& b) {
    std::error_code ec;
    if (std::filesystem::equivalent(a, b, ec) && !ec) {
        return true;
    }
    const std::filesystem::path ca = std::filesystem::weakly_canonical(a, ec);
    if (ec) {
        return false;
    }
    const std::filesystem::path cb = std::filesystem::weakly_canonical(b, ec);
    return !ec && ca == cb;
}

} // namespace

Result<void> checkOutputs(std::span<const NamedPath> outputs, std::span<const NamedPath> inputs) {
    std::vector<std::filesystem::path> targets;
    for (const NamedPath& output : outputs) {
        Result<std::filesystem::path> target = checkOneOutput(output);
        if (!target) {
            return target.error();
        }
        for (const NamedPath& input : inputs) {
            if (!input.path.empty() && sameFile(target.value(), input.path)) {
                return makeError(ErrorCode::InvalidArgument,
                                 output.path.string() + ": " + output.role + " is " + input.role +
                                     " (" + input.path.string() + "); it would be overwritten");
            }
        }
        for (size_t i = 0; i < targets.size(); ++i) {
            if (sameFile(target.value(), targets[i])) {
                return makeError(ErrorCode::InvalidArgument,
                                 output.path.string() + ": " + output.role + " and " +
                                     outputs[i].role + " name the same file");
            }
        }
        targets.push_back(target.value());
    }
    return {};
}

Result<void> writeFileAtomic(const std::filesystem::path& path, std::span<const uint8_t> bytes) {
    if (path.filename().empty()) {
        return makeError(ErrorCode::InvalidArgument, path.string() + ": not a file path");
    }
    auto resolved = resolveOutputPath(path);
    if (!resolved) {
        return resolved.error();
    }
    const std::filesystem::path& target = resolved.value();
    // The temporary must live in the target's directory: rename() is only atomic within one
    // file system. pid + counter keep concurrent writers (threads or processes) apart.
    static std::atomic<uint64_t> counter{0};
    const std::filesystem::path directory = folderOf(target);
    const std::filesystem::path temp_path =
        directory / temporaryName(target, std::to_string(counter.fetch_add(1)));

    const TemporaryRegistration registration(temp_path);
    FileDescriptor fd(::open(temp_path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666));
    if (fd.get() < 0) {
        const int error = errno;
        return ioError(path, "cannot create temporary file " + temp_path.string(), error);
    }
    auto abandon = [&](const std::string& what, int error) {
        if (fd.get() >= 0) {
            fd.close();
        }
        ::unlink(temp_path.c_str());
        return ioError(path, what, error);
    };

    size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
        if (n < 0) {
            const int error = errno;
            if (error == EINTR) {
                continue;
            }
            return abandon("write failed after " + std::to_string(done) + " of " +
                               std::to_string(bytes.size()) + " bytes",
                           error);
        }
        done += size_t(n);
    }
    // Without fsync a crash after rename can leave the new name pointing at an empty file.
    if (::fsync(fd.get()) != 0) {
        const int error = errno;
        return abandon("fsync failed", error);
    }
    if (fd.close() != 0) {
        const int error = errno;
        return abandon("close failed", error);
    }
    if (::rename(temp_path.c_str(), target.c_str()) != 0) {
        const int error = errno;
        return abandon("cannot rename temporary file over it", error);
    }
    // Persist the rename itself. Best effort: some file systems refuse fsync on directories and
    // the data is already safe in the file.
    FileDescriptor dir_fd(::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
    if (dir_fd.get() >= 0) {
        ::fsync(dir_fd.get());
    }
    return {};
}

} // namespace probekit
