#!/usr/bin/env bash
# `probekit render` end to end: every view and both formats, --bench's JSON line, exit codes,
# messages naming the file, and no output left behind by a failed render.
# Usage: render_cli_test.sh PROBEKIT WORKDIR. Prints "SKIPPED: no Vulkan device" (a ctest skip)
# when the machine has no Vulkan device.
set -u
pk=$1
work=$2
# shellcheck source=../cli/expect.sh
source "$(cd "$(dirname "$0")/../cli" && pwd)/expect.sh" || exit 1
hostile="$(cd "$(dirname "$0")/../data/hostile" && pwd)" || exit 1
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1

"$pk" scene cornell -o cornell.gltf >/dev/null || exit 1
"$pk" synth -o volume.pvol --resolution 4,4,4 --format half >/dev/null || exit 1
out=$("$pk" render cornell.gltf volume.pvol -o first.png --size 32,24 2>&1)
if [[ $? -ne 0 ]] && grep -qE "no usable device \(none found\)|vkCreateInstance failed" <<<"$out"; then
    echo "SKIPPED: no Vulkan device ($out)"
    exit 0
fi

expect 0 "wrote shaded.png: 64x48, shaded view" -- \
    "$pk" render cornell.gltf volume.pvol -o shaded.png --size 64,48
check "a PNG" test -s shaded.png
expect 0 "irradiance view" -- "$pk" render cornell.gltf volume.pvol -o e.exr --size 64,48 \
    --view irradiance
check "an EXR" test -s e.exr
expect 0 "probes view" -- "$pk" render cornell.gltf volume.pvol -o p.png --size 64,48 \
    --view probes --camera 0.3,0.3,-1,0.3,0.3,0.3 --fov 50
expect 0 "validity view" -- "$pk" render cornell.gltf volume.pvol -o v.png --size 64,48 \
    --view validity --exposure 1 --normal-offset 0.01 --direct-light
expect 0 '"shade_ms":.*"fetch_only_ms":|"fetch_only_ms":.*"shade_ms":' -- \
    "$pk" render cornell.gltf volume.pvol -o b.png --size 32,24 --bench 2
# The preview's options: background, camera side, exposure; the probes view reports its budget.
expect 0 "display: ACES filmic, exposure .*auto" -- "$pk" render cornell.gltf volume.pvol \
    -o env.png --size 32,24 --env 0.3,0.4,0.6 --camera-from -z
expect 0 "exposure \+1.00 EV \(fixed\)" -- "$pk" render cornell.gltf volume.pvol -o fx.png \
    --size 32,24 --env none --fixed-exposure --exposure 1
expect 0 "probes: drew [0-9]+ of 64 .*budget 12," -- "$pk" render cornell.gltf volume.pvol -o pb.png \
    --size 32,24 --view probes --camera-from +x
expect 1 "--env.*radiance" -- "$pk" render cornell.gltf volume.pvol -o bad.png --env -1,0,0
check "no output from a bad --env" test ! -e bad.png
expect 1 "--env: missing.hdr" -- "$pk" render cornell.gltf volume.pvol -o bad.png --env missing.hdr
# Issue 31: a .pvol is untrusted. Nested past the JSON depth limit it is refused naming the file
# and the field; the environment file it records is opened only under the scene's folder or
# the .pvol's: outside, the render warns, opens nothing and draws the black background.
expect 1 "deep-parameters.pvol: metadata.parameters_json: JSON arrays and objects nest 100000" -- \
    "$pk" render cornell.gltf "$hostile/deep-parameters.pvol" -o deep.png
check "no output from a refused volume" test ! -e deep.png
mkdir -p scene outside
printf 'Pf\n2 1\n-1.0\n' >grey.header
for d in scene outside; do
    { cat grey.header; printf '\000\000\100\100\000\000\100\100'; } >"$d/sky.pfm" # 3.0f twice
done
"$pk" scene cornell -o scene/cornell.gltf >/dev/null || exit 1
"$pk" bake scene/cornell.gltf -o scene/inside.pvol --resolution 2,2,2 --samples 16 \
    --env "$PWD/scene/sky.pfm" >/dev/null || exit 1
"$pk" bake scene/cornell.gltf -o scene/outside.pvol --resolution 2,2,2 --samples 16 \
    --env "$PWD/outside/sky.pfm" >/dev/null || exit 1
