#!/usr/bin/env bash
# test_lockstep.sh BUILD -- lockstep co-simulation, inside a private network namespace:
# `afmtwin lockstep --check` drives afmtwind --mode lockstep through a logged sequence of
# ticks and commands (dither, a Z ramp, four tones, a force and a geometry change, pause,
# a tick sent while paused, step, run, reset) and through a log without ticks (ticks made
# from its times). Every completion (tick_done_t: seq, samples, model time, the digests of
# the samples and harmonics messages) must match the outputs received and, bit for bit,
# `afmtwin replay --lockstep` of the same sequence; also a log with scan commands over a
# sample (issue 18), with and without the daemon's own Z loop, and a log that moves that
# loop's reference and lock-in (dither, force, squeeze, damping, reset, step: 7 of 7
# completions identical; with theta accumulated from each slice's first sample, the bug
# ad21b2c fixed, it fails where the 3-completion scan log passes). Re-sent ticks (the same
# seq again: a client whose completion was lost or late): never run twice, the completion
# published again, the status counts them, replay absorbs them. Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_lockstep.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
daemon_test_tmp lockstep

S() { "$A" send "$@" --quiet || bad "send $*"; }

# lockstep_check CONF WHAT LOG N [ALSO]: a lockstep daemon on CONF runs LOG with --check; N of
# N completions identical to replay (and the client's report has ALSO, when given); the
# daemon exits 0 on TERM
lockstep_check() {
  "$D" --config "$1" --mode lockstep --harmonics-every 10 --quiet 2> "$T/d-${2// /_}.err" &
  DPID=$!
  out=$("$A" lockstep --in "$3" --config "$1" --check --harmonics-every 10 2>&1); rc=$?
  echo "$out" | sed 's/^/     /'
  [ $rc -eq 0 ] && echo "$out" | grep -q "$4 of $4 completions identical" &&
    { [ -z "${5:-}" ] || echo "$out" | grep -q -- "$5"; } \
    && ok "$2 in lockstep: $4 completions identical to replay${5:+ ($5)}" \
    || bad "$2 in lockstep (exit $rc)"
  kill -TERM "$DPID"; wait "$DPID"; rc=$?; DPID=""
  [ $rc -eq 0 ] && ok "lockstep daemon ($2) exited 0" || bad "daemon ($2) exit $rc"
}

L="$T/ticks.log"
S dither --freq 338112 --amp 0.087e-9 --seq 1 --log "$L" --log-time 0
S tick --n 14060 --seq 2 --log "$L" --log-time 0.1
S setpoint --z 25e-9 --ramp 1e-3 --seq 3 --log "$L" --log-time 0.2
S tick --n 7000 --seq 4 --log "$L" --log-time 0.3
S dither --freq 338112,2.07e6,1e6,5e5 --amp 0.087e-9,2e-11,1e-11,1e-11 --seq 5 --log "$L" --log-time 0.35
S param forces.viscoelastic.eta_pa_s=600 --seq 6 --log "$L" --log-time 0.4
S param model.beam.length_m=118e-6 --seq 7 --log "$L" --log-time 0.45
S tick --n 9000 --seq 8 --log "$L" --log-time 0.5
S control pause --seq 9 --log "$L" --log-time 0.6
S tick --n 2000 --seq 10 --log "$L" --log-time 0.65
S control step --n 1000 --seq 11 --log "$L" --log-time 0.7
S control run --seq 12 --log "$L" --log-time 0.8
S control reset --seq 13 --log "$L" --log-time 0.85
S tick --n 3000 --seq 14 --log "$L" --log-time 0.9

"$D" --config config/default.conf --mode lockstep --harmonics-every 10 --quiet 2> "$T/d.err" &
DPID=$!
out=$("$A" lockstep --in "$L" --check --harmonics-every 10 2>&1); rc=$?
echo "$out" | sed 's/^/     /'
[ $rc -eq 0 ] && echo "$out" | grep -q "6 of 6 completions identical" \
  && ok "logged ticks: 6 completions (ticks, the paused tick after RUN, the step) identical to replay" \
  || bad "logged ticks (exit $rc)"

