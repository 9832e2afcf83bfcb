#!/usr/bin/env bash
# test_soak.sh BUILD -- the bounded command soak of issue 12, inside a private network
# namespace, on config/default.conf and config/nchv.conf. `afmtwin soak` sends seeded random
# valid commands of every kind (setpoints from 1 um down to indentation, ramps, frequency and
# amplitude steps, multi-tone, force / damping / geometry changes, pause / step / run, reset)
# at up to 1 kHz to a realtime afmtwind and checks: every status's real-time factor over the
# last second of running >= AFMTWIN_SOAK_MIN_RTF with no resync (one block may be skipped right after a
# geometry rebuild: counted, reported), every command applied and echoed, every output
# finite. Then the same command log runs through `afmtwin lockstep --check` against a
# lockstep afmtwind (--harmonics-every 64): every completion (seq, samples, model time, the
# samples and harmonics digests) identical to `afmtwin replay --lockstep` of the sequence
# (a run that differs says where and is run once more: see step 2 below).
# AFMTWIN_SOAK_S: soak seconds per config (default 10; `make soak`: 300), AFMTWIN_SOAK_CHECK_S:
# model seconds of each log checked in lockstep (default 3; `make soak`: 60; "all": the whole
# log). AFMTWIN_SOAK_MIN_RTF: the real-time factor every status must show (default 0.9: a
# machine shared with other work, CI's, dips a few per cent now and then; `make soak`: 0.99;
# the minimum seen is printed either way). The realtime daemon runs at --speed RT_SPEED
# (lib_daemon.sh: 0.5 in make test, 1 in make soak), the factor judged as a share of it. The lockstep run keeps a tick's round trip on CPU 0 (docs/realtime.md).
# Real-time checks on a machine shared with other real-time processes can fail for that
# reason: the failure names them. Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_soak.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
SOAK_S=${AFMTWIN_SOAK_S:-10}
CHECK_S=${AFMTWIN_SOAK_CHECK_S:-3}
MIN_RTF=${AFMTWIN_SOAK_MIN_RTF:-0.9}
T=$(mktemp -d /tmp/afmtwin-soak.XXXXXX)
DPID=""; MPID=""
cleanup() { for p in $DPID $MPID; do kill -KILL "$p" 2>/dev/null; done; rm -rf "$T"; }
trap cleanup EXIT

# One lockstep run of the soak log against a fresh lockstep daemon, checked against replay
# (outputs in $T/ls.txt, $T/ls.err); its exit status.
lockstep_once() {
  "$D" --config "$1" --mode lockstep --harmonics-every 64 --quiet --cpu 0 --chain-cpu 1 \
    --aux-cpu 0 2> "$T/l.err" &
  DPID=$!
  sleep 1
  local until="" rc
  [ "$CHECK_S" != "all" ] && until="--until $CHECK_S"
  # --timeout 30: a lost tick or completion is re-sent after 0.2 s (docs/realtime.md), but a
  # completion can also be late for seconds: another process's SCHED_FIFO threads (a
  # real-time twin at capacity) leave no CPU to the daemon's output chain (FIFO 60 on CPU 1;
  # seen: a tick applied, chain_lag_s = the whole tick after 10 s, no datagram dropped)
  "$A" lockstep --in "$T/soak.log" --config "$1" --check --harmonics-every 64 --cpu 0 $until \
    --timeout 30 > "$T/ls.txt" 2> "$T/ls.err"
  rc=$?
  kill -TERM "$DPID"; wait "$DPID"; DPID=""
  sed 's/^/     /' "$T/ls.txt"; head -8 "$T/ls.err" | sed 's/^/     /'
  return $rc
}

seed=1
for conf in config/default.conf config/nchv.conf; do
  name=$(basename "$conf")
  # 1. realtime soak
  "$D" --config "$conf" --quiet --speed "$RT_SPEED" 2> "$T/d.err" &
  DPID=$!
  rt_others "$T/others.txt" "$DPID" &
  MPID=$!
  sleep 1
  "$A" soak --config "$conf" --seconds "$SOAK_S" --seed $seed --min-rtf "$MIN_RTF" --speed "$RT_SPEED" --log "$T/soak.log" > "$T/soak.txt" 2> "$T/soak.err"
  rc=$?
  kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
  wait "$MPID" 2>/dev/null; MPID=""
  sed 's/^/     /' "$T/soak.txt"
  head -12 "$T/soak.err" | sed 's/^/     /'
  others=$(cat "$T/others.txt")
  summary=$(grep "real time:" "$T/soak.txt" | sed 's/^ *real time: //')
  if [ $rc -eq 0 ]; then
    ok "$name: ${SOAK_S} s soak, seed $seed: real time held, every command applied and echoed, outputs finite ($summary)"
  elif [ -n "$others" ]; then
    bad "$name: soak failed (exit $rc; other real-time processes ran meanwhile: $others) $summary"
  else
    bad "$name: soak failed (exit $rc) $summary"
  fi
  [ $drc -eq 0 ] && ok "$name: daemon exited 0 after the soak" || bad "$name: daemon exit $drc"
  # 2. the same log in lockstep, against replay. One rare difference has been seen (CI of
  # stop 40: 1 of 3046 completions, harmonics only, not reproduced in 40 000 here): a run
  # that differs is told with its first differing record and field, and run once more on a
  # fresh daemon; a second difference fails (a build that breaks lockstep differs every time).
  first=""
  for try in 1 2; do
    lockstep_once "$conf"
    rc=$?
    line=$(grep "vs afmtwin replay" "$T/ls.txt" | sed 's/^afmtwin lockstep: //')
    [ $rc -eq 0 ] && break
    first="$line; $(grep -E "differs|harmonics message|published|no completion|failed" "$T/ls.err" | head -3 | tr '\n' ' ')"
    echo "     first try differed: $first"
  done
  if [ $rc -eq 0 ] && [ -z "$first" ]; then
    ok "$name: the soak's commands (first ${CHECK_S} s) in lockstep: outputs identical to replay ($line)"
  elif [ $rc -eq 0 ]; then
    ok "$name: the soak's commands (first ${CHECK_S} s) in lockstep: outputs identical to replay on the second try ($line; the first: $first)"
  else
    bad "$name: lockstep vs replay (exit $rc, twice): $line $(head -3 "$T/ls.err" | tr '\n' ' ') (first try: $first)"
  fi
  seed=$((seed + 1))
done

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
