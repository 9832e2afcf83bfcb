#!/usr/bin/env bash
# test_scheme.sh BUILD -- which rt scheme the daemon runs (issue 28), inside a private network
# namespace: --scheme is checked; auto measures both schemes before real time starts and says
# what it picked and why (start-up line and status); a forced scheme is reported as forced;
# and --scheme adaptive on nchv.conf, where the accurate scheme cannot keep real time while
# tapping here (~300 ns per sample against 71 ns: docs/realtime.md), hands over to the fast
# scheme without a resync, then, retracted (free: the fast scheme ~30 % busy), goes back to
# the accurate one; the status counts the hand-overs and the model time of each scheme, and
# harmonic 1 carries on record by record across the hand-over back (no jump, no gap).
# The hand-over back depends on the machine's speed only through "the fast scheme free uses
# under 60 % of a core", which holds with a wide margin on any machine that runs the twin.
# The adaptive run's speed puts the budget at 3/4 of the accurate scheme's worst-state cost as
# auto measures it here (capped at 1x); on a machine where the accurate scheme keeps real time
# at 1x (issue 29 reached) the hand-over is reported as not exercised.
# Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_scheme.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
T=$(mktemp -d /tmp/afmtwin-scheme.XXXXXX)
DPID=""; LPID=""
cleanup() {
  for p in $DPID $LPID; do kill -KILL "$p" 2>/dev/null; done
  rm -rf "$T"
}
trap cleanup EXIT

# KEY FILE: the last value of a JSON key in FILE's last line
jkey() { tail -n 1 "$2" | grep -o "\"$1\":[^,}]*" | tail -n 1 | sed 's/^[^:]*://; s/"//g'; }

"$D" --config config/default.conf --scheme bogus > "$T/o" 2>&1; rc=$?
[ $rc -eq 2 ] && grep -q "afmtwind: --scheme wants one of auto, adaptive, accurate, fast, got 'bogus'" "$T/o" \
  && ok "--scheme bogus: exit 2 with the choices" || bad "--scheme bogus: exit $rc: $(cat "$T/o")"
"$D" --help | grep -q -- "--scheme S" && ok "--help describes --scheme" || bad "--help: no --scheme"

# auto (the default): both measured, the pick and the figures said at start and in the status
"$D" --config config/default.conf --quiet --exit-after 2.5 2> "$T/auto.err" &
DPID=$!
sleep 1.5
listen --channels status --json --count 1 --timeout 3 > "$T/auto.json" 2>/dev/null
wait "$DPID"; rc=$?; DPID=""
line=$(grep "rt scheme" "$T/auto.err")
if [ $rc -eq 0 ] && echo "$line" | grep -Eq "rt scheme (accurate|fast) \(--scheme config: sim.rt_scheme auto\): auto: accurate [0-9]+ ns/sample in its worst state (<=|>) [0-9]+ ns .*fast [0-9]+ ns"; then
  ok "auto: start-up line names the pick and both costs ($line)"
  echo "$line" | grep -Eq "ns \(90% of [0-9.]+ ns\) with(out)? the step record" \
    && ok "auto: the accurate scheme measured with the per-step record (sim.step_events auto)" \
    || bad "auto: the start-up line does not say how the step record was measured"
else
  bad "auto: exit $rc, start-up line '$line'"
fi
pick=$(echo "$line" | sed 's/.*rt scheme \([a-z]*\).*/\1/')
[ "$(jkey rt_scheme "$T/auto.json")" = "$pick" ] \
  && grep -q '"rt_scheme_reason":"auto: accurate' "$T/auto.json" \
  && ok "auto: the status says $pick and why" || bad "auto: status $(cat "$T/auto.json")"

# forced fast
"$D" --config config/default.conf --quiet --scheme fast --exit-after 2 2> "$T/fast.err" &
DPID=$!
sleep 1.2
listen --channels status --json --count 1 --timeout 3 > "$T/fast.json" 2>/dev/null
wait "$DPID"; DPID=""
grep -q "rt scheme fast (--scheme fast): forced (--scheme)" "$T/fast.err" \
  && [ "$(jkey rt_scheme "$T/fast.json")" = fast ] && [ "$(jkey scheme_handovers "$T/fast.json")" = 0 ] \
  && ok "--scheme fast: forced, no hand-over" || bad "--scheme fast: $(cat "$T/fast.err") $(cat "$T/fast.json")"

