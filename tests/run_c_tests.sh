#!/usr/bin/env bash
# Runs the C test executables in BUILD/tests, then prints the total as
# "N passed, N failed"; exits non-zero if any test or executable failed.
#
# usage: tests/run_c_tests.sh BUILD_DIR [PROGRAM [CASE]]
#   PROGRAM  only the executables whose name contains it (e.g. mis, test_aov)
#   CASE     only the tests whose name contains it, in those executables
# A PROGRAM that matches no executable, or a CASE that matches no test in
# one of them, is a failure, not an empty green run.
#
# The executables run C_TEST_JOBS at a time (default: the number of
# cores): most of them are single-threaded, and under the sanitizers they
# are a large part of CI's time. Each one's output is kept in a file and
# printed in name order, as if they had run one after another; every test
# that writes files makes its own folder (mkdtemp), so none share one.
set -u
build=${1:?usage: run_c_tests.sh BUILD_DIR [PROGRAM [CASE]]}
program=${2:-}
case_filter=()
[ $# -ge 3 ] && case_filter=("$3")
jobs=${C_TEST_JOBS:-$(nproc 2>/dev/null || echo 1)}
case $jobs in '' | *[!0-9]* | 0) echo "run_c_tests.sh: C_TEST_JOBS must be a positive integer, got \"$jobs\"" >&2; exit 2 ;; esac

tests=()
for t in "$build"/tests/test_*; do
  [ -x "$t" ] && [ -f "$t" ] || continue
  case "$t" in *.o|*.d) continue ;; esac
  case "$(basename "$t")" in *"$program"*) ;; *) continue ;; esac
  tests+=("$t")
done
if [ ${#tests[@]} -eq 0 ]; then
  echo "run_c_tests.sh: no test executable in $build/tests matches \"$program\"" >&2
  exit 1
fi

outdir=$(mktemp -d "${TMPDIR:-/tmp}/run_c_tests.XXXXXX") || exit 2
trap 'rm -rf "$outdir"' EXIT
running=0
for i in "${!tests[@]}"; do
  if [ $running -ge "$jobs" ]; then
    wait -n
    running=$((running - 1))
  fi
  { "${tests[$i]}" "${case_filter[@]}" >"$outdir/$i.out" 2>&1; echo $? >"$outdir/$i.rc"; } &
  running=$((running + 1))
done
wait

passed=0 failed=0 crashed=0
for i in "${!tests[@]}"; do
  t=${tests[$i]}
  echo "== $(basename "$t")"
  out=$(cat "$outdir/$i.out"); rc=$(cat "$outdir/$i.rc" 2>/dev/null || echo 127)
  printf '%s\n' "$out" | grep -v '^ok ' | grep -v ' passed, .* failed$'
  line=$(printf '%s\n' "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed$' | tail -n 1)
  if [ -z "$line" ]; then
    echo "   $(basename "$t") exited $rc without a summary (crash?)"
    crashed=$((crashed + 1)); continue
  fi
  p=${line%% passed*}; f=${line#*, }; f=${f%% failed*}
  passed=$((passed + p)); failed=$((failed + f))
  echo "   $line"
  if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then
    echo "   $(basename "$t") exited $rc"
    crashed=$((crashed + 1))
  fi
done
echo "renderer: $passed passed, $((failed + crashed)) failed"
[ $failed -eq 0 ] && [ $crashed -eq 0 ]
