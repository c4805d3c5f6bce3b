#!/usr/bin/env bash
# Shows that tests/check_layers.sh can fail: on copies of renderer/src with one
# include that points up, one bare include and one library header in the
# wrong layer, it must exit non-zero and name the line.
set -euo pipefail
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
expect_fail() { # CASE FILE LINE-TO-ADD EXPECTED-TEXT
    rm -rf "$tmp/src" && cp -r renderer/src "$tmp/src"
    printf '%s\n' "$3" >>"$tmp/src/$2"
    if out="$(tests/check_layers.sh "$tmp/src" 2>&1)"; then
        echo "check_layers_fails: $1: the check passed a tree it must refuse" >&2; exit 1
    fi
    grep -qF "$4" <<<"$out" || { echo "check_layers_fails: $1: unexpected message: $out" >&2; exit 1; }
}
expect_fail upward base/vec.h '#include "cli/describe.h"' 'base includes "cli/describe.h" of the layer above it, cli'
expect_fail bare geometry/polygon.c '#include "vec.h"' 'does not name its layer'
expect_fail library sampling/strategy.c '#include <embree3/rtcore.h>' 'belongs to the scene layer only'
echo "check_layers_fails: 3 bad trees refused"
