// probekit::formats — the result type every library function returns for untrusted input.
//
// Libraries never throw across their public boundary and never print. A function that can fail
// on input it does not control (a file, a glTF, a Vulkan call) returns Result<T>: either a value
// or an Error whose message names the file and field at fault. Programmer errors (preconditions
// a caller can check) are checked at function entry instead (ARCHITECTURE.md, "Preconditions").
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace probekit {

// What went wrong, coarse enough for callers and tests to branch on; the message carries detail.
enum class ErrorCode {
    Io,                 // the operating system refused a read, write or rename
    BadMagic,           // not a .pvol file
    UnsupportedVersion, // a .pvol format version this build cannot read
    Truncated,          // fewer bytes than the header or a field promises
    TrailingBytes,      // bytes after the end of the payload
    ChecksumMismatch,   // payload bytes do not hash to the stored checksum
    InconsistentSize,   // a count or size disagrees with another field
    BadResolution,      // a grid resolution outside 1..256 or not a power of two
    NonFinite,          // NaN or infinity where a finite number is required
    OutOfRange,         // a finite value outside the range its field allows
    BadEnum,            // an enum field holds a value this build does not know
    InvalidArgument,    // input rejected for any other stated reason
};

struct Error {
    ErrorCode code = ErrorCode::InvalidArgument;
    std::string message;
};

// Either a T or an Error. Deliberately small: value(), error(), ok(), explicit bool.
template <class T>
class [[nodiscard]] Result {
public:
    Result(T value) : m_state(std::in_place_index<0>, std::move(value)) {}
    Result(Error error) : m_state(std::in_place_index<1>, std::move(error)) {}

    bool ok() const { return m_state.index() == 0; }
    explicit operator bool() const { return ok(); }

    T& value() & {
        assert(ok());
        return std::get<0>(m_state);
    }
    const T& value() const& {
        assert(ok());
        return std::get<0>(m_state);
    }
    T&& value() && {
        assert(ok());
        return std::get<0>(std::move(m_state));
    }
    const Error& error() const {
        assert(!ok());
        return std::get<1>(m_state);
    }

private:
    std::variant<T, Error> m_state;
};

// Result of an operation that yields nothing but may fail.
template <>
class [[nodiscard]] Result<void> {
public:
    Result() = default;
    Result(Error error) : m_error(std::move(error)), m_failed(true) {}

    bool ok() const { return !m_failed; }
    explicit operator bool() const { return ok(); }
    const Error& error() const {
        assert(m_failed);
        return m_error;
    }

private:
    Error m_error;
    bool m_failed = false;
};

inline Error makeError(ErrorCode code, std::string message) {
    return Error{code, std::move(message)};
}

} // namespace probekit
