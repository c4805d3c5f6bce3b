#!/usr/bin/env bash
# Builds the libFuzzer target of the config loader with clang
# (-fsanitize=fuzzer,address,undefined; the Makefile's renderer/build-fuzz/
# fuzz_config) and runs it for SECONDS (default 60),
# seeded with every good and bad config. A crash input is kept under
# renderer/fuzz/crashes/ and should be added to tests/configs/fuzz/ as a
# regression test. Prints the number of executions.
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
# The Makefile target holds the sources and flags (FUZZ_SRCS, FUZZ_CC).
make --no-print-directory "$out/fuzz_config"
corpus="$out/corpus"
mkdir -p "$corpus"
cp configs/scenes/*.yaml tests/configs/good/*.yaml tests/configs/bad/*.yaml "$corpus"/ 2>/dev/null || true
[ -d tests/configs/fuzz ] && cp tests/configs/fuzz/* "$corpus"/ 2>/dev/null || true
log="$out/fuzz.log"
set +e
"$out/fuzz_config" "$corpus" -max_total_time="$seconds" -max_len=16384 -timeout=10 -rss_limit_mb=2048 \
  -artifact_prefix=renderer/fuzz/crashes/ -print_final_stats=1 >"$log" 2>&1
rc=$?
set -e
execs=$(grep -E '^stat::number_of_executed_units' "$log" | awk '{print $2}')
echo "fuzz: ${execs:-?} executions in ${seconds}s, exit $rc (log: $log)"
if [ $rc -ne 0 ]; then
  tail -n 40 "$log" >&2
  echo "fuzz: FAILED, crash input(s) in renderer/fuzz/crashes/" >&2
  exit 1
fi