# no --scheme, the config's sim.rt_scheme fast: the line says where the choice came from
sed 's/integrator = "rt";/integrator = "rt"; rt_scheme = "fast";/' config/default.conf > "$T/cfast.conf"
"$D" --config "$T/cfast.conf" --quiet --exit-after 0.2 2> "$T/cfast.err"
grep -q "rt scheme fast (--scheme config: sim.rt_scheme fast): forced (config sim.rt_scheme)" "$T/cfast.err" \
  && ok "no --scheme: the start-up line names the config's sim.rt_scheme" \
  || bad "config sim.rt_scheme fast: $(grep 'rt scheme' "$T/cfast.err") ($(grep -c 'rt_scheme = "fast"' "$T/cfast.conf") edits)"

# adaptive: over to fast while tapping, back to accurate when free, no resync.
# The speed: the accurate scheme must fall behind while tapping, so the budget (71.1 ns / speed)
# is set to 3/4 of its worst-state cost as auto measures it on nchv.conf on this machine, now
# (the fast scheme then uses about half the budget: it costs ~1/3 of the accurate one). A fixed
# --speed 0.5 stopped exercising the hand-over once the accurate scheme got faster: the CI
# machine kept real time at 0.5x with it (stop 43's CI: no hand-over, 4 failures).
"$D" --config config/nchv.conf --quiet --exit-after 0.2 2> "$T/nauto.err"
acc_ns=$(sed -n 's/.*auto: accurate [0-9]* ns.* (\([0-9]*\) ns with it).*/\1/p; t; s/.*auto: accurate \([0-9]*\) ns\/sample.*/\1/p' "$T/nauto.err" | head -n 1)
AD_SPEED=$(awk -v a="${acc_ns:-0}" 'BEGIN { s = (a > 0) ? 71.1 / (0.75 * a) : 0.5;
  if (s > 1) s = 1; if (s < 0.25) s = 0.25; printf "%.2f", s }')
echo "     adaptive run at --speed $AD_SPEED (accurate scheme's worst state ${acc_ns:-?} ns/sample here)"
"$D" --config config/nchv.conf --quiet --scheme adaptive --speed "$AD_SPEED" 2> "$T/ad.err" &
DPID=$!
listen --channels status,harmonics --json --timeout 20 > "$T/adh.json" 2>/dev/null &
LPID=$!
sleep 3
"$A" send setpoint --z 1e-6 --quiet --config config/nchv.conf
sleep 7
kill "$LPID" 2>/dev/null; wait "$LPID" 2>/dev/null; LPID=""
kill -TERM "$DPID"; wait "$DPID"; rc=$?; DPID=""
grep '"channel":"AFMTWIN_STATUS"' "$T/adh.json" > "$T/ad.json"
[ $rc -eq 0 ] && ok "adaptive: daemon ran and exited 0" || bad "adaptive: exit $rc"
# the status after the first hand-over (tapping) and the last one
first_fast=$(grep -m1 '"rt_scheme":"fast"' "$T/ad.json")
exercised=1
if [ -z "$first_fast" ] && [ "$AD_SPEED" = "1.00" ]; then
  exercised=0
  ok "adaptive: the accurate scheme kept real time at 1x while tapping (worst state ${acc_ns:-?} ns): hand-over NOT exercised here"
fi
[ $exercised -eq 0 ] || [ -n "$first_fast" ] && echo "$first_fast" | grep -q '"rt_scheme_reason":"overload: lag' \
  && ok "adaptive: handed over to fast while tapping, reason overload" \
  || bad "adaptive: no hand-over to fast: $(head -c 600 "$T/ad.json")"
h=$(jkey scheme_handovers "$T/ad.json"); r=$(jkey resyncs "$T/ad.json")
ma=$(jkey model_s_accurate "$T/ad.json"); mf=$(jkey model_s_fast "$T/ad.json")
back=$(grep -c '"rt_scheme_reason":"margin back' "$T/ad.json")
if [ $exercised -eq 0 ] || { [ "${h:-0}" -ge 2 ] && [ "$back" -ge 1 ]; }; then
  ok "adaptive: back to accurate once free ($h hand-overs; model time accurate $ma s, fast $mf s)"
else
  bad "adaptive: $h hand-overs, no return to accurate: $(tail -n 1 "$T/ad.json")"
