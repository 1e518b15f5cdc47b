#!/usr/bin/env bash
# Adaptive against fixed sampling on the bundled scenes: seconds to the same worst-probe noise,
# measured between two seeds (`probekit bench-noise`, one JSON line per scene, ratios from one
# run). Adaptive traces each probe to TARGET from 256 directions (cap 65536); fixed sampling
# gets the count whose worst probe (99th percentile) matches adaptive's.
# Usage: tools/bench-noise.sh [PROBEKIT] [OUT.jsonl] [TARGET]
set -euo pipefail
pk=${1:-build/tools/probekit}
out=${2:-out/bench-noise.jsonl}
target=${3:-0.05}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$(dirname "$out")"
: >"$out"
bench() { # bench SCENE CONFIG_JSON
    "$pk" scene "$1" -o "$work/$1.gltf" >/dev/null
    echo "$2" >"$work/$1.json"
    "$pk" bench-noise "$work/$1.gltf" --config "$work/$1.json" --target "$target" \
        --out "$work/$1.line"
    cat "$work/$1.line" >>"$out"
}
bench cornell '{"path": {"samples": 256}, "volumes": [{"resolution": [8, 8, 8]}]}'
bench thin-wall '{"path": {"samples": 256}, "volumes": [{"resolution": [16, 4, 8]}]}'
bench courtyard '{"path": {"samples": 256}, "environment": {"type": "constant",
  "radiance": [0.3, 0.4, 0.6]}, "volumes": [{"name": "courtyard", "bounds": {"mode": "custom",
  "min": [-8, 0, -8], "max": [8, 6, 8]}, "resolution": [8, 4, 8]}]}'
echo "bench-noise: wrote $out"
