#!/usr/bin/env bash
# The stages inside baker/src include only their own or a lower stage (ARCHITECTURE.md, "Inside
# baker/"): scene < trace < methods < volume, and no stage file includes the drivers' public
# headers (bake.hpp, target.hpp) or a top-level baker/src header. Prints each include that runs
# back up as `file:line: ...` and exits 1; exits 0 with a count otherwise.
# Usage: check_baker_stages.sh REPO_ROOT
set -u
repo=$1
stages=(scene trace methods volume)
checked=0
failed=0
for rank in "${!stages[@]}"; do
    stage=${stages[$rank]}
    dir="$repo/baker/src/$stage"
    [[ -d $dir ]] || continue
    while IFS=: read -r file line text; do
        checked=$((checked + 1))
        target=$(sed -E 's/.*#include "([^"]+)".*/\1/' <<<"$text")
        bad=""
        case $target in
        probekit/baker/bake.hpp | probekit/baker/target.hpp) bad="includes the driver header $target" ;;
        probekit/*) ;;
        */*)
            to=${target%%/*}
            for r in "${!stages[@]}"; do
                if [[ ${stages[$r]} == "$to" && $r -gt $rank ]]; then
                    bad="includes $target from the higher stage $to/"
                fi
            done
            ;;
        *)
            [[ -f "$repo/baker/src/$target" ]] && bad="includes the top-level baker/src header $target"
            ;;
        esac
        if [[ -n $bad ]]; then
            echo "${file#"$repo/"}:$line: $stage/ $bad"
            failed=$((failed + 1))
        fi
    done < <(grep -rn --include='*.cpp' --include='*.hpp' '^#include "' "$dir" | sort)
done
if ((failed > 0)); then
    echo "check_baker_stages: $failed of $checked includes run back up"
    exit 1
fi
echo "check_baker_stages: $checked includes, none runs back up"
