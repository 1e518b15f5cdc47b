// Private to probekit::formats: incremental xxHash64, for data that arrives in pieces. readPvol
// hashes the payload while it reads it straight into the volumes, so the file is touched once.
// The public one-shot xxhash64() (pvol.hpp) is this class over a single span.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace probekit::detail {

class XxHash64 {
public:
    explicit XxHash64(uint64_t seed = 0);

    // Any split of the same bytes into update() calls gives the same digest.
    void update(std::span<const uint8_t> bytes);
    // The hash of everything passed to update() so far; does not change the state.
    uint64_t digest() const;

private:
    static constexpr size_t kStripeBytes = 32;

    uint64_t m_seed;
    uint64_t m_acc[4];
    uint64_t m_totalBytes = 0;
    uint8_t m_pending[kStripeBytes] = {}; // start of an incomplete stripe
    size_t m_pendingBytes = 0;
};

} // namespace probekit::detail
