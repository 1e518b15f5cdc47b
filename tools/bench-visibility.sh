#!/usr/bin/env bash
# What leak-proof interpolation (per-probe visibility) costs, each figure a ratio measured in one
# run: bytes per probe (file and GPU bytes from `probekit info --json`), bake seconds with and
# without visibility (hyperfine, same command but --no-visibility, same probes), and the
# renderer's shading time with and without on the same volume (`probekit render --bench`,
# --no-visibility drops the data before upload; on lavapipe without a GPU).
# Usage: tools/bench-visibility.sh [PROBEKIT] [OUT.csv]
set -euo pipefail
pk=${1:-build/tools/probekit}
out=${2:-out/bench-visibility.csv}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$(dirname "$out")"
"$pk" scene cornell -o "$work/cornell.gltf" >/dev/null
"$pk" scene thin-wall -o "$work/thin-wall.gltf" >/dev/null
cat >"$work/bricked.json" <<'JSON'
{"path": {"samples": 256}, "volumes": [{"name": "box", "layout": "bricked", "levels": 2,
  "refine_error": 0.05, "resolution": [2, 2, 2], "format": "half"}]}
JSON
echo "case,figure,with,without,ratio" >"$out"
row() { # row CASE FIGURE WITH WITHOUT
    /usr/bin/python3 -c "import sys; a, b = float(sys.argv[3]), float(sys.argv[4]); \
print(f'{sys.argv[1]},{sys.argv[2]},{a:.6g},{b:.6g},{a / b:.4f}')" "$@" | tee -a "$out"
}
json_field() { # json_field FILE EXPRESSION (Python over the parsed JSON `j`)
    /usr/bin/python3 -c "import json, sys; j = json.load(open(sys.argv[1])); print($2)" "$1"
}
bake_case() { # bake_case NAME SCENE ARGS...
    local name=$1 scene=$2
    shift 2
    hyperfine -N --warmup 1 --runs 5 --export-json "$work/$name.json" \
        "$pk bake $work/$scene.gltf -o $work/$name-vis.pvol -q $*" \
        "$pk bake $work/$scene.gltf -o $work/$name-plain.pvol -q --no-visibility $*" >/dev/null
    row "$name" bake_seconds_median \
        "$(json_field "$work/$name.json" "j['results'][0]['median']")" \
        "$(json_field "$work/$name.json" "j['results'][1]['median']")"
    row "$name" file_bytes "$(stat -c %s "$work/$name-vis.pvol")" \
        "$(stat -c %s "$work/$name-plain.pvol")"
    "$pk" info "$work/$name-vis.pvol" --json >"$work/$name-vis.info"
    "$pk" info "$work/$name-plain.pvol" --json >"$work/$name-plain.info"
    local gpu="sum(v['texel_bytes'] + v.get('visibility_gpu_bytes', 0) for v in j['volumes'])"
    local probes="sum(v['probes'] for v in j['volumes'])"
    row "$name" gpu_bytes_per_probe \
        "$(json_field "$work/$name-vis.info" "($gpu) / ($probes)")" \
        "$(json_field "$work/$name-plain.info" "($gpu) / ($probes)")"
}
bake_case cornell-32-l2-half cornell --resolution 32,32,32 --samples 256 --format half
bake_case thin-wall-16x8x8 thin-wall --resolution 16,8,8 --samples 1024
bake_case cornell-bricked cornell --config "$work/bricked.json"
# Shading: render --bench alternates frames of the volumes with their visibility and of the same
# volumes without it (one run, same device), and prints both medians.
render_case() { # render_case NAME SCENE PVOL
    "$pk" render "$work/$2.gltf" "$work/$3" -o "$work/$1.png" --bench 5 >"$work/$1.render"
    row "$1" shade_ms_median \
        "$(json_field "$work/$1.render" "j['shade_ms']")" \
        "$(json_field "$work/$1.render" "j['shade_no_visibility_ms']")"
}
render_case render-thin-wall-16x8x8 thin-wall thin-wall-16x8x8-vis.pvol
render_case render-cornell-32-l2-half cornell cornell-32-l2-half-vis.pvol
render_case render-cornell-bricked cornell cornell-bricked-vis.pvol
