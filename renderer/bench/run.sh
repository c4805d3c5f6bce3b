#!/usr/bin/env bash
# The benchmark suite (`make bench`): the C micro-benchmarks (Makefile
# targets BUILD_DIR/bench/micro, raw_embree and mesh_load), runs every section (renderer/bench/bench.py) and
# writes results/bench/<section>.json plus results/bench/summary.md, which
# is also printed. Progress goes to stderr.
#
# usage: renderer/bench/run.sh BUILD_DIR
#   BENCH_QUICK=1          smoke version (~2 minutes instead of ~10-15)
#   BENCH_ONLY=a,b         only these sections (see bench.py --help)
#   BENCH_FRESH_REFS=1     re-render the cached efficiency references
#   BENCH_PYTHON=path      Python with numpy and the openexr bindings
#                          (default: .venv/bin/python of the repository)
#   BENCH_MITSUBA_PYTHON=path  Python with Mitsuba 3 for the `mitsuba` section
#                          (default: .venv-xcheck/bin/python; make bench
#                          installs it, and libllvm19 for DRJIT_LIBLLVM_PATH)
set -euo pipefail

die() { echo "bench: $*" >&2; exit 1; }

[ $# -eq 1 ] || die "usage: renderer/bench/run.sh BUILD_DIR"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="$1"
case "$BUILD" in /*) ;; *) BUILD="$PWD/$BUILD" ;; esac
cd "$ROOT"

[ -x "$BUILD/render" ] || die "renderer not found: $BUILD/render is missing or not executable (run make first)"
[ -f "$BUILD/librender.a" ] || die "library not found: $BUILD/librender.a is missing (run make first)"

PY="${BENCH_PYTHON:-$ROOT/.venv/bin/python}"
[ -x "$PY" ] || die "python not found at $PY (run make venv, or set BENCH_PYTHON)"
"$PY" -c 'import numpy, OpenEXR' 2>/dev/null || die "$PY lacks numpy or the openexr bindings"

# The programs are the Makefile's targets (the library's own flags); for a
# build folder inside the repository, make brings them up to date here.
rel="${BUILD#"$ROOT"/}"
if [ "$rel" != "$BUILD" ]; then
    make --no-print-directory "$rel/bench/raw_embree" "$rel/bench/micro" "$rel/bench/mesh_load" >&2 \
        || die "cannot build the benchmark programs (make $rel/bench/raw_embree $rel/bench/micro $rel/bench/mesh_load)"
fi
for prog in raw_embree micro mesh_load; do
    [ -x "$BUILD/bench/$prog" ] || die "$BUILD/bench/$prog is missing (run make bench)"
done

args=("$BUILD")
[ "${BENCH_QUICK:-0}" = "1" ] && args+=(--quick)
[ -n "${BENCH_ONLY:-}" ] && args+=(--only "$BENCH_ONLY")

status=0
"$PY" renderer/bench/bench.py "${args[@]}" || status=$?
[ $status -eq 2 ] && exit 2  # usage error: nothing was measured
"$PY" renderer/bench/summary.py || status=$?
[ $status -eq 0 ] || echo "bench: some sections failed (see the messages above)" >&2
exit $status
