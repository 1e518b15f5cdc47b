// Test-only LD_PRELOAD library for tests/cli/cli_test.sh: it makes a write slow enough to be
// interrupted, without any hook in probekit itself. When PROBEKIT_TEST_PAUSE_MARKER names a file,
// an fsync() of a file whose path holds ".tmp." (writeFileAtomic's temporary, fully written by
// then) creates that marker and then waits for signals forever; the test sees the marker and
// sends its signal while the command is inside its write. Every other fsync() is the C
// library's.
#include <cstdlib>
#include <cstring>
#include <string>

#include <dlfcn.h>
#include <fcntl.h>
#include <unistd.h>

namespace {

bool isTemporary(int fd) {
    char path[4096];
    const std::string link = "/proc/self/fd/" + std::to_string(fd);
    const ssize_t n = ::readlink(link.c_str(), path, sizeof path - 1);
    if (n <= 0) {
        return false;
    }
    path[n] = '\0';
    return std::strstr(path, ".tmp.") != nullptr;
}

} // namespace

extern "C" int fsync(int fd) {
    const char* marker = std::getenv("PROBEKIT_TEST_PAUSE_MARKER");
    if (marker != nullptr && isTemporary(fd)) {
        const int made = ::open(marker, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
        if (made >= 0) {
            ::close(made);
        }
        while (true) {
            ::pause(); // returns only after a handler that returned; the test's signal ends us
        }
    }
    using Fsync = int (*)(int);
    static const auto real = reinterpret_cast<Fsync>(::dlsym(RTLD_NEXT, "fsync"));
    return real(fd);
}
