// probekit::check — always-on precondition checks at public entry points.
//
// CI and users build Release, where assert() is compiled out. A precondition whose violation
// would read or write out of bounds or use an invalid object, at a function that cannot report
// it as a Result (a constructor, an accessor, a function returning a plain value), is checked
// with PK_CHECK instead: in every build type a failure prints "probekit: precondition failed",
// the violated condition, the function and the source line to stderr and aborts. This is the
// one place a library prints or ends the process (ARCHITECTURE.md, "Preconditions"): the caller
// has a bug, and going on would corrupt memory. Functions that return Result report such
// arguments as errors instead, and hot per-probe accessors keep assert where a check would cost
// measurable time.
#pragma once

#include "probekit/formats/result.hpp"

namespace probekit::detail {

// Prints the failed check (`detail`, when not null, is the error message of PK_CHECK_OK's
// Result) and aborts. Out of line, so that a check costs a compare and a branch at its site.
[[noreturn]] void checkFailed(const char* condition, const char* detail, const char* function,
                              const char* file, int line);

} // namespace probekit::detail

// Aborts, naming the condition, unless it holds.
#define PK_CHECK(condition)                                                                        \
    do {                                                                                           \
        if (!(condition)) [[unlikely]] {                                                           \
            ::probekit::detail::checkFailed(#condition, nullptr, __func__, __FILE__, __LINE__);    \
        }                                                                                          \
    } while (false)

// Aborts, naming the expression and the Error's message, unless the Result<void> is ok.
#define PK_CHECK_OK(expression)                                                                    \
    do {                                                                                           \
        if (const ::probekit::Result<void> pk_check_result = (expression); !pk_check_result)       \
            [[unlikely]] {                                                                         \
            ::probekit::detail::checkFailed(#expression, pk_check_result.error().message.c_str(),  \
                                            __func__, __FILE__, __LINE__);                         \
        }                                                                                          \
    } while (false)