expect 0 "outside.pvol \(its recorded bake settings\): environment file $PWD/outside/sky.pfm recorded in the volume is outside the scene folder; not opened \(pass --env to use it\)" -- \
    "$pk" render scene/cornell.gltf scene/outside.pvol -o refused.png --size 32,24 --fixed-exposure
"$pk" render scene/cornell.gltf scene/outside.pvol -o black.png --size 32,24 --fixed-exposure \
    --env none >/dev/null 2>&1
check "the refused environment renders as the black background" cmp refused.png black.png
check "an environment inside the scene folder loads, without a warning" bash -c \
    '! "$1" render scene/cornell.gltf scene/inside.pvol -o inside.png --size 32,24 \
    --fixed-exposure 2>&1 | grep -q "outside the scene folder"' _ "$pk"
"$pk" render scene/cornell.gltf scene/inside.pvol -o inside-black.png --size 32,24 \
    --fixed-exposure --env none >/dev/null 2>&1
check "the environment inside the scene folder is drawn" bash -c '! cmp -s inside.png inside-black.png'
expect 2 "" -- "$pk" render cornell.gltf volume.pvol -o x.png --camera-from z

# A bricked bake renders in every view; the probes view colours probes by brick level.
cat >bricked.json <<'JSON'
{"path": {"samples": 16}, "volumes": [{"name": "box", "layout": "bricked", "levels": 2,
  "refine_error": 0.05, "resolution": [2, 2, 2]}]}
JSON
"$pk" bake cornell.gltf -o bricked.pvol --config bricked.json -q || exit 1
expect 0 "wrote bp.png: 64x48, probes view" -- "$pk" render cornell.gltf bricked.pvol -o bp.png \
    --size 64,48 --view probes --camera 0.3,0.3,-1,0.3,0.3,0.3 --fov 50
expect 0 "wrote bs.png: 64x48, shaded view" -- "$pk" render cornell.gltf bricked.pvol -o bs.png \
    --size 64,48

# Visibility (baked by default): the leak view, and --bench times the same volume with and
# without it; --no-visibility drops it (plain trilinear interpolation).
"$pk" bake cornell.gltf -o dense.pvol --samples 16 -q || exit 1
expect 0 "wrote leak.png: 64x48, leak view" -- "$pk" render cornell.gltf dense.pvol -o leak.png \
    --size 64,48 --view leak
expect 0 "wrote bleak.png: 64x48, leak view" -- "$pk" render cornell.gltf bricked.pvol \
    -o bleak.png --size 64,48 --view leak
expect 0 '"shade_no_visibility_ms":.*"shade_visibility_over_none":.*"visibility":true' -- \
    "$pk" render cornell.gltf dense.pvol -o bv.png --size 32,24 --bench 2
expect 0 '"visibility":false' -- "$pk" render cornell.gltf dense.pvol -o bn.png --size 32,24 \
    --bench 2 --no-visibility
expect 0 "no-visibility" -- "$pk" render --help

# Dynamic GI: without a volume (the GI alone) along a sun path, one image per frame; on top of
# a volume; its debug views; --bench's gi_ keys; the errors.
"$pk" scene courtyard -o courtyard.gltf >/dev/null || exit 1
expect 0 "wrote gi01.png: frame 1, shaded view; GI [1-9][0-9]* dispatches \(1 cascades\)" -- \
    "$pk" render courtyard.gltf --dynamic-gi --env 0.3,0.4,0.6 --sun-path 30,50,-60,35 \
    --frames 3 -o gi%02d.png --size 32,24 --gi-iterations 4
check "one image per frame" test -s gi00.png -a -s gi01.png -a -s gi02.png
check "no fourth frame" test ! -e gi03.png
expect 0 "wrote gib.png: frame 0, irradiance view" -- "$pk" render cornell.gltf volume.pvol \
    --dynamic-gi -o gib.png --size 32,24 --view irradiance --sun-path 0,60,0,60 \
    --gi-iterations 4 --gi-quality zonal --gi-cascades 2
for view in gi-lpv gi-geometry gi-ao; do
    expect 0 "wrote $view.png: frame 0, $view view" -- "$pk" render courtyard.gltf --dynamic-gi \
        -o $view.png --size 32,24 --view $view --gi-iterations 4
done
expect 0 '"gi_occupancy_ms":.*"gi_inject_ms":.*"gi_propagate_ms":.*"shade_baked_only_ms":.*"shade_ms"|"gi_inject_ms":.*"shade_ms":' -- \
    "$pk" render cornell.gltf volume.pvol --dynamic-gi -o gb.png --size 32,24 --bench 2 \
    --sun-path 0,60,0,60 --gi-iterations 4