# A log without ticks: ticks of 0.5 ms made from its times; the same daemon continues, so
# the check against replay (which starts at 0) is not asked for, the completions are.
M="$T/timed.log"
S setpoint --z 30e-9 --seq 20 --log "$M" --log-time 10
S dither --freq 339000 --amp 0.08e-9 --seq 21 --log "$M" --log-time 10.004
out=$("$A" lockstep --in "$M" --tick-us 500 --tail 0.003 2>&1); rc=$?
echo "$out" | sed 's/^/     /'
[ $rc -eq 0 ] && echo "$out" | grep -q "14 completions" && echo "$out" | grep -q "all matching" \
  && ok "log times -> 14 ticks of 0.5 ms (4 ms + 3 ms tail), outputs matching every completion" \
  || bad "timed log (exit $rc)"
# The completions are on the output channel, for any listener.
listen --channels tick_done --json --count 1 --timeout 5 > "$T/done.json" 2>/dev/null &
lp=$!
sleep 0.5
"$A" send tick --n 100 --seq 30 --quiet
wait $lp
n=$(grep -c '"seq":30' "$T/done.json")
[ "$n" -eq 1 ] && ok "listen prints the completion of a tick sent by hand" || bad "no tick_done seq 30"
# A re-sent tick (the same seq as the last tick received: a client whose completion did not
# come) never runs again: the daemon publishes that completion again, identical but for utime
# and msg_seq, and the model stays where it was (the next tick starts from the same samples).
listen --channels tick_done --json --count 3 --timeout 8 > "$T/dup.json" 2>/dev/null &
lp=$!
sleep 0.5
"$A" send tick --n 100 --seq 31 --quiet
sleep 0.3
"$A" send tick --n 100 --seq 31 --quiet
sleep 0.3
"$A" send tick --n 100 --seq 32 --quiet
wait $lp
strip() { sed -n "$1p" "$T/dup.json" | sed 's/"utime":[0-9]*,//; s/"msg_seq":[0-9]*,//'; }
s31=$(sed -n 1p "$T/dup.json" | sed 's/.*"samples":\([0-9]*\).*/\1/')
s32=$(sed -n 3p "$T/dup.json" | sed 's/.*"samples":\([0-9]*\).*/\1/')
sed 's/^/     /' "$T/dup.json"
[ "$(wc -l < "$T/dup.json")" -eq 3 ] && [ "$(strip 1)" = "$(strip 2)" ] &&
  grep -q '"seq":31' <(strip 2) && grep -q '"seq":32' <(strip 3) && [ -n "$s31" ] &&
  [ "$s32" -eq $((s31 + 100)) ] &&
  ok "a re-sent tick (seq 31 twice): its completion published again, identical; the model did not move (seq 32 at $s31 + 100 samples)" ||
  bad "re-sent tick: completions $(tr '\n' ' ' < "$T/dup.json")"
listen --channels status --json --count 1 --timeout 5 > "$T/st.json" 2>/dev/null
grep -q '"tick_resends":1,' "$T/st.json" && grep -q '"republished":1,' "$T/st.json" &&
  ok "the daemon's status counts it: tick_resends 1, republished 1" ||
  bad "status after a re-sent tick: $(grep -o '"tick_resends":[0-9]*,"republished":[0-9]*' "$T/st.json")"
kill -TERM "$DPID"; wait "$DPID"; rc=$?; DPID=""
[ $rc -eq 0 ] && ok "lockstep daemon exited 0" || bad "daemon exit $rc"

# A log with re-sent ticks (each tick twice, one of them while paused): `afmtwin lockstep`
# sends them as logged; each re-send after its completion brings that completion again (not
# a new one), the one while paused nothing (its tick runs once, after RUN); replay
# --lockstep absorbs them as the daemon does: 4 of 4 completions identical.
R="$T/resent.log"
S dither --freq 338112 --amp 0.087e-9 --seq 71 --log "$R" --log-time 0
S tick --n 14060 --seq 72 --log "$R" --log-time 0.1
S tick --n 14060 --seq 72 --log "$R" --log-time 0.11
S setpoint --z 25e-9 --seq 73 --log "$R" --log-time 0.2
S tick --n 7000 --seq 74 --log "$R" --log-time 0.3
S tick --n 7000 --seq 74 --log "$R" --log-time 0.31
S control pause --seq 75 --log "$R" --log-time 0.4
S tick --n 2000 --seq 76 --log "$R" --log-time 0.5
S tick --n 2000 --seq 76 --log "$R" --log-time 0.51
S control run --seq 77 --log "$R" --log-time 0.6
S tick --n 3000 --seq 78 --log "$R" --log-time 0.7
lockstep_check config/default.conf "a log with re-sent ticks" "$R" 4 " 3 re-sent ticks in the log"

