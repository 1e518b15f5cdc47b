// probekit::baker — counter-based random numbers for the bakers.
//
// Determinism is the point (ARCHITECTURE.md, "Output is deterministic"): every random number a bake
// uses is a pure function of (seed, volume index, probe index, sample index) and the order of draws
// within one sample, never of the clock, the thread or the order in which probes are visited.
// So the same input gives a bit-identical volume whatever the thread count.
//
// Two generators:
//  * Rng: a SplitMix64 stream (Steele, Lea, Flood, "Fast Splittable Pseudorandom Number
//    Generators", OOPSLA 2014) keyed by hashing the indices; one stream per path.
//  * scrambledSobol2d: the first two Sobol dimensions (a (0,2)-sequence), index-shuffled and
//    Owen-scrambled with the Laine-Karras hash of Burley, "Practical Hash-based Owen Scrambling"
//    (JCGT 2020). Each point is exactly uniform on [0,1)^2 over the scramble seed (the
//    permutation is a fixed bijection applied to x + seed), so estimators built on it stay
//    unbiased; and the first 2^k points form a (0,k,2)-net (the scramble is nested: output bit k
//    depends only on input bits of higher significance), so they stratify the square in every
//    elementary interval of area 2^-k.
//
// Everything here is header-only, allocation-free and constexpr where it can be.
#pragma once

#include <cstdint>

#include <glm/vec2.hpp>

namespace probekit::baker {

// The SplitMix64 / MurmurHash3 64-bit finaliser: a bijection with full avalanche.
constexpr uint64_t mix64(uint64_t x) {
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    x ^= x >> 31;
    return x;
}

// Hash of an ordered list of 64-bit keys. Each key passes through the golden-ratio increment and
// the finaliser, so (a, b) and (b, a) give unrelated results.
constexpr uint64_t hashKeys(uint64_t a, uint64_t b) {
    return mix64(mix64(a + 0x9e3779b97f4a7c15ull) ^ (b + 0x632be59bd9b4e019ull));
}
constexpr uint64_t hashKeys(uint64_t a, uint64_t b, uint64_t c) {
    return hashKeys(hashKeys(a, b), c);
}

// A SplitMix64 stream. Copyable value type; one per path, never shared between threads.
class Rng {
public:
    explicit constexpr Rng(uint64_t key) : m_state(key) {}

    constexpr uint64_t nextBits() {
        m_state += 0x9e3779b97f4a7c15ull;
        return mix64(m_state);
    }
    // Uniform in [0, 1) on the 2^-24 grid: every value is exactly representable and < 1.
    constexpr float uniform() { return float(nextBits() >> 40) * 0x1p-24f; }
    constexpr glm::vec2 uniform2() {
        const float a = uniform();
        return glm::vec2(a, uniform());
    }
    // Uniform in [0, 1) on the 2^-53 grid, for inverting long discrete CDFs without losing
    // small entries to float resolution.
    constexpr double uniformDouble() { return double(nextBits() >> 11) * 0x1p-53; }

private:
    uint64_t m_state;
};

constexpr uint32_t reverseBits(uint32_t x) {
    x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
    x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
    x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
    x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
    return (x >> 16) | (x << 16);
}

// Sobol dimension 0 is the van der Corput sequence: the bit-reversed index.
constexpr uint32_t sobolDimension0(uint32_t index) {
    return reverseBits(index);
}

// Sobol dimension 1: direction numbers v_0 = 2^31, v_k = v_{k-1} ^ (v_{k-1} >> 1); the point is
// the XOR of v_k over the set bits k of the index, looked up a byte at a time.
namespace detail {
struct SobolDimension1Tables {
    uint32_t byte[4][256];
};
constexpr SobolDimension1Tables makeSobolDimension1Tables() {
    SobolDimension1Tables tables{};
    uint32_t v[32]{};
    v[0] = 0x80000000u;
    for (int k = 1; k < 32; ++k) {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
    }
    for (int b = 0; b < 4; ++b) {
        for (uint32_t value = 0; value < 256; ++value) {
            uint32_t x = 0;
            for (int bit = 0; bit < 8; ++bit) {
                if (value & (1u << bit)) {
                    x ^= v[8 * b + bit];
                }
            }
            tables.byte[b][value] = x;
        }
    }
    return tables;
}
inline constexpr SobolDimension1Tables kSobolDimension1 = makeSobolDimension1Tables();
} // namespace detail

constexpr uint32_t sobolDimension1(uint32_t index) {
    const auto& t = detail::kSobolDimension1.byte;
    return t[0][index & 0xffu] ^ t[1][(index >> 8) & 0xffu] ^ t[2][(index >> 16) & 0xffu] ^
           t[3][index >> 24];
}

// Nested scramble of the bits of x (most significant first), keyed by seed: bit-reverse, apply
// the Laine-Karras permutation (add the seed, then x ^= x * even constant: each bit is flipped
// depending only on less significant bits), reverse back (Burley 2020, listing 2). The seed
// enters only through the first addition, which is what makes each output uniform over seeds.
constexpr uint32_t owenScramble(uint32_t x, uint32_t seed) {
    x = reverseBits(x);
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return reverseBits(x);
}

// Point `index` of a per-seed shuffled, Owen-scrambled 2D Sobol sequence, in [0, 1)^2
// (values on the 2^-24 grid so that they are exact floats below 1).
constexpr glm::vec2 scrambledSobol2d(uint32_t index, uint32_t seed) {
    const uint32_t shuffled = owenScramble(index, seed);
    const uint64_t dims = hashKeys(seed, 0x50b01ull);
    const uint32_t x = owenScramble(sobolDimension0(shuffled), uint32_t(dims));
    const uint32_t y = owenScramble(sobolDimension1(shuffled), uint32_t(dims >> 32));
    return glm::vec2(float(x >> 8) * 0x1p-24f, float(y >> 8) * 0x1p-24f);
}

} // namespace probekit::baker
