#!/usr/bin/env bash
# The main job on the bundled example: generate the Cornell box, bake it, describe the file,
# sample irradiance at a few points and render it with the Vulkan runtime (lavapipe without a
# GPU). Outputs go to ./out/.
set -euo pipefail
cd "$(dirname "$0")/.."
pk=./build/tools/probekit
mkdir -p out
"$pk" scene cornell -o out/cornell.gltf
"$pk" bake out/cornell.gltf -o out/cornell.pvol --config examples/cornell-bake.json \
    --report out/cornell-report.json
"$pk" info out/cornell.pvol
"$pk" sample out/cornell.pvol --points examples/cornell-points.csv
"$pk" render out/cornell.gltf out/cornell.pvol -o out/cornell.png --camera-from -z
