#!/usr/bin/env bash
# Installs everything probekit needs on Debian 12 (run as root). Idempotent: packages already
# present are left alone, and apt's lists are refreshed only when something is missing.
set -euo pipefail

# openimageio-tools: Debian's OpenImageIO CMake config declares its command-line tools
# (iconvert, oiiotool, ...) as imported targets and fails at configure when their binaries are
# absent, and libopenimageio-dev does not depend on that package.
# clang-14 and libclang-rt-14-dev: the libFuzzer targets (tools/fuzz.sh) need clang and its
# fuzzer and sanitizer runtimes; the build and the tests use g++.
# libopenmpi-dev and openmpi-bin: distributed bakes (mpirun -np N probekit bake,
# docs/baking.md#distributed-bakes) and their test; optional to the build, which leaves MPI out
# without them.
# chromium and nodejs: the engine tests (ctest -L engines, tests/engines) drive three.js in
# headless Chromium with the npm packages pinned in integrations/package-lock.json. npm only
# when no npm command exists: NodeSource's nodejs bundles npm and conflicts with Debian's.

packages=(
    build-essential cmake ninja-build pkg-config git clang-format
    libembree-dev libopenimageio-dev openimageio-tools libtinygltf-dev libglm-dev libcereal-dev libimath-dev
    nlohmann-json3-dev libcli11-dev
    libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers glslc
    libgtest-dev libgmock-dev googletest libbenchmark-dev
    clang-14 libclang-rt-14-dev
    libopenmpi-dev openmpi-bin
    python3 python3-matplotlib python3-numpy hyperfine
    chromium nodejs
)
command -v npm > /dev/null || packages+=(npm)

missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done

if ((${#missing[@]} == 0)); then
    echo "install-deps: all ${#packages[@]} packages present"
else
    echo "install-deps: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The integrations' npm packages, exactly as locked; again only when node_modules is missing or
# was installed from another lock.
integrations="$(cd "$(dirname "$0")/.." && pwd)/integrations"
stamp="$integrations/node_modules/.probekit-lock.sha256"
lock_sum=$(sha256sum "$integrations/package-lock.json" | cut -d' ' -f1)
# They come from registry.npmjs.org over HTTPS. Where that cannot be reached (offline, or a proxy
# whose certificate this machine does not trust), everything else still installs: the engine
# tests that need the packages (ctest -L engines) report themselves skipped, and this says why.
if [ "$(cat "$stamp" 2>/dev/null)" != "$lock_sum" ]; then
    echo "install-deps: npm ci in integrations/"
    if npm ci --prefix "$integrations" --no-audit --no-fund --loglevel=error; then
        echo "$lock_sum" > "$stamp"
    else
        rm -rf "$integrations/node_modules"
        echo "install-deps: warning: npm ci failed (registry.npmjs.org unreachable or untrusted?);" \
            "the engine tests (ctest -L engines) will be skipped until it succeeds"
    fi
else
    echo "install-deps: integrations/node_modules matches package-lock.json"
fi
