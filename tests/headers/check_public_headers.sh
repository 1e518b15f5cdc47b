#!/usr/bin/env bash
# Compiles every public header of the libraries on its own, with only the include paths its
# layer may use (ARCHITECTURE.md), and fails when one does not compile alone or pulls Embree,
# tinygltf or OpenImageIO into its include tree (all three live under /usr/include, so include
# paths alone cannot keep them out: the compiler's -H list of included files is checked).
# Usage: check_public_headers.sh CXX REPO_ROOT
set -u
cxx=$1
repo=$2
passed=0
failed=0
check_layer() { # check_layer LAYER INCLUDE_DIRS...
    local layer=$1
    shift
    local flags=()
    for dir in "$@"; do flags+=("-I$repo/$dir"); done
    local header
    while IFS= read -r header; do
        local name=${header#"$repo/$layer/include/"}
        local out
        if ! out=$(printf '#include "%s"\n' "$name" |
            "$cxx" -std=c++20 -fsyntax-only -H "${flags[@]}" -x c++ - 2>&1); then
            failed=$((failed + 1))
            echo "FAIL: $name does not compile alone with $layer's include paths:"
            echo "$out" | grep -v '^\.' | head -5
            continue
        fi
        local banned
        banned=$(grep -E '^\.+ .*(embree3/|tiny_gltf|OpenImageIO/)' <<<"$out" | head -3)
        if [[ -n $banned ]]; then
            failed=$((failed + 1))
            echo "FAIL: $name includes a baker-only library:"
            echo "$banned"
            continue
        fi
        passed=$((passed + 1))
    done < <(find "$repo/$layer/include" -name '*.hpp' | sort)
}
check_layer formats formats/include
check_layer runtime runtime/include formats/include shaders
check_layer baker baker/include formats/include
check_layer viewer viewer/include baker/include runtime/include formats/include shaders
echo "$passed passed, $failed failed"
[[ $failed -eq 0 && $passed -gt 0 ]]
