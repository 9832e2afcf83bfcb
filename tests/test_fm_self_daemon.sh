#!/usr/bin/env bash
# test_fm_self_daemon.sh BUILD -- the self-excited FM drive in the daemon (issue 32:
# fm.control = "internal", fm.drive = "self"), inside a private network namespace, on the
# lumped vdW probe of test_fm_daemon.sh (Z 6 nm, amplitude set-point 1 nm). Why its own file:
# test_fm_daemon.sh is the PLL's and already runs three daemons; this one checks that the
# daemon runs the self drive as `afmtwin approach --mode fm --fm-drive self` runs it offline:
#  (a) lockstep (afmtwind --mode lockstep driven by `afmtwin lockstep --bench`, the accurate
#      scheme, as approach): the status says "internal" and "locked", and the frequency shift,
#      the mean of the statuses after 0.1 s of model time (each one controller update's
#      counted frequency), equals approach's at that Z within 0.005 Hz; the harmonics records
#      carry the drive (locked, shift = their own tone 0 less the reference, phase error
#      ~0);
#  (b) real time at --speed RT_SPEED (lib_daemon.sh: 0.5 on this 2-core machine kind) with
#      tone 0 re-synthesised (a phase jump) every update: realtime_factor_1s of the speed asked
#      for >= 0.9 in every status over 20 and no resync, still locked; a dither command is
#      refused with the reason and counted, as under the PLL.
# Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_fm_self_daemon.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
. tests/lib_fm.sh # T, Z, DPID, LPID, fm_conf, jget, fm_self_reference, fm_daemon_up, ...
run=(); chrt -f 90 true 2>/dev/null && run=(chrt -f 90)
fm_conf internal self > "$T/self.conf"

# ---- the offline reference ---------------------------------------------------------------
fm_self_reference "$T/self.conf"

# ---- (a) lockstep: the same samples as approach ------------------------------------------
"$D" --config "$T/self.conf" --mode lockstep --scheme accurate --quiet 2> "$T/d1.err" & DPID=$!
sleep 1
# statuses until 7 s from here: the 4 s of ticks and after (it ends by itself: a killed listener
# may lose what it has not written)
listen --channels status --json --timeout 7 > "$T/st1.jsonl" 2>/dev/null & LPID=$!
# harmonics records from 2 s of wall time on (locked long before: ~30 ms of model time)
(sleep 2; listen --channels harmonics --json --count 40 --timeout 3 > "$T/h1.jsonl" 2>/dev/null) &
HPID=$!
"$A" lockstep --bench 4 --tick-us 1000 --json > "$T/bench.json" 2> "$T/bench.err"
wait "$HPID"
wait "$LPID" 2>/dev/null; LPID=""
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
mm=$(python3 -c "import json; print(json.load(open('$T/bench.json'))['mismatched'])" 2>/dev/null)
[ "$mm" = 0 ] && [ "$drc" -eq 0 ] && ok "lockstep: 4 s of ticks, none mismatched, daemon stopped cleanly" ||
  bad "lockstep: mismatched '$mm', daemon exit $drc ($(tail -2 "$T/bench.err" "$T/d1.err"))"
# Tolerance 0.005 Hz (3e-5 of the shift) on the mean: each status is one update's counted
# frequency, low-passed at fm.pll_bandwidth_hz (100 Hz: statuses ~50 ms of model time apart
# are independent), scattered by 0.004 Hz (measured), so the mean of >= 20 is good to
# ~0.001 Hz; approach's is a window's mean, and both run the same integrator, lock-in and
# delay line on the same sample grid. A delay line one sample off is ~10 Hz off (7.7 deg of
# phase on a slope of 0.76 deg/Hz); the PLL instead of the self drive is 0.02 Hz off.
if python3 - "$T/st1.jsonl" "$sa" > "$T/a.out" 2>&1 <<'PY'
import json, statistics, sys
L = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
sa = float(sys.argv[2])
by_t = {d["model_time_s"]: d for d in L if d["model_time_s"] > 0.1}
v = [d["fm_frequency_shift_hz"] for d in by_t.values()]
last = L[-1]
assert len(v) >= 20, "%d statuses after 0.1 s of model time" % len(v)
assert last["fm_control"] == "internal" and last["fm_lock_state"] == "locked" and \
    last["fm_drive"] == "self", (last["fm_control"], last["fm_lock_state"], last["fm_drive"])
