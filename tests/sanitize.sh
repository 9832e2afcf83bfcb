#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# sanitize.sh SAN_BUILD [all|short] -- the unit tests of the sanitizer build (`make
# sanitize-build`: clang, ASan + LSan + UBSan, every report fatal) must pass and stay clean:
# exit 0, no AddressSanitizer, LeakSanitizer or UBSan "runtime error" report. `all` (make
# sanitize) runs every unit test binary and the tool scripts (replay of crafted logs, the
# CLI) on the sanitized tools; `short` (make test, via test_sanitize.sh) the decoder and
# engine subset that takes seconds. Prints "N passed, N failed".
set -u
SAN=${1:-build/san}
MODE=${2:-all}
cd "$(dirname "$0")/.." || exit 1
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:halt_on_error=1:detect_stack_use_after_return=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=report_objects=1
pass=0; fail=0
ok()  { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
. tests/san_build.sh   # SAN_SHORT: the short list
if [ "$MODE" = short ]; then list=$SAN_SHORT; else list=$(cd "$SAN/tests" && ls test_* 2>/dev/null); fi
log=$(mktemp)
trap 'rm -f "$log"' EXIT
for t in $list; do
  bin="$SAN/tests/$t"
  [ -x "$bin" ] || { bad "$t: not built in $SAN (make sanitize-build)"; continue; }
  t0=$(date +%s.%N)
  "$bin" >"$log" 2>&1; rc=$?
  dt=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b - a}')
  line=$(grep -E '^[0-9]+ passed, [0-9]+ failed' "$log" | tail -1)
  reports=$(grep -cE 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:' "$log")
  if [ $rc -eq 0 ] && [ "$reports" -eq 0 ] && [ -n "$line" ]; then
    ok "$t: $line, clean under ASan+LSan+UBSan ($dt s)"
  else
    bad "$t: exit $rc, $reports sanitizer report(s), '${line:-no result line}' ($dt s)"
    grep -E -A12 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:|^FAIL' "$log" | head -40
  fi
done
if [ "$MODE" = all ]; then
  # The tools on crafted inputs (test_replay.sh: logs with datalen 0x7fffffff, wrapping time
  # stamps, crafted samples_t/status_t) and the CLI, all sanitized.
  for s in tests/test_replay.sh tests/test_cli.sh; do
    bash "$s" "$SAN" >"$log" 2>&1; rc=$?
    line=$(grep -E '^[0-9]+ passed, [0-9]+ failed' "$log" | tail -1)
    reports=$(grep -cE 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:' "$log")
    if [ $rc -eq 0 ] && [ "$reports" -eq 0 ]; then
      ok "$s on the sanitized tools: $line, no sanitizer report"
    else
      bad "$s on the sanitized tools: exit $rc, $reports report(s), $line"
      grep -E -A12 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:|^FAIL' "$log" | head -40
    fi
  done
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
