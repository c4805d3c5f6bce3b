#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (-fsanitize=fuzzer,address,
# undefined; the Makefile's renderer/build-fuzz/fuzz_config and fuzz_mesh)
# and runs them one after the other for SECONDS in all (default 60), a third
# each:
#   fuzz_config  the config loader, seeded with every scene, good and bad
#                config (and tests/configs/fuzz/)
#   fuzz_mesh    the mesh loaders (OBJ and PLY, mesh_file.c, ply_check.c),
#                seeded with tests/configs/meshes and the bad meshes (and
#                tests/configs/fuzz_mesh/)
#   fuzz_portals `portals: auto` on random shades built from the bytes
#                (boxes and prisms with holes, welded or not, split,
#                duplicated, flipped, transformed): complete portals or a
#                clean fallback; seeded with tests/configs/fuzz_portals/
# A crash input is kept under renderer/fuzz/crashes/ and should be added to
# tests/configs/fuzz/ (configs) or tests/configs/fuzz_mesh/ (meshes) as a
# regression test (fuzz_portals inputs to tests/configs/fuzz_portals/):
# make test-c replays the folders. Prints the number of
# executions of each target.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-60}
if ! command -v clang >/dev/null; then
  echo "fuzz: installing clang with apt-get" >&2
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq clang >/dev/null
fi
# libFuzzer's runtime lives in libclang-rt-N-dev, only recommended by clang.
major=$(clang -dumpversion | cut -d. -f1)
if ! ls /usr/lib/llvm-"$major"/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a >/dev/null 2>&1; then
  echo "fuzz: installing libclang-rt-$major-dev with apt-get" >&2
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "libclang-rt-$major-dev" >/dev/null
fi
out=renderer/build-fuzz
mkdir -p "$out" renderer/fuzz/crashes
# The Makefile targets hold the sources and flags (FUZZ_SRCS, FUZZ_MESH_SRCS, FUZZ_CC).
make --no-print-directory -j"${JOBS:-$(nproc)}" "$out/fuzz_config" "$out/fuzz_mesh" "$out/fuzz_portals"

# fuzz TARGET SECONDS MAX_LEN SEED_FILES...: runs one target on its own
# corpus folder; returns its exit status.
fuzz() {
  local target=$1 secs=$2 max_len=$3
  shift 3
  local corpus="$out/corpus_$target" log="$out/$target.log"
  mkdir -p "$corpus"
  cp "$@" "$corpus"/ 2>/dev/null || true
  set +e
  "$out/$target" "$corpus" -max_total_time="$secs" -max_len="$max_len" -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix=renderer/fuzz/crashes/"$target"- -print_final_stats=1 >"$log" 2>&1
  local rc=$?
  set -e
  local execs
  execs=$(grep -E '^stat::number_of_executed_units' "$log" | awk '{print $2}')
  echo "fuzz: $target: ${execs:-?} executions in ${secs}s, exit $rc (log: $log)"
  if [ $rc -ne 0 ]; then
    tail -n 40 "$log" >&2
    echo "fuzz: $target FAILED, crash input(s) in renderer/fuzz/crashes/" >&2
  fi
  return $rc
}

first=$((seconds / 3))
[ "$first" -ge 1 ] || first=1
second=$first
third=$((seconds - first - second))
[ "$third" -ge 1 ] || third=1
status=0
shopt -s nullglob
fuzz fuzz_config "$first" 16384 configs/scenes/*.yaml tests/configs/good/*.yaml tests/configs/bad/*.yaml \
  tests/configs/fuzz/* || status=1
# Assimp leaks what it allocated when its OBJ importer throws; the
# suppressions (renderer/fuzz/lsan_mesh.supp) name libassimp only.
LSAN_OPTIONS="suppressions=$PWD/renderer/fuzz/lsan_mesh.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}" \
  fuzz fuzz_mesh "$second" 16384 tests/configs/meshes/*.obj tests/configs/meshes/*.ply \
  tests/configs/bad/meshes/* tests/configs/fuzz_mesh/* || status=1
fuzz fuzz_portals "$third" 512 tests/configs/fuzz_portals/* || status=1
exit $status
