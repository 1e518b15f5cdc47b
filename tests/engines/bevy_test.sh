#!/usr/bin/env bash
# The Bevy export read by an independent KTX 2.0 reader (ktx-parse, under node): container
# fields, the Data Format Descriptor, and every texel against probekit's CPU sampler
# (tests/engines/bevy_ktx_parse.mjs), for a centre-mode and a corner-mode analytic volume.
# Usage: bevy_test.sh PROBEKIT_BINARY WORKDIR. Exit 77 (skipped) without node or ktx-parse.
set -euo pipefail
probekit=$1
work=$2
here=$(cd "$(dirname "$0")" && pwd)
integrations=$here/../../integrations

if ! command -v node >/dev/null 2>&1; then
    echo "SKIPPED: node is not installed"
    exit 77
fi
if [ ! -f "$integrations/node_modules/ktx-parse/package.json" ]; then
    echo "SKIPPED: ktx-parse is not installed (npm ci --prefix integrations)"
    exit 77
fi

# Exports NAME.pvol and checks every texel against the sampler at the voxel centres.
export_and_check() {
    local name=$1
    "$probekit" export "$work/$name.pvol" --format bevy -o "$work/$name.ktx2"
    node "$here/bevy_ktx_parse.mjs" points "$work/$name.ktx2" >"$work/$name-points.csv"
    "$probekit" sample "$work/$name.pvol" --points "$work/$name-points.csv" -o "$work/$name-E.csv"
    node "$here/bevy_ktx_parse.mjs" check "$work/$name.ktx2" "$work/$name-E.csv"
}

rm -rf "$work"
mkdir -p "$work"
for position in center corner; do
    "$probekit" synth -o "$work/$position.pvol" --resolution 4,2,8 --position "$position" \
        --light 0.7,1.6,0.4 --intensity 2 >/dev/null
    export_and_check "$position"
done
# A real bake (half storage, visibility, dilated and relocated probes) when the shared scenes are
# beside the checkout, as in CI: the Cornell box, 8^3 probes, a second or two.
cornell=$here/../../../shared/scenes/cornell-box/cornell_from_obj.gltf
if [ -f "$cornell" ]; then
    "$probekit" bake "$cornell" --config "$here/../../examples/cornell-bake.json" \
        --resolution 8,8,8 --samples 128 -q -o "$work/cornell.pvol"
    export_and_check cornell
else
    echo "bevy_test: no $cornell; the Cornell case is left out"
fi
echo "bevy_test: passed"
