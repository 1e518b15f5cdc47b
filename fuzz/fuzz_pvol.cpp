// libFuzzer target: untrusted .pvol bytes through decodePvol and validateVolume.
//
// Each input is decoded twice: as it is (the header, length and checksum checks), and with the
// header's payload length and xxHash64 rewritten to match the bytes that follow, so that
// mutations of the payload reach the parser instead of stopping at the checksum.
//
// Beyond "no crash, no sanitizer report": a file that decodes must re-encode to bytes that
// decode again and re-encode to the same bytes (the decoder accepts only what the encoder can
// reproduce), and every probe of it must give finite irradiance, as the runtime evaluates it.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"

namespace {

// Prints why the input is a failure, then aborts so libFuzzer saves it.
[[noreturn]] void fail(const char* why) {
    std::fprintf(stderr, "fuzz_pvol: %s\n", why);
    std::abort();
}

void checkDecoded(std::span<const uint8_t> bytes) {
    const auto decoded = probekit::decodePvol(bytes, "fuzz.pvol");
    if (!decoded) {
        return;
    }
    for (const probekit::Volume& volume : decoded.value().volumes) {
        if (!probekit::validateVolume(volume)) {
            fail("decodePvol returned a volume that validateVolume rejects");
        }
        for (size_t i = 0; i < volume.probeCount(); ++i) {
            for (const glm::vec3 normal : {glm::vec3(0, 1, 0), glm::vec3(0.6f, -0.8f, 0)}) {
                const glm::vec3 e =
                    probekit::sh::irradiance(volume.probe(i), volume.desc.shOrder, normal);
                if (!std::isfinite(e.x) || !std::isfinite(e.y) || !std::isfinite(e.z)) {
                    fail("a file validate accepts would shade as NaN or infinity");
                }
            }
        }
    }
    const std::vector<uint8_t> once = probekit::encodePvol(decoded.value());
    const auto again = probekit::decodePvol(once, "fuzz re-encoded");
    if (!again || probekit::encodePvol(again.value()) != once) {
        fail("the encoder wrote something its own decoder does not reproduce");
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    checkDecoded(std::span<const uint8_t>(data, size));
    if (size >= probekit::kPvolHeaderBytes) {
        // Layout in pvol.hpp: payload bytes (u64) at offset 16, checksum (u64) at offset 24.
        std::vector<uint8_t> fixed(data, data + size);
        const std::span<const uint8_t> payload(fixed.data() + probekit::kPvolHeaderBytes,
                                               size - probekit::kPvolHeaderBytes);
        const uint64_t payload_bytes = payload.size();
        const uint64_t checksum = probekit::xxhash64(payload);
        std::memcpy(fixed.data() + 16, &payload_bytes, sizeof(payload_bytes)); // little-endian host
        std::memcpy(fixed.data() + 24, &checksum, sizeof(checksum));
        checkDecoded(fixed);
    }
    return 0;
}