expect 1 "dynamicGi|need --dynamic-gi|needs --dynamic-gi|dynamic GI views" -- \
    "$pk" render cornell.gltf volume.pvol -o x.png --size 8,8 --view gi-ao
expect 1 "need --dynamic-gi" -- "$pk" render cornell.gltf volume.pvol -o x.png --sun-path 0,1,2,3
expect 1 "VOLUME is required" -- "$pk" render cornell.gltf -o x.png
expect 1 "%d or %0Nd" -- "$pk" render courtyard.gltf --dynamic-gi -o "x%s.png" --size 8,8
check "no output after the GI errors" bash -c '! ls x*.png 2>/dev/null | grep -q .'
expect 2 "" -- "$pk" render courtyard.gltf --dynamic-gi -o x.png --gi-resolution 48

# Light modes (docs/baking.md#light-modes) with --direct-light: the text-floor scene's two lights
# baked indirect, their direct light shaded by the renderer with traced shadows, against the path
# tracer's irradiance at the same pixels. Measured at these settings: median 0.5% (the same volume
# with both lights baked: 5.5%; without --direct-light the image holds only the bounce, 0.016x).
"$pk" scene text-floor -o tf.gltf >/dev/null
tf_view=(--camera 0,2.5,-3.5,0,0,0 --size 80,60)
"$pk" bake tf.gltf -o tf.pvol --resolution 16,8,16 --samples 256 --light-mode indirect -q
"$pk" surface-reference tf.gltf -o tf-ref.exr "${tf_view[@]}" --samples 128 >/dev/null
expect 0 "wrote tf.exr" -- "$pk" render tf.gltf tf.pvol --view irradiance --direct-light \
    -o tf.exr "${tf_view[@]}"
median=$("$pk" surface-error tf-ref.exr tf.exr | awk '/median abs error/ {print $4}')
check "indirect lights + shadowed direct light: median error $median under 0.02" \
    awk -v m="$median" 'BEGIN { exit !(m > 0 && m < 0.02) }'
"$pk" bake tf.gltf -o tf-baked.pvol --resolution 16,8,16 --samples 256 -q
expect 0 "nothing is added" -- "$pk" render tf.gltf tf-baked.pvol --direct-light -o tf2.exr \
    "${tf_view[@]}"

expect 2 "png or .exr" -- "$pk" render cornell.gltf volume.pvol -o out.jpg
check "no output for a bad extension" test ! -e out.jpg
expect 2 "" -- "$pk" render cornell.gltf volume.pvol -o x.png --view nope
expect 1 "missing.gltf" -- "$pk" render missing.gltf volume.pvol -o m.png
check "no output after a missing scene" test ! -e m.png
expect 1 "missing.pvol" -- "$pk" render cornell.gltf missing.pvol -o m.png
expect 1 "eye and the target coincide" -- "$pk" render cornell.gltf volume.pvol -o m.png \
    --camera 1,1,1,1,1,1
check "no output after a bad camera" test ! -e m.png
mkdir locked && chmod 500 locked
if [[ ! -w locked ]]; then # root can write anyway; the check only means something otherwise
    expect 1 "locked/x.png" -- "$pk" render cornell.gltf volume.pvol -o locked/x.png --size 8,8
fi
# The output rule of every command (docs/commands.md#files-probekit-reads-and-writes): a FIFO is
# refused before any rendering, a link is followed and stays a link, and both formats are
# written through the same atomic writer.
mkfifo fifo.png
expect 1 "fifo.png: not a regular file \(it is a FIFO\); only a regular file is replaced" -- \
    timeout 60 "$pk" render cornell.gltf volume.pvol -o fifo.png --size 8,8
check "the FIFO is still a FIFO" test -p fifo.png
mkdir store && cp e.exr store/v1.exr && ln -s store/v1.exr latest.exr
expect 0 "wrote latest.exr" -- "$pk" render cornell.gltf volume.pvol -o latest.exr --size 8,8
check "-o onto a link keeps the link" test -L latest.exr
check "-o onto a link writes its target" bash -c '! cmp -s e.exr store/v1.exr'
check "no temporary files left" bash -c '! ls -A . locked store | grep -q "\.tmp\."'

echo "render CLI: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