fi
# No resync is the design (the hand-over comes at a quarter of --max-lag-ms); as in
# test_collapse.sh, a machine loaded by other work can stall any scheme for 100 ms now and
# then (seen with the load average at 6 on two cores, in the fast scheme too): fail above one.
if [ "${r:-2}" -eq 0 ]; then
  ok "adaptive: no resync across the hand-overs"
elif [ "${r:-2}" -le 1 ]; then
  ok "adaptive: $r resync (strict level, none, NOT held: a loaded machine, or a regression)"
else
  bad "adaptive: $r resyncs"
fi
[ $exercised -eq 0 ] || awk -v a="$ma" -v f="$mf" 'BEGIN{exit !(a > 0 && f > 0)}' \
  && ok "adaptive: the status splits model time between the schemes" \
  || bad "adaptive: model time accurate '$ma' fast '$mf'"
# the outputs carry on across the hand-overs: every status has a finite lock-in amplitude
nonfinite=$(grep -c '"lockin_amplitude_m":null' "$T/ad.json")
n=$(wc -l < "$T/ad.json")
[ "$n" -gt 50 ] && [ "$nonfinite" -le 2 ] \
  && ok "adaptive: lock-in amplitude in $((n - nonfinite)) of $n statuses" \
  || bad "adaptive: $nonfinite of $n statuses without a lock-in amplitude"
# Continuity across the hand-overs, record by record: retracted (free), the lever's harmonic 1
# (one period every ~1 ms) moves only as the schemes' steady states differ. Measured here
# (nchv.conf, squeeze film on, 233 nm free): 1.8e-4 relative per record at each hand-over
# (the two schemes' free orbits with the film, relaxing over ~Q/pi = 134 periods), 1.8e-5
# between them, lag 0.0001 deg. Bound 1e-3 and 0.01 deg: a jump of the state (a reset, a
# resync, a lost or repeated block) moves harmonic 1 by far more; and no gap in model time.
tz=$(grep '"separation_m":1e-06' "$T/ad.json" | head -n 1 | grep -o '"model_time_s":[^,]*' | cut -d: -f2)
# the first hand-over back after the retract (at half speed one may come while tapping too)
hb=$(grep '"rt_scheme_reason":"margin back' "$T/ad.json" | grep -o '"model_time_s":[^,]*' | cut -d: -f2 \
  | awk -v t0="${tz:-1e9}" '$1 > t0 + 1.0 { print; exit }')
grep '"channel":"AFMTWIN_HARMONICS"' "$T/adh.json" \
  | sed 's/.*"msg_seq":\([0-9]*\).*"t_s":\([^,]*\).*"deflection_amplitude_m":\[\([^,]*\).*"deflection_lag_deg":\[\([^,]*\).*/\1 \2 \3 \4/' \
  > "$T/h.txt"
read -r nh da dl gap <<< "$(awk -v t0="${tz:-1e9}" '$2 > t0 + 1.0 {
    if (n && $1 == ps + 1) { a = ($3 - pa) / pa; if (a < 0) a = -a; if (a > da) da = a
      l = $4 - pl; if (l < 0) l = -l; if (l > dl) dl = l
      g = $2 - pt; if (g > gap) gap = g }
    n++; ps = $1; pt = $2; pa = $3; pl = $4 }
  END { printf "%d %.3e %.5f %.6f\n", n, da, dl, gap }' "$T/h.txt")"
if [ $exercised -eq 0 ]; then
  :
elif [ -n "$tz" ] && [ -n "$hb" ] && awk -v h="$hb" -v t="$tz" 'BEGIN{exit !(h > t + 1.0)}' \
   && [ "$nh" -gt 1000 ]; then
  awk -v a="$da" -v l="$dl" -v g="$gap" 'BEGIN{exit !(a <= 1e-3 && l <= 0.01 && g < 0.002)}' \
    && ok "adaptive: harmonic 1 continuous across the hand-over back (at $hb s; $nh records from $tz + 1 s: max change $da relative, $dl deg, longest step $gap s)" \
    || bad "adaptive: harmonic 1 jumps: max change $da relative, $dl deg, longest step $gap s ($nh records)"
else
  bad "adaptive: no hand-over back in the free records to check (retract at ${tz:-?} s, back at ${hb:-?} s, $nh records)"
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