# A daemon that stops answering for a while (SIGSTOP for 1 s in the middle of a run: the
# ticks and re-sends wait in its socket, as when its threads get no CPU): the client re-sends
# after 0.2 s and on, the daemon runs each tick once and absorbs the re-sends (publishing a
# completion again where it had already gone out); all 1004 completions identical to replay
# (harmonics not compared: with 1 ms ticks over this log, completion 158's harmonics differ
# from replay in the last bit of one dissipated_energy_j, with or without the stop: a
# difference of its own, left to its issue; the outputs still match every completion).
"$D" --config config/default.conf --mode lockstep --harmonics-every 10 --quiet 2> "$T/d-s.err" &
DPID=$!
"$A" lockstep --in "$M" --tick-us 1000 --tail 1 --check > "$T/stop.txt" 2>&1 &
cp=$!
sleep 2.5 # the client waits for the daemon's status, then ticks
kill -STOP "$DPID"; sleep 1; kill -CONT "$DPID"
wait $cp; rc=$?
sed 's/^/     /' "$T/stop.txt"
listen --channels status --json --count 1 --timeout 5 > "$T/st2.json" 2>/dev/null
rs=$(grep -o '"tick_resends":[0-9]*' "$T/st2.json" | cut -d: -f2)
[ $rc -eq 0 ] && grep -q "1004 of 1004 completions identical" "$T/stop.txt" &&
  grep -q " [1-9][0-9]* ticks re-sent" "$T/stop.txt" && [ "${rs:-0}" -ge 1 ] &&
  ok "daemon stopped for 1 s mid-run: ticks re-sent, $rs absorbed by the daemon, 1004 of 1004 completions identical to replay" ||
  bad "daemon stopped for 1 s mid-run (exit $rc, daemon tick_resends ${rs:-?})"
kill -TERM "$DPID"; wait "$DPID"; rc=$?; DPID=""
[ $rc -eq 0 ] && ok "lockstep daemon (stopped for 1 s) exited 0" || bad "daemon (stopped) exit $rc"

# Scan commands (issue 18) go through lockstep as the others do: a twin over a 3 nm step
# (tests/step-3nm.conf, test_scan_internal.sh's) rasters a line across the edge and moves the
# tip between ticks; every completion (the harmonics records carry the tip's x, y, true height
# and Z, each that of the sample its period ended on) is bit-identical to replay --lockstep of the same log.
# Then the same log with the daemon's own Z loop (am.control = "internal"): its lock-in takes
# tone 0's phase from the sample index (estimators/afm_phase_gen.h), as the chain does, so the
# daemon's slices and replay's give the same bits (before, with a phase anchored at each
# slice's first sample, 0 of 3 completions were identical, and replay --block 700 differed
# from --block 1024 in the last digits of Z).
cp tests/step-3nm.conf "$T/step.conf"
SC="$T/scan.log"
S tick --n 28120 --seq 41 --log "$SC" --log-time 0 --config "$T/step.conf"
S scan raster --x 150nm --size-x 100nm --pixels 16 --line-rate 50 --seq 42 --log "$SC" \
  --log-time 0.1 --config "$T/step.conf"
S tick --n 70300 --seq 43 --log "$SC" --log-time 0.2 --config "$T/step.conf"
S scan move --x 180nm --y 5nm --speed 1e-5 --seq 44 --log "$SC" --log-time 0.3 --config "$T/step.conf"
S tick --n 42180 --seq 45 --log "$SC" --log-time 0.4 --config "$T/step.conf"
lockstep_check "$T/step.conf" "scan commands" "$SC" 3
{ cat tests/step-3nm.conf
  echo 'am = { control = "internal"; setpoint_ratio = 0.8; ki_hz = 2000.0; };'; } > "$T/am.conf"
