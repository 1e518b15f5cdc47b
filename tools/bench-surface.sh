#!/usr/bin/env bash
# Per-pixel surface accuracy of the bundled scenes (docs/accuracy.md#surface-accuracy): for each
# view, a path-traced surface reference (probekit surface-reference), then the volume of each bake
# sampled at its pixels by the CPU sampler (probekit surface-error --volume), as a markdown
# table. "before" bakes with relocation and deringing off (validity.relocate, dering) and, on
# the Cornell box, the bundled example's former config; "after" with the defaults and today's
# example; "seed 2" repeats "after" with another seed, so bake noise shows beside the error.
# References are kept in the output folder and reused.
# Usage: tools/bench-surface.sh [PROBEKIT] [OUT_DIR] [REFERENCE_SAMPLES]
set -euo pipefail
pk=${1:-build/tools/probekit}
out=${2:-out/surface}
samples=${3:-1024}
mkdir -p "$out"
"$pk" scene cornell -o "$out/cornell.gltf" >/dev/null
"$pk" scene thin-wall -o "$out/thin-wall.gltf" >/dev/null
here=$(cd "$(dirname "$0")/.." && pwd)

config() { # config NAME BASE.json RELOCATE DERING SEED
    /usr/bin/python3 - "$2" "$3" "$4" "$5" >"$out/$1.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
c.setdefault("validity", {})
c["validity"]["relocate"] = sys.argv[2] == "true"
c["dering"] = sys.argv[3] == "true"
c["seed"] = int(sys.argv[4])
print(json.dumps(c))
PY
}
cat >"$out/thin-wall-base.json" <<'JSON'
{"volumes": [{"name": "rooms", "resolution": [16, 8, 8]}]}
JSON
# The bundled example before issue 26: 8^3 over the box and a 4^3 corner volume by the light,
# 8,192 samples per probe.
cat >"$out/previous-example.json" <<'JSON'
{"method": "path", "seed": 1, "path": {"samples": 8192, "max_bounces": 64},
 "environment": {"type": "black"},
 "volumes": [
  {"name": "box", "bounds": {"mode": "auto-world", "padding": 0.0}, "resolution": [8, 8, 8],
   "position": "center", "format": "half", "sh_order": 2},
  {"name": "light-corner",
   "bounds": {"mode": "custom", "min": [0.2, 0.34, 0.15], "max": [0.4, 0.54, 0.35]},
   "resolution": "auto", "density": 20, "max_resolution": 8, "position": "corner",
   "format": "float", "sh_order": 2, "blend_priority": 1, "fade_distance": 0.05}]}
JSON

row() { # row LABEL SCENE BEFORE.json AFTER.json REFERENCE.exr
    local label=$1 scene=$2 before=$3 after=$4 ref=$5
    for variant in "before false false 1 $before" "after true true 1 $after" \
        "seed2 true true 2 $after"; do
        set -- $variant
        config "$label-$1" "$5" "$2" "$3" "$4"
        "$pk" bake "$out/$scene.gltf" -o "$out/$label-$1.pvol" --config "$out/$label-$1.json" \
            >/dev/null 2>"$out/$label-$1.log"
        "$pk" surface-error "$ref" --volume "$out/$label-$1.pvol" --json \
            --heatmap "$out/$label-$1-heat.png" >"$out/$label-$1-error.json"
    done
    /usr/bin/python3 - "$label" "$out/$label-before-error.json" "$out/$label-after-error.json" \
        "$out/$label-seed2-error.json" <<'PY'
import json, sys
b, a, s = (json.load(open(p)) for p in sys.argv[2:5])
f = lambda j: (f"{100 * j['median_abs_error']:.1f}% | {j['mean_ratio']:.3f} | "
               f"{100 * j['share_under_half']:.2f}% | {100 * j['share_over_two']:.2f}% | "
               f"{100 * j['share_negative']:.2f}%")
print(f"| {sys.argv[1]} | before | {f(b)} | {100 * b['noise_floor']:.1f}% |")
print(f"| {sys.argv[1]} | after | {f(a)} | {100 * a['noise_floor']:.1f}% |")
print(f"| {sys.argv[1]} | after, seed 2 | {f(s)} | {100 * s['noise_floor']:.1f}% |")
PY
}

reference() { # reference NAME SCENE SAMPLES CAMERA-ARGS...
    local name=$1 scene=$2 n=$3
    shift 3
    if [ ! -f "$out/$name-reference.exr" ]; then
        "$pk" surface-reference "$out/$scene.gltf" -o "$out/$name-reference.exr" \
            --samples "$n" "$@" >&2
    fi
}

reference cornell-front cornell "$samples" --camera-from -z --size 320,240
# The face is lit mostly from the side and the opening: 8x the samples for the same noise.
reference cornell-face cornell $((8 * samples)) --camera 0.26,0.09,-0.08,0.20,0.09,0.09 --fov 30 \
    --size 64,48
reference thin-wall-lit thin-wall "$samples" --camera -2.5,1.8,-1.9,0.5,0.8,1.0 --size 240,160
# The unlit room sees its light through the doorway only: 16x the samples at a quarter of the
# pixels.
reference thin-wall-dark thin-wall $((16 * samples)) --camera 2.5,1.8,-1.9,-0.5,0.8,1.0 \
    --size 120,80

echo "| view | bake | median abs error | mean E/E_ref | under 0.5x | over 2x | E < 0 | reference noise floor |"
echo "|---|---|---|---|---|---|---|---|"
example="$here/examples/cornell-bake.json"
row cornell-front cornell "$out/previous-example.json" "$example" "$out/cornell-front-reference.exr"
row cornell-face cornell "$out/previous-example.json" "$example" "$out/cornell-face-reference.exr"
base="$out/thin-wall-base.json"
row thin-wall-lit thin-wall "$base" "$base" "$out/thin-wall-lit-reference.exr"
row thin-wall-dark thin-wall "$base" "$base" "$out/thin-wall-dark-reference.exr"
