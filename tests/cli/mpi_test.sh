#!/usr/bin/env bash
# Distributed bakes end to end (docs/baking.md#distributed-bakes): `mpirun -np N probekit bake`
# writes the same bytes as one process for every method, layout and setting that bakes probes in
# batches (dense, bricked with its level-by-level refinement, --target-error, adaptive sampling,
# vpl, lpv), for 2 and 3 ranks and 1 and 2 threads; and a rank killed mid-bake ends the job with an
# error and leaves no file. Usage: mpi_test.sh PROBEKIT WORKDIR MPIRUN
set -u
pk=$1
work=$2
mpirun=$3
# shellcheck source=expect.sh
source "$(cd "$(dirname "$0")" && pwd)/expect.sh" || exit 1
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
# As root (CI containers), Open MPI refuses to start without these.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# Local ranks over shared memory; more ranks than cores are allowed.
mpi=("$mpirun" --oversubscribe --mca btl self,vader)

"$pk" scene cornell -o cornell.gltf >/dev/null || exit 1
"$pk" scene thin-wall -o thin.gltf >/dev/null || exit 1
cat >bricked.json <<'JSON'
{"path": {"samples": 32}, "volumes": [{"name": "box", "layout": "bricked", "levels": 2,
  "refine_error": 0.05, "resolution": [2, 2, 2]}]}
JSON

# same NAME "ARGS..." RANKS THREADS: the single-process bake and the distributed one, compared.
same() {
    local name=$1 args=$2 ranks=$3 threads=$4
    # shellcheck disable=SC2086
    "$pk" bake $args -o "$name.single.pvol" -q --threads "$threads" || {
        failed=$((failed + 1))
        echo "FAIL: $name: the single-process bake failed"
        return
    }
    local out
    # shellcheck disable=SC2086
    out=$("${mpi[@]}" -np "$ranks" "$pk" bake $args -o "$name.mpi.pvol" --threads "$threads" \
        --report "$name.report.json" 2>&1)
    local rc=$?
    if [[ $rc -ne 0 ]]; then
        failed=$((failed + 1))
        echo "FAIL: $name: mpirun -np $ranks exited $rc:"
        echo "$out" | tail -5
        return
    fi
    check "$name: -np $ranks --threads $threads equals one process (cmp)" \
        cmp "$name.single.pvol" "$name.mpi.pvol"
    check "$name: the summary names the processes" \
        grep -q "distributed over $ranks processes" <<<"$out"
    check "$name: the report counts the traffic" \
        grep -qE "\"processes\": $ranks|\"mpi_result_bytes_per_probe\"" "$name.report.json"
}

same dense "cornell.gltf --samples 64 --resolution 8,8,8" 2 1
same dense2 "cornell.gltf --samples 64 --resolution 8,8,8" 2 2
same three "cornell.gltf --samples 64 --resolution 8,8,8" 3 1
same vpl "cornell.gltf --method vpl --resolution 4,4,4" 2 1
same lpv "cornell.gltf --method lpv --resolution 4,4,4 --samples 32" 2 1
same bricked "cornell.gltf --config bricked.json" 2 1
same target "thin.gltf --target-error 0.3" 2 1
same adaptive "thin.gltf --resolution 8,4,4 --noise-target 0.1 --samples 64" 2 1

# Only rank 0 writes: one output, no other rank's temporaries.
check "no temporary files left" bash -c '! ls -A . | grep -q "\.tmp\."'

# An error every rank meets (a missing scene) ends the job at once, naming the file.
out=$(timeout 120 "${mpi[@]}" -np 2 "$pk" bake missing.gltf -o missing.pvol 2>&1)
rc=$?
check "a missing scene fails the job (exit $rc)" test "$rc" -ne 0 -a "$rc" -ne 124
check "the error names the file" grep -q "missing.gltf" <<<"$out"
check "no file after the error" test ! -e missing.pvol

# A rank killed mid-bake (a bake of about 20 s of one core, killed 1 s in): the job ends with
# an error naming the lost process, and no file.
"${mpi[@]}" -np 2 "$pk" bake thin.gltf --samples 16384 --resolution 16,8,8 -o killed.pvol \
    --threads 1 -q >killed.log 2>&1 &
launcher=$!
victim=""
for _ in $(seq 1 200); do
    # [.]: the pattern must not match the command line of a shell that runs pgrep.
    for p in $(pgrep -f "probekit bake thin[.]gltf --samples 16384" || true); do
        if tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=1"; then
            victim=$p
        fi
    done
    [[ -n $victim ]] && break
    sleep 0.05
done
if [[ -z $victim ]]; then
    failed=$((failed + 1))
    echo "FAIL: kill test: rank 1 never started"
else
    sleep 1 # into the bake
    kill -9 "$victim"
    wait "$launcher"
    rc=$?
    check "killing rank 1 fails the job (exit $rc)" test "$rc" -ne 0
    check "the error names the lost process" grep -qiE "rank 1|process.*(killed|exited)" killed.log
    check "no file after a killed rank" test ! -e killed.pvol
    check "no temporary file after a killed rank" bash -c '! ls -A . | grep -q "killed.pvol.tmp"'
    check "no process of the job left" bash -c '! pgrep -f "probekit bake thin[.]gltf --samples 16384" >/dev/null'
fi

echo "MPI bake: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
