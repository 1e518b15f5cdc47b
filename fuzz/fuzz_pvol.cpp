// libFuzzer target: untrusted .pvol bytes through decodePvol and validateVolume. Beyond "no
// crash, no sanitizer report", a file that decodes must re-encode to bytes that decode again and
// re-encode to the same bytes: the decoder accepts only what the encoder can reproduce.
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "probekit/formats/pvol.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const auto decoded = probekit::decodePvol(std::span<const uint8_t>(data, size), "fuzz.pvol");
    if (!decoded) {
        return 0;
    }
    for (const probekit::Volume& volume : decoded.value().volumes) {
        if (!probekit::validateVolume(volume)) {
            std::abort(); // decodePvol returned a volume that validateVolume rejects
        }
    }
    const std::vector<uint8_t> once = probekit::encodePvol(decoded.value());
    const auto again = probekit::decodePvol(once, "fuzz re-encoded");
    if (!again || probekit::encodePvol(again.value()) != once) {
        std::abort(); // the encoder wrote something its own decoder does not reproduce
    }
    return 0;
}
