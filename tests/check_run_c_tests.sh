#!/usr/bin/env bash
# The C test runner's own test (`make test-c`): a filter that selects
# nothing must fail, loudly, instead of passing as "0 passed, 0 failed".
# usage: tests/check_run_c_tests.sh BUILD_DIR
set -u
build=${1:?usage: check_run_c_tests.sh BUILD_DIR}
runner="$(dirname "$0")/run_c_tests.sh"
fails=0
expect() { # expect STATUS(0|nonzero) PATTERN COMMAND...
  local want=$1 pattern=$2; shift 2
  local out rc
  out=$("$@" 2>&1); rc=$?
  if { [ "$want" = 0 ] && [ $rc -ne 0 ]; } || { [ "$want" = nonzero ] && [ $rc -eq 0 ]; } ||
     ! printf '%s\n' "$out" | grep -q -- "$pattern"; then
    echo "FAIL: $* exited $rc (want $want, output matching \"$pattern\"):" >&2
    printf '%s\n' "$out" | sed 's/^/    /' >&2
    fails=$((fails + 1))
  fi
}
expect nonzero 'no test matches "no_such_case"' "$build/tests/test_rng" no_such_case
expect 0 '^1 passed, 0 failed$' "$build/tests/test_rng" streams_are_pinned
expect nonzero 'no test executable .* matches "no_such_program"' "$runner" "$build" no_such_program
expect nonzero 'renderer: 0 passed, 1 failed' "$runner" "$build" test_rng no_such_case
expect 0 'renderer: 1 passed, 0 failed' "$runner" "$build" test_rng streams_are_pinned
expect nonzero 'C_TEST_JOBS must be a positive integer' env C_TEST_JOBS=0 "$runner" "$build" test_rng
if [ $fails -ne 0 ]; then
  echo "test runner: $fails checks failed" >&2
  exit 1
fi
echo "test runner: empty filters fail, 6 checks passed"
