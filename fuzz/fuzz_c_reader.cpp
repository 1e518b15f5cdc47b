// libFuzzer target: the C reader (integrations/c/probekit_pvol.h, compiled as C) against
// formats' decodePvol on the same untrusted bytes.
//
// Each input is read twice, as it is and with the header's payload length and checksum
// rewritten to match the bytes that follow (as fuzz_pvol does), so that mutations reach the
// payload parsers. The two readers must accept and reject the same inputs, with the same error
// kind, and on an accepted input agree on every field and every texel bit for bit
// (tests/unit/c_reader_agreement.hpp); anything else aborts, so libFuzzer keeps the input.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include "c_reader_agreement.hpp"

namespace {

void checkAgreement(std::span<const uint8_t> bytes) {
    const probekit::c_reader::Outcome outcome = probekit::c_reader::compareReaders(bytes);
    if (!outcome.disagreement.empty()) {
        std::fprintf(stderr, "fuzz_c_reader: %s\n", outcome.disagreement.c_str());
        std::abort();
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::span<const uint8_t> bytes(data, size);
    checkAgreement(bytes);
    if (size >= probekit::kPvolHeaderBytes) {
        checkAgreement(probekit::c_reader::withMatchingHeader(bytes));
    }
    return 0;
}
