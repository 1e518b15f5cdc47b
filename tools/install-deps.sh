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

packages=(
    build-essential cmake ninja-build pkg-config git clang-format
    libembree-dev libopenimageio-dev openimageio-tools libtinygltf-dev libglm-dev libcereal-dev libimath-dev
    nlohmann-json3-dev libcli11-dev
    libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers glslc
    libgtest-dev libgmock-dev googletest libbenchmark-dev
    clang-14 libclang-rt-14-dev
    libopenmpi-dev openmpi-bin
    python3 python3-matplotlib python3-numpy hyperfine
)

missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done

if ((${#missing[@]} == 0)); then
    echo "install-deps: all ${#packages[@]} packages present"
    exit 0
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
