#!/usr/bin/env bash
# Adaptive against fixed sampling on the bundled scenes: seconds to the same worst-probe noise,
# measured from the spread of SEEDS bakes (`probekit bench-noise`, one JSON line per case,
# ratios from one run). Adaptive traces each probe to TARGET from 128 directions (cap 2^20, so
# that the unlit room reaches the target); fixed sampling gets the count whose worst probes
# match adaptive's. The cases: the three bundled scenes, and the thin-wall scene's unlit room
# alone (the room lit only through the doorway).
# Usage: tools/bench-noise.sh [PROBEKIT] [OUT.jsonl] [TARGET] [SEEDS]
set -euo pipefail
pk=${1:-build/tools/probekit}
out=${2:-out/bench-noise.jsonl}
target=${3:-0.05}
seeds=${4:-8}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$(dirname "$out")"
: >"$out"
bench() { # bench CASE SCENE CONFIG_JSON
    "$pk" scene "$2" -o "$work/$2.gltf" >/dev/null
    echo "$3" >"$work/$1.json"
    "$pk" bench-noise "$work/$2.gltf" --config "$work/$1.json" --target "$target" \
        --seeds "$seeds" --out "$work/$1.line"
    /usr/bin/python3 -c "import json, sys; j = json.load(open(sys.argv[1])); j['case'] = sys.argv[2]; \
print(json.dumps(j))" "$work/$1.line" "$1" >>"$out"
}
path='"path": {"samples": 128, "max_samples": 1048576}'
bench cornell cornell "{$path, \"volumes\": [{\"resolution\": [8, 8, 8]}]}"
bench thin-wall thin-wall "{$path, \"volumes\": [{\"resolution\": [16, 4, 8]}]}"
bench unlit-room thin-wall "{$path, \"volumes\": [{\"bounds\": {\"mode\": \"custom\",
  \"min\": [0.05, 0, -2], \"max\": [4, 2.5, 2]}, \"resolution\": [8, 4, 8]}]}"
bench courtyard courtyard "{$path, \"environment\": {\"type\": \"constant\",
  \"radiance\": [0.3, 0.4, 0.6]}, \"volumes\": [{\"name\": \"courtyard\", \"bounds\": {\"mode\":
  \"custom\", \"min\": [-8, 0, -8], \"max\": [8, 6, 8]}, \"resolution\": [16, 8, 16]}]}"
echo "bench-noise: wrote $out"
