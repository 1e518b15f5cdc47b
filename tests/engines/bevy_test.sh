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

rm -rf "$work"
mkdir -p "$work"
for position in center corner; do
    pvol=$work/$position.pvol
    ktx=$work/$position.ktx2
    "$probekit" synth -o "$pvol" --resolution 4,2,8 --position "$position" --light 0.7,1.6,0.4 \
        --intensity 2 >/dev/null
    "$probekit" export "$pvol" --format bevy -o "$ktx"
    node "$here/bevy_ktx_parse.mjs" points "$ktx" >"$work/$position-points.csv"
    "$probekit" sample "$pvol" --points "$work/$position-points.csv" -o "$work/$position-E.csv"
    node "$here/bevy_ktx_parse.mjs" check "$ktx" "$work/$position-E.csv"
done
echo "bevy_test: passed"