lockstep_check "$T/am.conf" "internal Z loop" "$SC" 3
# The internal Z loop under the commands that move its reference or its lock-in: a dither
# that moves tone 0 (its A0 computed off the real-time thread by the daemon and by replay
# alike), a tip-sample force param (no new A0), a squeeze-film and a damping param (new A0
# at the drive in force), a reset (the lock-in starts over), a pause with a step.
AM="$T/am.log"
sed 's/radius_m = 1e-8;/radius_m = 1e-8; squeeze = { model = "linear"; p1_n_s_m2 = 0.0; p2_n_s_m = 1e-9; };/' \
  "$T/am.conf" > "$T/amsq.conf"
C() { S "$@" --log "$AM" --config "$T/amsq.conf"; }
C tick --n 14060 --seq 51 --log-time 0
C dither --freq 300e3 --amp 1.5e-10 --seq 52 --log-time 0.1
C tick --n 21090 --seq 53 --log-time 0.2
C param forces.vdw_contact.hamaker_j=2e-19 --seq 54 --log-time 0.3
C tick --n 7030 --seq 55 --log-time 0.4
C param forces.squeeze.p2_n_s_m=2e-8 --seq 56 --log-time 0.5
C param 'model.quality_factor[0]=120' --seq 57 --log-time 0.55
C tick --n 10000 --seq 58 --log-time 0.6
C control reset --seq 59 --log-time 0.7
C tick --n 7000 --seq 60 --log-time 0.8
C control pause --seq 61 --log-time 0.85
C control step --n 3000 --seq 62 --log-time 0.9
C control run --seq 63 --log-time 0.95
C tick --n 2000 --seq 64 --log-time 1.0
lockstep_check "$T/amsq.conf" "internal Z loop under dither, force, squeeze, damping, reset, step" "$AM" 7
for b in 1024 700; do
  "$A" replay --config "$T/am.conf" --in "$SC" --out "$T/r$b.log" --lockstep --block "$b" \
    --harmonics-every 10 --channels harmonics --quiet || bad "replay --block $b"
  "$A" listen --log "$T/r$b.log" --channels harmonics --json 2>/dev/null | md5sum > "$T/r$b.md5"
done
cmp -s "$T/r1024.md5" "$T/r700.md5" && [ -s "$T/r700.md5" ] &&
  ok "internal Z loop: replay --block 700 and --block 1024 give the same records, bit for bit" ||
  bad "internal Z loop: replay --block 700 differs from --block 1024"

# The accurate scheme's step record carried across the runs the caller splits the samples
# into (afm_rt_evrec.h, rt_ev_start): default.conf tapping at Z 40 nm, every period's record
# (--harmonics-every 1) from replay in blocks of 1024, 14060, 13 and 7 samples, bit for bit.
# Before, a run's first step took its start acceleration from a fresh sum: the dissipated
# energy of a period moved in its last bits with the block (here blocks 13 and 7 differed;
# CI of stop 40: the daemon, whose ring items end where real time has them end, 1 completion
# of 3046 off replay).
TL="$T/tap.log"
S setpoint --z 40e-9 --seq 71 --log "$TL" --log-time 0 --config config/default.conf
S tick --n 42180 --seq 72 --log "$TL" --log-time 0.1 --config config/default.conf
S dither --freq 339000 --amp 0.1e-9 --seq 73 --log "$TL" --log-time 0.2 --config config/default.conf
S tick --n 28120 --seq 74 --log "$TL" --log-time 0.3 --config config/default.conf
for b in 1024 14060 13 7; do
  "$A" replay --config config/default.conf --in "$TL" --out "$T/t$b.log" --lockstep --block "$b" \
    --harmonics-every 1 --channels harmonics --quiet || bad "replay --block $b (tapping)"
  "$A" listen --log "$T/t$b.log" --channels harmonics --json 2>/dev/null | sed 's/"utime":[0-9]*,//' \
    > "$T/t$b.json"
done
nt=$(wc -l < "$T/t1024.json")
same=0
for b in 14060 13 7; do cmp -s "$T/t1024.json" "$T/t$b.json" && same=$((same + 1)); done
[ "$same" -eq 3 ] && [ "$nt" -gt 1000 ] &&
  ok "tapping, every period's record: replay --block 14060, 13 and 7 give --block 1024's $nt records, bit for bit" ||
  bad "tapping: $same of 3 block sizes give --block 1024's $nt records ($(diff "$T/t1024.json" "$T/t7.json" | head -c 300))"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
