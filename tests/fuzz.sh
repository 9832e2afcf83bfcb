#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# fuzz.sh SAN_BUILD RUNS SECONDS -- runs every libFuzzer harness of the sanitizer build
# (fuzz/fuzz_*.c, built by `make sanitize-build`) for RUNS inputs each (0: no limit), or
# until SECONDS have passed (0: no limit), from seed corpora the unit tests' inputs make
# (fuzz/seeds.c; the config harness: config/ and tests/bad-configs/). Every report is fatal:
# a crash, an ASan/UBSan error, a leak (LSan, checked per input), a hang (60 s per
# input) or an out-of-memory (2 GB) fails the harness; the input is kept in
# SAN_BUILD/fuzz/artifacts/. New inputs accumulate in SAN_BUILD/fuzz/corpus/<harness>.
# `make fuzz` (RUNS 1e7), `make test` (tests/test_fuzz.sh: 3 s each). Prints one line per
# harness with executions, rate, corpus and coverage, then "N passed, N failed".
set -u
SAN=${1:-build/san}
RUNS=${2:-10000000}
SECONDS_EACH=${3:-0}
cd "$(dirname "$0")/.." || exit 1
F="$SAN/fuzz"
pass=0; fail=0
ok()  { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
[ -x "$F/seeds" ] || { bad "no fuzzers in $F (make sanitize-build)"; echo "$pass passed, $fail failed"; exit 1; }
export ASAN_OPTIONS=detect_leaks=1:halt_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=suppressions=$PWD/fuzz/lsan.supp:print_suppressions=0
rm -rf "$F/seeds-dir"
"$F/seeds" "$F/seeds-dir" >/dev/null || { bad "seeds"; echo "$pass passed, $fail failed"; exit 1; }
mkdir -p "$F/seeds-dir/config" "$F/artifacts"
cp config/*.conf tests/bad-configs/*.conf "$F/seeds-dir/config/"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
for h in cmd can config out log; do
  mkdir -p "$F/corpus/$h"
  args=(-print_final_stats=1 -timeout=60 -rss_limit_mb=2048 -max_len=8192
        -artifact_prefix="$F/artifacts/$h-")
  # libconfig leaks on many parse errors (fuzz/lsan.supp): a leak check after each such
  # input makes fuzz_config 23x slower (1960/s against 45600/s). It runs without the
  # per-input check, and its whole corpus is run once more with leak checks after it.
  [ "$h" = config ] && args+=(-detect_leaks=0)
  [ "$RUNS" -gt 0 ] && args+=(-runs="$RUNS")
  [ "$SECONDS_EACH" -gt 0 ] && args+=(-max_total_time="$SECONDS_EACH")
  t0=$(date +%s.%N)
  "$F/fuzz_$h" "${args[@]}" "$F/corpus/$h" "$F/seeds-dir/$h" >"$log" 2>&1; rc=$?
  dt=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.0f", b - a}')
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | cut -d' ' -f2)
  corp=$(ls "$F/corpus/$h" | wc -l)
  leakpass=""
  if [ "$h" = config ] && [ $rc -eq 0 ]; then
    "$F/fuzz_$h" -runs=0 -detect_leaks=1 -artifact_prefix="$F/artifacts/$h-" \
      "$F/corpus/$h" "$F/seeds-dir/$h" >>"$log" 2>&1; rc=$?
    leakpass=", leak-checked corpus pass over $(ls "$F/corpus/$h" "$F/seeds-dir/$h" | wc -l) inputs"
  fi
  reports=$(grep -cE 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error:|SUMMARY: ' "$log")
  what="fuzz_$h: ${execs:-?} executions in $dt s (${rate:-?}/s), corpus $corp inputs, coverage ${cov:-?} edges$leakpass"
  if [ $rc -eq 0 ] && [ "$reports" -eq 0 ] && [ -n "$execs" ] &&
     { [ "$RUNS" -eq 0 ] || [ "$SECONDS_EACH" -gt 0 ] || [ "$execs" -ge "$RUNS" ]; }; then
    ok "$what, 0 crashes, 0 leaks, 0 UBSan reports"
  else
    bad "$what: exit $rc, $reports report(s)"
    grep -E -B2 -A20 'ERROR:|runtime error:|SUMMARY:' "$log" | head -60
    ls -t "$F/artifacts" | head -3 | sed 's/^/     artifact: /'
  fi
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
