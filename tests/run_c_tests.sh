#!/usr/bin/env bash
# Runs every C test executable in BUILD/tests, then prints the total as
# "N passed, N failed"; exits non-zero if any test or executable failed.
set -u
build=${1:?usage: run_c_tests.sh BUILD_DIR}
passed=0 failed=0 crashed=0
for t in "$build"/tests/test_*; do
  [ -x "$t" ] && [ -f "$t" ] || continue
  case "$t" in *.o|*.d) continue ;; esac
  echo "== $(basename "$t")"
  out=$("$t" 2>&1); rc=$?
  printf '%s\n' "$out" | grep -v '^ok ' | grep -v ' passed, .* failed$'
  line=$(printf '%s\n' "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed$' | tail -n 1)
  if [ -z "$line" ]; then
    echo "   $(basename "$t") exited $rc without a summary (crash?)"
    crashed=$((crashed + 1)); continue
  fi
  p=${line%% passed*}; f=${line#*, }; f=${f%% failed*}
  passed=$((passed + p)); failed=$((failed + f))
  echo "   $line"
  [ $rc -ne 0 ] && [ "$f" -eq 0 ] && crashed=$((crashed + 1))
done
echo "renderer: $passed passed, $((failed + crashed)) failed"
[ $failed -eq 0 ] && [ $crashed -eq 0 ]
