#!/usr/bin/env bash
# run.sh BUILD -- runs every test binary (and tests/*.sh scripts) and prints one closing
# line "N passed, N failed" summed over all of them. Exit status 1 if anything failed.
# The unit test binaries and the scripts that need no daemon (they source tests/lib_check.sh:
# the CLI's offline computations; no wall-clock bound) form a pool that runs
# AFMTWIN_TEST_JOBS at a time (default: the number of CPUs, at most 2), the longest first,
# at nice 19 beside the daemon scripts (which run one at a time, their daemons at SCHED_FIFO
# or, where that is not permitted, at nice 0: the pool takes only the CPU they leave, at
# --speed 0.5 about half); its outputs are printed in order once it is done.
# AFMTWIN_TEST_OVERLAP=0: the pool first, at normal priority, then the daemon scripts. The
# builds of the scripts run last (the sanitizer build of test_flood, test_fuzz and
# test_sanitize; test_march's other copies) are made in the pool too, at -j1, so that their
# one long compile (afm_rt.c) does not leave a core idle; a failed one is made again, and
# reported, by its script.
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
OVERLAP=${AFMTWIN_TEST_OVERLAP:-1}
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
# After the pool: the scripts that run what its builds made.
first=(); after=()
for t in "${serial[@]}"; do
  case $(basename "$t") in
    test_flood.sh | test_fuzz.sh | test_sanitize.sh | test_march.sh) after+=("$t") ;;
    *) first+=("$t") ;;
  esac
done
# The pool, JOBS at a time: section i writes TMP/i.out, .rc, .s; nice 19 when it runs beside
# the daemon scripts.
run_pool() {
  local running=0 i t
  for i in "${order[@]}"; do
    t=${pool[$i]}
    case $t in build:*) ;; *) [ -e "$t" ] || continue ;; esac
    if [ "$running" -ge "$JOBS" ]; then wait -n; running=$((running - 1)); fi
    running=$((running + 1))
    ( [ "$OVERLAP" = 1 ] && renice -n 19 -p $BASHPID > /dev/null
      t0=$(date +%s)
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
  echo $(( $(date +%s) - T0 )) > "$TMP/pool.s"
}
print_pool() {
  local i t
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
  echo "   (the pool of ${#pool[@]} sections, $JOBS at a time$([ "$OVERLAP" = 1 ] && echo " at nice 19 beside the daemon scripts"): $(cat "$TMP/pool.s") s wall)"
}
run_serial() {
  local t t0 out rc
  for t in "$@"; do
    t0=$(date +%s)
    out=$(bash "$t" "$BUILD" 2>&1); rc=$?
    account "$t" "$out" "$rc" $(( $(date +%s) - t0 ))
  done
}
if [ "$OVERLAP" = 1 ]; then
  run_pool &
  POOL=$!
  run_serial "${first[@]}"
  wait "$POOL"
  print_pool
else
  run_pool
  print_pool
  run_serial "${first[@]}"
fi
run_serial "${after[@]}"
echo "   slowest sections (s): $(printf '%s\n' "${times[@]}" | sort -rn | head -12 | awk '{printf "%s %s; ", $2, $1}')"
echo "   all tests: $(( $(date +%s) - T0 )) s wall"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
