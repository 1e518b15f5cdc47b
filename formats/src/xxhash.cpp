// xxHash64, written from Yann Collet's public algorithm description
// (https://github.com/Cyan4973/xxHash/blob/dev/doc/xxhash_spec.md). The .pvol checksum and the
// scene hash both use it, so its output is part of the file format and must never change.
#include "xxhash64.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

#include "probekit/formats/pvol.hpp"

namespace probekit {

namespace {

constexpr uint64_t kPrime1 = 0x9E3779B185EBCA87ull;
constexpr uint64_t kPrime2 = 0xC2B2AE3D27D4EB4Full;
constexpr uint64_t kPrime3 = 0x165667B19E3779F9ull;
constexpr uint64_t kPrime4 = 0x85EBCA77C2B2AE63ull;
constexpr uint64_t kPrime5 = 0x27D4EB2F165667C5ull;

// memcpy makes unaligned loads legal; the spec reads every word little-endian whatever the host.
template <class Word>
inline Word loadLe(const uint8_t* p) {
    static_assert(sizeof(Word) == 4 || sizeof(Word) == 8);
    Word v;
    std::memcpy(&v, p, sizeof(v));
    if constexpr (std::endian::native == std::endian::big) {
        if constexpr (sizeof(Word) == 8) {
            v = __builtin_bswap64(v);
        } else {
            v = __builtin_bswap32(v);
        }
    }
    return v;
}

inline uint64_t round(uint64_t acc, uint64_t lane) {
    acc += lane * kPrime2;
    acc = std::rotl(acc, 31);
    return acc * kPrime1;
}

inline uint64_t mergeAccumulator(uint64_t hash, uint64_t acc) {
    hash ^= round(0, acc);
    return hash * kPrime1 + kPrime4;
}

inline uint64_t avalanche(uint64_t hash) {
    hash ^= hash >> 33;
    hash *= kPrime2;
    hash ^= hash >> 29;
    hash *= kPrime3;
    hash ^= hash >> 32;
    return hash;
}

// Consumes every whole 32-byte stripe of [p, p + size) and returns how many bytes it used. The
// four accumulators stay in registers and are independent, so the CPU overlaps their multiplies.
inline size_t consumeStripes(uint64_t (&acc)[4], const uint8_t* p, size_t size) {
    uint64_t acc1 = acc[0];
    uint64_t acc2 = acc[1];
    uint64_t acc3 = acc[2];
    uint64_t acc4 = acc[3];
    const size_t stripes = size / 32;
    for (size_t i = 0; i < stripes; ++i, p += 32) {
        acc1 = round(acc1, loadLe<uint64_t>(p));
        acc2 = round(acc2, loadLe<uint64_t>(p + 8));
        acc3 = round(acc3, loadLe<uint64_t>(p + 16));
        acc4 = round(acc4, loadLe<uint64_t>(p + 24));
    }
    acc[0] = acc1;
    acc[1] = acc2;
    acc[2] = acc3;
    acc[3] = acc4;
    return stripes * 32;
}

} // namespace

namespace detail {

XxHash64::XxHash64(uint64_t seed)
    : m_seed(seed), m_acc{seed + kPrime1 + kPrime2, seed + kPrime2, seed, seed - kPrime1} {}

void XxHash64::update(std::span<const uint8_t> bytes) {
    if (bytes.empty()) {
        return; // also keeps a null data() away from memcpy
    }
    const uint8_t* p = bytes.data();
    size_t size = bytes.size();
    m_totalBytes += size;

    if (m_pendingBytes > 0) {
        const size_t take = std::min(size, kStripeBytes - m_pendingBytes);
        std::memcpy(m_pending + m_pendingBytes, p, take);
        m_pendingBytes += take;
        p += take;
        size -= take;
        if (m_pendingBytes < kStripeBytes) {
            return;
        }
        consumeStripes(m_acc, m_pending, kStripeBytes);
        m_pendingBytes = 0;
    }
    const size_t used = consumeStripes(m_acc, p, size);
    if (used < size) {
        std::memcpy(m_pending, p + used, size - used);
        m_pendingBytes = size - used;
    }
}

uint64_t XxHash64::digest() const {
    uint64_t hash;
    if (m_totalBytes >= kStripeBytes) {
        hash = std::rotl(m_acc[0], 1) + std::rotl(m_acc[1], 7) + std::rotl(m_acc[2], 12) +
               std::rotl(m_acc[3], 18);
        for (uint64_t acc : m_acc) {
            hash = mergeAccumulator(hash, acc);
        }
    } else {
        hash = m_seed + kPrime5;
    }
    hash += m_totalBytes;

    // The tail (< 32 bytes) is consumed in 8-, then 4-, then 1-byte steps.
    const uint8_t* p = m_pending;
    const uint8_t* const end = m_pending + m_pendingBytes;
    while (end - p >= 8) {
        hash ^= round(0, loadLe<uint64_t>(p));
        hash = std::rotl(hash, 27) * kPrime1 + kPrime4;
        p += 8;
    }
    if (end - p >= 4) {
        hash ^= uint64_t(loadLe<uint32_t>(p)) * kPrime1;
        hash = std::rotl(hash, 23) * kPrime2 + kPrime3;
        p += 4;
    }
    while (p < end) {
        hash ^= uint64_t(*p) * kPrime5;
        hash = std::rotl(hash, 11) * kPrime1;
        ++p;
    }
    return avalanche(hash);
}

} // namespace detail

uint64_t xxhash64(std::span<const uint8_t> bytes, uint64_t seed) {
    detail::XxHash64 state(seed);
    state.update(bytes);
    return state.digest();
}

} // namespace probekit
