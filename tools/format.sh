#!/usr/bin/env bash
# Reformats every C++ source of the project in place with the committed .clang-format.
set -euo pipefail
cd "$(dirname "$0")/.."
git ls-files -co --exclude-standard -- '*.cpp' '*.hpp' | xargs -r clang-format -i