assert all(d["fm_lock_state"] == "locked" for d in by_t.values())
m = statistics.mean(v)
print("%d statuses to %.2f s of model time: locked, fm_drive self, shift %.5f Hz (sd %.4f), approach %.5f Hz, "
      "difference %.1e Hz; phase error %.1e deg, drive %.4e m, reference %.3f Hz" %
      (len(v), last["model_time_s"], m, statistics.pstdev(v), sa, m - sa,
       last["fm_phase_error_deg"], last["fm_drive_amplitude_m"], last["fm_reference_hz"]))
assert abs(m - sa) <= 0.005, (m, sa)
PY
then ok "lockstep self drive: $(cat "$T/a.out") (0.005 Hz)"
else bad "lockstep self drive: $(tail -3 "$T/a.out")"; fi
ref=$(jget "$T/st1.jsonl" fm_reference_hz)
# the shift within 0.02 Hz: one update's count, 5 sd of its scatter (0.004 Hz)
if fm_harm_check "$T/h1.jsonl" "$ref" "$sa" self 20 0.02 > "$T/h.out" 2>&1
then ok "harmonics records under the self drive: $(cat "$T/h.out"); shift = tone 0 - reference, within 0.02 Hz of approach's"
else bad "harmonics records under the self drive: $(tail -2 "$T/h.out") $(head -c 300 "$T/h1.jsonl")"; fi

# ---- (b) real time, tone 0 re-synthesised every update --------------------------------------
fm_daemon_up "$T/d2.err" "$T/others" --config "$T/self.conf" --speed "$RT_SPEED"
listen --channels status --json --count 20 --timeout 10 > "$T/st2.jsonl" 2>/dev/null
python3 - "$T/st2.jsonl" "$RT_SPEED" > "$T/rt.out" <<'PY'
import json, sys
w = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
speed = float(sys.argv[2])
if len(w) < 15:
    print("FAIL self drive in real time: %d statuses" % len(w)); sys.exit()
r = [d["realtime_factor_1s"] / speed for d in w]
res = w[-1]["resyncs"] - w[0]["resyncs"]
dt = w[-1]["model_time_s"] - w[0]["model_time_s"]
ch = (w[-1]["fm_tone_changes"] - w[0]["fm_tone_changes"]) / dt if dt > 0 else 0
ok = min(r) >= 0.9 and res == 0 and w[-1]["fm_lock_state"] == "locked"
print("%s self drive in real time (--speed %g, %d statuses, %.0f tone-0 re-syntheses per s of "
      "model time, %s, shift %.3f Hz): real-time factor of the speed asked for min %.3f, "
      "resyncs %d; >= 0.9 in every status, no resync" %
      ("ok  " if ok else "FAIL", speed, len(w), ch, w[-1]["fm_lock_state"],
       w[-1]["fm_frequency_shift_hz"], min(r), res))
PY
read -r tag rest < "$T/rt.out"
if [ "$tag" = ok ]; then ok "$rest"; else
  bad "$rest (other real-time processes: $(cat "$T/others" 2>/dev/null); load $(cut -d' ' -f1-3 /proc/loadavg))"; fi
# a dither command while the self drive owns tone 0: refused, counted, nothing changed
listen --channels status --json --count 1 --timeout 3 > "$T/s1.json" 2>/dev/null
fm_dither_refused "$T/self.conf" "the self drive" "$T/s1.json"
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
[ "$drc" -eq 0 ] && ok "daemon (self drive, real time) stopped cleanly" || bad "daemon exit $drc"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
