#!/usr/bin/env bash
# The three.js export in a real browser (ctest label engines): bakes the bundled Cornell box
# small and fast, exports it with `probekit export --format three`, and has Chromium's WebGL
# (SwiftShader) draw it through integrations/three/probekit-three.js; tests/engines/
# three_chromium.mjs compares every lit pixel with `probekit sample`.
# Usage: three_chromium_test.sh PROBEKIT WORKDIR. Exit 77 (skipped) without chromium, node or
# integrations/node_modules (tools/install-deps.sh installs them). With PROBEKIT_THREE_PICTURE=1
# it also writes docs/images/three-cornell.png.
set -euo pipefail
pk=$1
work=$2
repo=$(cd "$(dirname "$0")/../.." && pwd)

skip() {
    echo "SKIP: $1 (tools/install-deps.sh installs it)"
    exit 77
}
command -v node > /dev/null || skip "no node"
command -v chromium > /dev/null || [ -x /usr/lib/chromium/chromium ] || skip "no chromium"
[ -d "$repo/integrations/node_modules/three" ] || skip "no integrations/node_modules"
[ -d "$repo/integrations/node_modules/puppeteer-core" ] || skip "no integrations/node_modules"

rm -rf "$work" && mkdir -p "$work" && cd "$work"
"$pk" scene cornell -o cornell.gltf > /dev/null
# The bundled example's settings (examples/cornell-bake.json) with few directions per probe:
# the comparison is against the same file, so noise does not matter.
# The picture uses the example's own 4,096 directions (about 20 s more on 2 cores).
if [ "${PROBEKIT_THREE_PICTURE:-0}" = 1 ]; then
    cp "$repo/examples/cornell-bake.json" bake.json
else
    sed 's/"samples": 4096/"samples": 256/' "$repo/examples/cornell-bake.json" > bake.json
fi
"$pk" bake cornell.gltf -o vis.pvol --config bake.json -q
"$pk" bake cornell.gltf -o plain.pvol --config bake.json -q --no-visibility
"$pk" export plain.pvol --format three -o plain.json -q
"$pk" export vis.pvol --format three -o vis.json -q

# Thin-wall leak (tests/bake/test_leak.cpp's figure through three.js): the bundled rooms split
# by a 5 cm wall at x = 0, a probe plane 6 mm from its lit face (x = -0.03125, spacing 0.5 m),
# and a path-traced reference: a corner-mode volume whose 64 probes are the dark-side points
# (0.25-0.4 m beyond the wall, 0.9 m or more from the doorway).
"$pk" scene thin-wall -o thin.gltf > /dev/null
cat > thin-reference.json << 'EOF'
{"method": "path", "seed": 7, "dering": false, "path": {"samples": 4096, "max_bounces": 64},
 "environment": {"type": "black"},
 "volumes": [{"name": "dark", "position": "corner", "resolution": [4, 4, 4],
              "bounds": {"mode": "custom", "min": [0.275, 0.6, -1.5], "max": [0.425, 1.8, 0.3]},
              "format": "float", "sh_order": 2}]}
EOF
cat > thin-bake.json << 'EOF'
{"method": "path", "seed": 1, "path": {"samples": 512, "max_bounces": 64},
 "environment": {"type": "black"},
 "volumes": [{"name": "rooms", "position": "center", "resolution": [16, 8, 8],
              "bounds": {"mode": "custom", "min": [-3.78125, 0, -2], "max": [4.21875, 4, 2]},
              "format": "half", "sh_order": 2}]}
EOF
"$pk" bake thin.gltf -o thin-reference.pvol --config thin-reference.json -q
"$pk" bake thin.gltf -o thin.pvol --config thin-bake.json -q
"$pk" export thin.pvol --format three -o thin.json -q

picture=""
if [ "${PROBEKIT_THREE_PICTURE:-0}" = 1 ]; then
    picture='"picture": "docs/images/three-cornell.png", "exposure": 1.6, "pictureSize": 320,'
fi
view='"gltf": "cornell.gltf", "eye": [0.278, 0.274, -0.75], "target": [0.278, 0.274, 0.28],
      "fov": 42, "size": 128'
# Tolerances. Both sides read the same binary16 texels, so half rounding cancels; what is left is
# float32 arithmetic (~1e-6 relative) and SwiftShader's filtering, which here interpolates in
# float: median ~6e-7, max ~2e-4 of the brightest channel (at dim pixels beside bright ones).
# A GPU that filters with 8-bit weights (1/256 of a texel) would be off by up to ~2e-3 where
# the field is steep; the maxima below leave room for that, and the median stays tight.
cases="[
  {\"name\": \"plain\", \"pvol\": \"plain.pvol\", \"grid\": \"plain.json\", \"visibility\": false,
   $view, \"median\": 1e-4, \"max\": 5e-3},
  {\"name\": \"visibility\", \"pvol\": \"vis.pvol\", \"grid\": \"vis.json\", \"visibility\": true,
   $picture $view, \"median\": 1e-4, \"max\": 5e-3},
  {\"name\": \"leak\", \"type\": \"leak\", \"grid\": \"thin.json\", \"pvol\": \"thin.pvol\",
   \"reference\": \"thin-reference.pvol\", \"xs\": [0.275, 0.325, 0.375, 0.425],
   \"ys\": [0.6, 1.0, 1.4, 1.8], \"zs\": [-1.5, -0.9, -0.3, 0.3], \"bound\": 1.5}
]"
node "$repo/tests/engines/three_chromium.mjs" "$repo" "$work" "$pk" "$cases"
