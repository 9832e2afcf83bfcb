#!/usr/bin/env bash
# test_collapse.sh BUILD -- the real-time collapse of issue 12 as a regression test, inside a
# private network namespace. The recipe: afmtwind in realtime mode on config/default.conf, up
# for a few seconds; retract (setpoint 1 um), then dither frequency steps 336 -> 340 kHz in
# 400 Hz steps every 0.3 s, then an amplitude-only dither change and an unchanged-config
# SIGHUP (the other triggers the audit found). Before the fix the real-time factor fell to
# 0.015-0.04 with ~8 resyncs a second (the estimators' phase trackers rebuilt their tables
# sample by sample once model time was large). Pass: every status from 1.5 s after the start
# shows a real-time factor over the last second of running (realtime_factor_1s) of at least
# 0.9 (the strict 0.99 is printed), at most one resync, and the lock-in amplitude and peak
# force of the status finite. The daemon runs at --speed RT_SPEED (lib_daemon.sh: 0.5, as this
# 2-core machine kind runs default.conf at capacity at 1x; AFMTWIN_RT_SPEED=1 for the full
# speed) and the factor is judged as a share of it. Run once
# after 4 s of real uptime and once with --start-time 60 (model time as after a minute up,
# where the collapse was worst). Timing-sensitive only at the strict level: on a machine
# loaded by other work a window can dip below 0.99, which is reported, not failed.
# Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_collapse.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
T=$(mktemp -d /tmp/afmtwin-collapse.XXXXXX)
DPID=""; LPID=""; MPID=""
cleanup() {
  for p in $DPID $LPID $MPID; do kill -KILL "$p" 2>/dev/null; done
  rm -rf "$T"
}
trap cleanup EXIT

# RECIPE NAME WARMUP_S DAEMON_ARGS...
recipe() {
  local name=$1 warm=$2; shift 2
  cp config/default.conf "$T/twin.conf"
  "$D" --config "$T/twin.conf" --quiet --speed "$RT_SPEED" "$@" 2> "$T/d.err" &
  DPID=$!
  rt_others "$T/others.txt" "$DPID" &
  MPID=$!
  listen --channels status --json --timeout 30 > "$T/status.json" 2>/dev/null &
  LPID=$!
  sleep "$warm"
  local t0; t0=$(date +%s.%N)
  "$A" send setpoint --z 1e-6 --quiet
  sleep 0.3
  for f in 336000 336400 336800 337200 337600 338000 338400 338800 339200 339600 340000; do
    "$A" send dither --freq $f --amp 0.087e-9 --quiet
    sleep 0.3
  done
  "$A" send dither --freq 340000 --amp 0.06e-9 --quiet # amplitude only
  sleep 1
  listen --channels status --json --count 1 --timeout 3 > "$T/before_hup.json" 2>/dev/null
  kill -HUP "$DPID"                                     # unchanged config
  sleep 2
  kill "$LPID" 2>/dev/null; wait "$LPID" 2>/dev/null; LPID=""
  kill -TERM "$DPID"; wait "$DPID"; local rc=$?; DPID=""
  wait "$MPID" 2>/dev/null; MPID=""
  local others; others=$(cat "$T/others.txt")
  [ $rc -eq 0 ] && ok "$name: daemon ran the recipe and exited 0" || bad "$name: daemon exit $rc"
  # statuses from 1.5 s after start: the real-time factor of the last second, resyncs
  awk -v warm=1.5 -v speed="$RT_SPEED" '
    function num(k,   m) { if (match($0, "\"" k "\":[^,}]*")) { m = substr($0, RSTART, RLENGTH); sub(/.*:/, "", m); return m } return "" }
    { n++; t = num("utime") / 1e6; if (n == 1) t0 = t
      if (t - t0 < warm) { r0 = num("resyncs"); next }
      w++; f = (num("realtime_factor_1s") + 0) / speed; if (w == 1 || f < min) min = f
      r = num("resyncs"); st = num("chain_stalls")
      if (num("lockin_amplitude_m") == "null" || num("peak_force_n") == "null") nonfinite++ }
    END { printf "%d %.4f %d %d %s\n", w, min, r - r0, nonfinite, st }' "$T/status.json" > "$T/sum.txt"
  read -r windows min resyncs nonfinite stalls < "$T/sum.txt"
  local msg="$name (--speed $RT_SPEED): $windows statuses, real-time factor of the last second (of the speed asked for) min $min, resyncs $resyncs, chain stalls $stalls"
  # The guard: the collapse ran at 0.015-0.04 of real time with ~8 resyncs a second; a
  # machine shared with other work (CI's) dips a few per cent now and then (0.96 seen). Fail
  # below 0.9 or on more than one resync. Chain stalls (the integrator waiting for the output
  # chain) are printed, not judged: 0-81 per run seen on unchanged builds, and a tracker
  # broken on purpose to rebuild the estimators' tables on every sample gave 0-446 while real
  # time held (test_estimators bounds the rebuild count itself). The strict level (0.99, no
  # resync) is printed, and held by make soak on random command sequences.
  local strict="strict level (>= 0.99, no resync) held"
  awk -v m="$min" 'BEGIN{exit !(m >= 0.99)}' && [ "$resyncs" -eq 0 ] \
    || strict="strict level (>= 0.99, no resync) NOT held: a loaded machine, or the start of a regression"
  if [ "${windows:-0}" -gt 30 ] && awk -v m="$min" 'BEGIN{exit !(m >= 0.9)}' && [ "$resyncs" -le 1 ]; then
    ok "$msg; >= 0.9 and at most 1 resync; $strict"
  else
    if [ -n "$others" ]; then
      bad "$msg (below 0.9 or over one resync; other real-time processes ran meanwhile: $others-- re-run on a quiet machine)"
    else
      bad "$msg (below 0.9 or over one resync: the collapse)"
    fi
  fi
  [ "${nonfinite:-1}" -eq 0 ] && ok "$name: lock-in amplitude and peak force in every status" \
    || bad "$name: $nonfinite statuses without lock-in amplitude or peak force"
  local last; last=$(cat "$T/before_hup.json")
  echo "$last" | grep -q '"fe_hz":340000,' && echo "$last" | grep -q '"separation_m":1e-06' \
    && echo "$last" | grep -q '"amplitude_m":6e-11' \
    && ok "$name: the commands took effect (Z 1 um, 340 kHz, 0.06 nm)" \
    || bad "$name: status before the reload: $last"
}

