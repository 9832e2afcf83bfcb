#!/usr/bin/env bash
# run.sh BUILD -- runs every test binary (and tests/*.sh scripts) and prints one closing
# line "N passed, N failed" summed over all of them. Exit status 1 if anything failed.
set -u
BUILD=${1:-build}
export AFMTWIN_BUILD=$BUILD # for the tests that run the CLI
cd "$(dirname "$0")/.."
pass=0; fail=0
# The binaries of the sources that exist (a stale binary of a removed test is not run).
bins=()
for c in tests/test_*.c; do bins+=("$BUILD/tests/$(basename "${c%.c}")"); done
for t in "${bins[@]}" tests/test_*.sh; do
  if [ ! -e "$t" ]; then echo "FAIL $t: not built"; fail=$((fail+1)); continue; fi
  echo "== $t"
  t0=$(date +%s)
  out=$(if [ "${t%.sh}" != "$t" ]; then bash "$t" "$BUILD"; else "$t"; fi 2>&1); rc=$?
  echo "$out"
  echo "   ($t: $(( $(date +%s) - t0 )) s)"
  line=$(echo "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed' | tail -1)
  if [ -z "$line" ]; then
    echo "FAIL $t: no result line (exit $rc)"; fail=$((fail+1)); continue
  fi
  p=${line%% passed*}; f=${line#*, }; f=${f%% failed*}
  pass=$((pass+p)); fail=$((fail+f))
  if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then echo "FAIL $t: exit $rc"; fail=$((fail+1)); fi
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
