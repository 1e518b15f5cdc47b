// Private to formats: a descriptor owner and the one way formats opens a file for reading.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include <unistd.h>

#include "probekit/formats/result.hpp"

namespace probekit::detail {

// Closes a descriptor on every path out of a function.
class FileDescriptor {
public:
    FileDescriptor() = default;
    explicit FileDescriptor(int fd) : m_fd(fd) {}
    FileDescriptor(FileDescriptor&& other) noexcept : m_fd(other.m_fd) { other.m_fd = -1; }
    FileDescriptor& operator=(FileDescriptor&& other) noexcept {
        if (this != &other) {
            reset();
            m_fd = other.m_fd;
            other.m_fd = -1;
        }
        return *this;
    }
    FileDescriptor(const FileDescriptor&) = delete;
    FileDescriptor& operator=(const FileDescriptor&) = delete;
    ~FileDescriptor() { reset(); }
    int get() const { return m_fd; }
    // Closes now and reports the result: close() can be the first to report a failed write
    // (NFS, quotas), so the atomic writer must check it rather than leave it to the destructor.
    int close() {
        const int rc = ::close(m_fd);
        m_fd = -1;
        return rc;
    }

private:
    void reset() {
        if (m_fd >= 0) {
            ::close(m_fd);
        }
        m_fd = -1;
    }
    int m_fd = -1;
};

struct OpenedFile {
    FileDescriptor fd;
    uint64_t bytes = 0; // st_size when opened
};

// Opens a regular file for reading without ever blocking on a FIFO: O_NONBLOCK for the open,
// fstat, refusal of anything but a regular file, then blocking reads again. `what` names the
// file's role in messages ("config file"); empty for plain "<path>: not a regular file ...".
Result<OpenedFile> openRegularFile(const std::filesystem::path& path, std::string_view what);

std::string errnoText(int error);

} // namespace probekit::detail