recipe "after 4 s of uptime" 4
recipe "at model time 60 s (--start-time 60)" 1.5 --start-time 60

# Behind real time with every thread below the integrator on its CPU (`--cpu 0 --chain-cpu 1
# --aux-cpu 0` at --speed 3: the integrator never keeps up). Before: the publisher's drain
# never emptied, so no status went out, and at the same SCHED_FIFO priority it kept the
# receive and main threads off the CPU: no status in 3 s, --exit-after 5 took 10-16 s (a
# scan daemon pinned this way ran on, unkillable, for 10 minutes). Now the drain is bounded
# per loop, the publisher yields, and the integrator naps 1 ms after 50 ms without a wait.
# Pass: 3 statuses within 3 s (the listener above the daemon, on its CPU), and the daemon
# gone within 3 s of --exit-after.
t0=$(date +%s.%N)
"$D" --config config/default.conf --scheme fast --speed 3 --cpu 0 --chain-cpu 1 --aux-cpu 0 \
  --quiet --exit-after 5 2> "$T/pin.err" & DPID=$!
sleep 2
n=$(taskset -c 0 chrt -f 90 "$A" listen --channels status --json --count 3 --timeout 3 2>/dev/null |
  grep -c realtime_factor)
for _ in $(seq 1 60); do kill -0 "$DPID" 2>/dev/null || break; sleep 0.1; done
gone=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b - a}')
if kill -0 "$DPID" 2>/dev/null; then kill -KILL "$DPID"; gone="not gone after $gone"; fi
wait "$DPID" 2>/dev/null; DPID=""
[ "$n" -eq 3 ] && ok "pinned beside its integrator, behind real time: 3 statuses in 3 s" ||
  bad "pinned beside its integrator, behind real time: $n statuses in 3 s"
case "$gone" in
  not*) bad "pinned beside its integrator: --exit-after 5: $gone s" ;;
  *) awk -v g="$gone" 'BEGIN{exit !(g <= 8)}' && ok "pinned beside its integrator: --exit-after 5 gone after $gone s" ||
       bad "pinned beside its integrator: --exit-after 5 gone after $gone s (> 8)" ;;
esac

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
