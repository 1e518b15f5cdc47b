// libFuzzer target: untrusted .pvol bytes through decodePvol, validateVolume and `probekit
// info`'s formatting (formatInfo, text and JSON).
//
// Each input is decoded twice: as it is (the header, length and checksum checks), and with the
// header's payload length and xxHash64 rewritten to match the bytes that follow, so that
// mutations of the payload reach the parser instead of stopping at the checksum.
//
// Beyond "no crash, no sanitizer report": a file that decodes must re-encode to bytes that
// decode again and re-encode to the same bytes (the decoder accepts only what the encoder can
// reproduce), every probe of it must give finite irradiance, as the runtime evaluates it, and
// what `info` prints holds no terminal control byte (text) and parses back (JSON); an error
// message, once escaped for the terminal, holds none either.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "probekit/formats/pvol.hpp"
#include "probekit/formats/sh.hpp"

#include <nlohmann/json.hpp>

#include "info_format.hpp"
#include "terminal_text.hpp"

namespace {

// Prints why the input is a failure, then aborts so libFuzzer saves it.
[[noreturn]] void fail(const char* why) {
    std::fprintf(stderr, "fuzz_pvol: %s\n", why);
    std::abort();
}

// Printable for a terminal: no C0 control but newline, no DEL, no C1 control (U+0080..U+009F,
// encoded C2 80..C2 9F).
bool printable(std::string_view text) {
    for (size_t i = 0; i < text.size(); ++i) {
        const auto c = static_cast<unsigned char>(text[i]);
        if ((c < 0x20 && c != '\n') || c == 0x7f ||
            (c == 0xc2 && i + 1 < text.size() && static_cast<unsigned char>(text[i + 1]) >= 0x80 &&
             static_cast<unsigned char>(text[i + 1]) <= 0x9f)) {
            return false;
        }
    }
    return true;
}

void checkInfo(const probekit::PvolFile& file, size_t bytes) {
    const auto text = probekit::cli::formatInfo(file, "fuzz.pvol", bytes, false);
    if (text && !printable(text.value())) {
        fail("info's text output holds a terminal control byte");
    }
    const auto json = probekit::cli::formatInfo(file, "fuzz.pvol", bytes, true);
    if (json && !nlohmann::json::accept(json.value())) {
        fail("info --json printed something that is not JSON");
    }
}

void checkDecoded(std::span<const uint8_t> bytes) {
    const auto decoded = probekit::decodePvol(bytes, "fuzz.pvol");
    if (!decoded) {
        if (!printable(probekit::cli::terminalText(decoded.error().message))) {
            fail("an escaped error message holds a terminal control byte");
        }
        return;
    }
    checkInfo(decoded.value(), bytes.size());
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
