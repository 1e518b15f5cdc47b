#!/usr/bin/env bash
# Dense against bricked volumes on the bundled courtyard at equal error. Three cases: "sunny"
# (scene courtyard, the interior 16 x 6 x 16 m), "overcast" (scene courtyard-overcast, the
# interior and the open air above it, 16 x 16 x 16 m) and "overcast-tall" (16 x 32 x 16 m).
# Each is baked densely at several resolutions and bricked at several refinement settings, all
# with the same samples per probe, and every file is measured against the same path reference
# (probekit bake --verify, 1024 points). Writes CSV rows: case, layout, setting, seconds,
# gpu_bytes, rel_rmse.
# Usage: tools/bench-bricked.sh [PROBEKIT] [OUT.csv] [SAMPLES]
set -euo pipefail
pk=${1:-build/tools/probekit}
out=${2:-out/bench-bricked.csv}
samples=${3:-512}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$(dirname "$out")"
"$pk" scene courtyard -o "$work/sunny.gltf" >/dev/null
"$pk" scene courtyard-overcast -o "$work/overcast.gltf" >/dev/null
config() { # $1 = top of the box (m), $2 = extra volume fields
    cat > "$work/c.json" <<JSON
{ "method": "path", "path": {"samples": $samples, "max_bounces": 8},
  "environment": {"type": "constant", "radiance": [0.3, 0.4, 0.6]},
  "volumes": [ {"name": "courtyard", "format": "half",
                "bounds": {"mode": "custom", "min": [-8, 0, -8], "max": [8, $1, 8]}, $2} ] }
JSON
}
run() { # $1 case (its scene: the case without "-tall"), $2 layout, $3 setting label
    "$pk" bake "$work/${1%-tall}.gltf" --config "$work/c.json" -o "$work/v.pvol" --verify \
        --verify-points 1024 --report "$work/r.json" -q
    /usr/bin/python3 - "$work/r.json" "$1" "$2" "$3" >> "$out" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"{sys.argv[2]},{sys.argv[3]},{sys.argv[4]},{r['bake_seconds']:.3f},{r['gpu_bytes']},"
      f"{r['verify']['rel_rmse']:.4f}")
PY
    tail -1 "$out"
}
echo "case,layout,setting,seconds,gpu_bytes,rel_rmse" > "$out"
for res in "16 8 16" "32 16 32" "64 32 64" "128 64 128"; do
    config 6 "\"resolution\": [${res// /, }]"
    run sunny dense "${res// /x}"
done
for refine in 0.1 0.05 0.03; do
    config 6 "\"layout\": \"bricked\", \"resolution\": [8, 4, 8], \"levels\": 3, \"refine_error\": $refine"
    run sunny bricked "8x4x8 levels 3 refine $refine"
done
for res in 16 32 64; do
    config 16 "\"resolution\": [$res, $res, $res]"
    run overcast dense "${res}x${res}x${res}"
done
for top in 2 4; do
    for refine in 0.01 0.005 0.0025; do
        config 16 "\"layout\": \"bricked\", \"resolution\": [$top, $top, $top], \"levels\": 3, \"refine_error\": $refine"
        run overcast bricked "${top}x${top}x${top} levels 3 refine $refine"
    done
done
# The same overcast courtyard inside a 32 m tall volume: open air is ~80% of it.
for res in "16 32 16" "32 64 32" "64 128 64"; do
    config 32 "\"resolution\": [${res// /, }]"
    run overcast-tall dense "${res// /x}"
done
for refine in 0.01 0.005 0.0025; do
    config 32 "\"layout\": \"bricked\", \"resolution\": [2, 4, 2], \"levels\": 3, \"refine_error\": $refine"
    run overcast-tall bricked "2x4x2 levels 3 refine $refine"
done
# Equal error: each bricked row against the dense rows of its case, bytes and seconds
# interpolated log-log between the two dense rows whose errors bracket the bricked one.
/usr/bin/python3 - "$out" <<'PY'
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("case,bricked setting,error,bytes / dense at equal error,seconds / dense at equal error")
for b in (r for r in rows if r["layout"] == "bricked"):
    dense = sorted((r for r in rows if r["case"] == b["case"] and r["layout"] == "dense"),
                   key=lambda r: -float(r["rel_rmse"]))
    e = float(b["rel_rmse"])
    for hi, lo in zip(dense, dense[1:]):
        e_hi, e_lo = float(hi["rel_rmse"]), float(lo["rel_rmse"])
        if e_lo <= e <= e_hi:
            t = math.log(e / e_hi) / math.log(e_lo / e_hi)
            at = lambda k: math.exp((1 - t) * math.log(float(hi[k])) + t * math.log(float(lo[k])))
            print(f"{b['case']},{b['setting']},{e:.4f},{float(b['gpu_bytes']) / at('gpu_bytes'):.3f},"
                  f"{float(b['seconds']) / at('seconds'):.3f}")
            break
    else:
        print(f"{b['case']},{b['setting']},{e:.4f},outside the dense rows' errors,")
PY
