#!/usr/bin/env bash
# Debug build with AddressSanitizer and UndefinedBehaviorSanitizer (every assert live, any
# undefined behaviour fatal) into ./build-asan, then the unit and bake suites under it. .ci/run
# runs this after the Quick start's test command
# (README.md#quick-start-fresh-debian-12-as-root-from-the-repository-root). Built at -O1, as
# AddressSanitizer's documentation advises for usable speed: on the project's 2-core machine
# the eight slowest tests took 377 s against 1,457 s at -O0, and in CI the whole suite 585 s
# against 1,809 s (compiling costs more: 36 CPU-minutes at -O1).
set -euo pipefail
cd "$(dirname "$0")/.."
flags="-O1 -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS="$flags" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
cmake --build build-asan --parallel "$(nproc)" \
    --target probekit_unit_tests probekit_bake_tests probekit probekit_test_pause_in_fsync
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1
ctest --test-dir build-asan -L 'unit|bake' --output-on-failure -j2 --timeout 1500
