#!/usr/bin/env bash
# Runs the C test executables in BUILD/tests, then prints the total as
# "N passed, N failed"; exits non-zero if any test or executable failed.
#
# usage: tests/run_c_tests.sh BUILD_DIR [PROGRAM [CASE]]
#   PROGRAM  only the executables whose name contains it (e.g. mis, test_aov)
#   CASE     only the tests whose name contains it, in those executables
# A PROGRAM that matches no executable, or a CASE that matches no test in
# one of them, is a failure, not an empty green run.
set -u
build=${1:?usage: run_c_tests.sh BUILD_DIR [PROGRAM [CASE]]}
program=${2:-}
case_filter=()
[ $# -ge 3 ] && case_filter=("$3")
passed=0 failed=0 crashed=0 ran=0
for t in "$build"/tests/test_*; do
  [ -x "$t" ] && [ -f "$t" ] || continue
  case "$t" in *.o|*.d) continue ;; esac
  case "$(basename "$t")" in *"$program"*) ;; *) continue ;; esac
  ran=$((ran + 1))
  echo "== $(basename "$t")"
  out=$("$t" "${case_filter[@]}" 2>&1); rc=$?
  printf '%s\n' "$out" | grep -v '^ok ' | grep -v ' passed, .* failed$'
  line=$(printf '%s\n' "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed$' | tail -n 1)
  if [ -z "$line" ]; then
    echo "   $(basename "$t") exited $rc without a summary (crash?)"
    crashed=$((crashed + 1)); continue
  fi
  p=${line%% passed*}; f=${line#*, }; f=${f%% failed*}
  passed=$((passed + p)); failed=$((failed + f))
  echo "   $line"
  if [ $rc -ne 0 ] && [ "$f" -eq 0 ]; then
    echo "   $(basename "$t") exited $rc"
    crashed=$((crashed + 1))
  fi
done
if [ $ran -eq 0 ]; then
  echo "run_c_tests.sh: no test executable in $build/tests matches \"$program\"" >&2
  exit 1
fi
echo "renderer: $passed passed, $((failed + crashed)) failed"
[ $failed -eq 0 ] && [ $crashed -eq 0 ]
