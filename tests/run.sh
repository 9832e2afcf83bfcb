#!/usr/bin/env bash
# run.sh BUILD -- runs every test binary (and tests/*.sh scripts) and prints one closing
# line "N passed, N failed" summed over all of them. Exit status 1 if anything failed.
# The unit test binaries and the scripts that need no daemon (they source tests/lib_check.sh:
# the CLI's offline computations; no wall-clock bound) run AFMTWIN_TEST_JOBS at a time
# (default: the number of CPUs, at most 2), the longest first, their outputs printed in
# order once all are done; the other scripts (daemons held to real time, their own -j2
# builds) one at a time after them. The builds those scripts need (the sanitizer build of
# test_flood, test_fuzz and test_sanitize; test_march's other copies) are made in the pool
# too, at -j1, so that their one long compile (afm_rt.c) runs beside the unit tests rather
# than beside an idle core; a failed one is made again, and reported, by its script.
# Every section prints its wall time, "(tests/test_X.sh: N s)"; the slowest ones and the
# total are repeated before the closing line.
set -u
BUILD=${1:-build}
export AFMTWIN_BUILD=$BUILD # for the tests that run the CLI
cd "$(dirname "$0")/.."
pass=0; fail=0
T0=$(date +%s)
TMP=$(mktemp -d /tmp/afmtwin-run.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
times=()
JOBS=${AFMTWIN_TEST_JOBS:-$(nproc 2>/dev/null || echo 1)}
[ "$JOBS" -gt 2 ] && [ -z "${AFMTWIN_TEST_JOBS:-}" ] && JOBS=2
# The binaries of the sources that exist (a stale binary of a removed test is not run), and
# the scripts without a daemon: the pool. The longest start first (LONG_FIRST, in this
# order), so that the pool does not end on one of them alone.
LONG_FIRST="test_rt_steady build:san test_continue build:march test_thesis_sweeps test_plot.sh
            test_period_metrics"
pool=(); serial=()
for c in tests/test_*.c; do pool+=("$BUILD/tests/$(basename "${c%.c}")"); done
for t in tests/test_*.sh; do
  if grep -q 'lib_check.sh' "$t" && ! grep -qE 'afmtwind|unshare|lib_daemon|lib_fm|mpirun' "$t"; then
    pool+=("$t"); else serial+=("$t"); fi
done
pool+=(build:san)
[ "$(uname -m)" = x86_64 ] && pool+=(build:march)
order=()
for l in $LONG_FIRST; do
  for i in "${!pool[@]}"; do [ "$(basename "${pool[$i]}")" = "$l" ] && order+=("$i"); done
done
for i in "${!pool[@]}"; do case " ${order[*]} " in *" $i "*) ;; *) order+=("$i") ;; esac; done
# One section's output, its time and its result line into the sums.
account() { # NAME OUT RC SECONDS
  local t=$1 out=$2 rc=$3 s=$4 line p f
  echo "== $t"
  echo "$out"
  echo "   ($t: $s s)"
  times+=("$s $t")
  line=$(echo "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed' | tail -1)
  if [ -z "$line" ]; then
    echo "FAIL $t: no result line (exit $rc)"; fail=$((fail+1)); return
  fi
  p=${line%% passed*}; f=${line#*, }; f=${f%% failed*}
  pass=$((pass+p)); fail=$((fail+f))
  if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then echo "FAIL $t: exit $rc"; fail=$((fail+1)); fi
}
# The pool, JOBS at a time: section i writes TMP/i.out, .rc, .s.
running=0
for i in "${order[@]}"; do
  t=${pool[$i]}
  case $t in build:*) ;; *) [ -e "$t" ] || continue ;; esac
  if [ "$running" -ge "$JOBS" ]; then wait -n; running=$((running - 1)); fi
  running=$((running + 1))
  ( t0=$(date +%s)
    case $t in
      build:san) (. tests/san_build.sh
                  SAN_JOBS=1 san_build "$BUILD" bin/afmtwind fuzzers $(printf 'tests/%s ' $SAN_SHORT)) ;;
      build:march) # tests/test_march.sh's copies
        for m in x86-64 $([ "${AFMTWIN_VALIDATE:-}" = full ] && echo x86-64-v3); do
          make -s -j1 --no-print-directory BUILD="$BUILD/march/$m" AFMTWIN_MARCH=$m \
            "$BUILD/march/$m/bin/afmtwin" || exit 1
        done ;;
      *.sh) bash "$t" "$BUILD" ;;
      *) "$t" ;;
    esac > "$TMP/$i.out" 2>&1
    echo $? > "$TMP/$i.rc"; echo $(( $(date +%s) - t0 )) > "$TMP/$i.s" ) &
done
wait
pool_s=$(( $(date +%s) - T0 ))
for i in "${!pool[@]}"; do
  t=${pool[$i]}
  case $t in build:*)
    echo "   ($t, the scripts' build: $(cat "$TMP/$i.s") s, exit $(cat "$TMP/$i.rc"))"
    [ "$(cat "$TMP/$i.rc")" = 0 ] || tail -5 "$TMP/$i.out"
    continue ;;
  esac
  if [ ! -e "$t" ]; then echo "FAIL $t: not built"; fail=$((fail+1)); continue; fi
  account "$t" "$(cat "$TMP/$i.out")" "$(cat "$TMP/$i.rc")" "$(cat "$TMP/$i.s")"
done
echo "   (the pool of ${#pool[@]} sections, $JOBS at a time: $pool_s s wall)"
for t in "${serial[@]}"; do
  t0=$(date +%s)
  out=$(bash "$t" "$BUILD" 2>&1); rc=$?
  account "$t" "$out" "$rc" $(( $(date +%s) - t0 ))
done
echo "   slowest sections (s): $(printf '%s\n' "${times[@]}" | sort -rn | head -12 | awk '{printf "%s %s; ", $2, $1}')"
echo "   all tests: $(( $(date +%s) - T0 )) s wall"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
