#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang++-14, AddressSanitizer and
# UndefinedBehaviorSanitizer into ./build-fuzz, then runs each for SECONDS (default 30) from its
# committed seed corpus (fuzz/corpus/<target>). Any crash, sanitizer report, leak, timeout (10 s
# per input) or out-of-memory (2 GiB) fails the script and leaves the input under
# build-fuzz/artifacts/. .ci/run runs it with the default; run it longer by hand:
#   bash tools/fuzz.sh 3600              # an hour per target
#   bash tools/fuzz.sh 600 fuzz_gltf     # one target
# New inputs that reach new code go to build-fuzz/corpus/<target> (kept between runs, never into
# the checkout); copy the interesting ones into fuzz/corpus/<target> to commit them.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-30}"
shift || true
all_targets=(fuzz_pvol fuzz_gltf fuzz_config fuzz_points fuzz_c_reader)
targets=("${@:-${all_targets[@]}}")

flags="-fsanitize=address,undefined,fuzzer-no-link -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_C_FLAGS="$flags" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
    -DPROBEKIT_BUILD_TESTS=OFF -DPROBEKIT_FUZZ=ON >/dev/null
cmake --build build-fuzz --parallel "$(nproc)" --target "${targets[@]}" fuzz_config_dict
# The config fuzzer's dictionary is written from the settings table, never kept by hand.
build-fuzz/fuzz/fuzz_config_dict >build-fuzz/fuzz_config.dict

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:symbolize=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
mkdir -p build-fuzz/artifacts
status=0
for target in "${targets[@]}"; do
    work="build-fuzz/corpus/$target"
    mkdir -p "$work"
    log="build-fuzz/$target.log"
    echo "fuzz: $target for ${seconds} s (log: $log)"
    # -dict: JSON tokens help the text formats past their first syntax errors.
    dict=()
    [[ -f "fuzz/$target.dict" ]] && dict=(-dict="fuzz/$target.dict")
    [[ -f "build-fuzz/$target.dict" ]] && dict=(-dict="build-fuzz/$target.dict")
    if ! "build-fuzz/fuzz/$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="build-fuzz/artifacts/$target-" "${dict[@]}" \
        "$work" "fuzz/corpus/$target" >"$log" 2>&1; then
        echo "fuzz: $target FAILED; the end of its log:"
        tail -n 60 "$log"
        status=1
        continue
    fi
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
    echo "fuzz: $target passed: ${runs:-?} executions, $(find "$work" -type f | wc -l) corpus inputs"
done
exit "$status"
