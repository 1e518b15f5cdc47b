# Sourced by the end-to-end CLI scripts (tests/cli/cli_test.sh, tests/gpu/render_cli_test.sh,
# tests/cli/mpi_test.sh): the pass/fail counters and the two checks that count into them.
passed=0
failed=0

# expect CODE PATTERN -- COMMAND...: exit code CODE and stderr+stdout matching PATTERN.
expect() {
    local code=$1 pattern=$2
    shift 3
    local out rc
    out=$("$@" 2>&1)
    rc=$?
    if [[ $rc -eq $code ]] && grep -qE -- "$pattern" <<<"$out"; then
        passed=$((passed + 1))
    else
        failed=$((failed + 1))
        echo "FAIL: $* -> exit $rc (want $code), output must match '$pattern':"
        echo "$out" | head -5
    fi
}
check() { # check DESCRIPTION COMMAND...: the command must succeed.
    local what=$1
    shift
    if "$@"; then passed=$((passed + 1)); else failed=$((failed + 1)); echo "FAIL: $what"; fi
}
