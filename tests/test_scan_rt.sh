#!/usr/bin/env bash
# test_scan_rt.sh BUILD -- an outside controller images a sample in real time on the thesis's
# cantilever (issue 18): tests/step-3nm-thesis.conf is config/default.conf's beam (3 kept
# modes, squeeze film, viscoelastic sapphire) tapping over a 3 nm step at x = 200 nm (edge
# 20 nm wide); tests/scan_client.c (a PI on each period's lock-in amplitude acting on Z, as
# examples/hil_pi.c, set-point 0.8 A0) steps the tip across it with scan_t at 0.1 um/s (2 s of
# model time) over LCM.
#  (a) the image: the step height the controller recovers (its Z on the upper plateau less on
#      the lower one) is the true 3 nm within 2 % (lib_scan.sh's judge: the loop holds
#      Z - z_s at the same amplitude on both plateaus, same material, so what remains is its
#      settling after the edge and the records' OBD noise), and its Z - z_s on the plateaus
#      spreads less than 0.1 nm;
#  (b) real time under the scan: realtime_factor_1s / speed >= 0.99 in every status from 1 s
#      in, no resync: asserted with SCAN_RT_CHECK=1 (make soak: --speed 1, the CPU plan
#      below), printed as info otherwise (make test: --speed 0.5 beside the other tests);
#  (c) the daemon's scheme (--scheme auto: at 1x the fast one here) and a clean stop;
#  (d) the image against the offline one (`afmtwin scan` of the same line, its PI with the same
#      gains, trace at 1 um/s): step heights within 0.05 nm, and each plateau's Z within
#      0.2 nm = 0.5 % of the 40 nm set-point amplitude. The controller reads the published
#      lock-in amplitude of the OBD signal, with the base motion in it (Ae cos(lag), 0.047 nm
#      at the 57 deg lag here), and takes A0 from it at Z = 1 um; the offline PI reads the
#      deflection's: the daemon's Z stands ~0.06 nm higher (0.057 nm measured at 0.5x with the
#      accurate scheme, 0.063 at 1x with the fast one; the schemes' steady amplitudes differ by
#      up to 2.3e-3 relative, 0.09 nm here).
# SCAN_SPEED (default 0.5), SCAN_RT_CHECK (default 0), SCAN_DAEMON_ARGS (e.g. the CPU plan
# "--cpu 0 --chain-cpu 1 --aux-cpu 1": the integrator alone on CPU 0), SCAN_SIDE_CPU (the CPUs
# this script, the listener and the client run on). Prints "N passed, N failed".
BUILD=${1:-build}
SPEED=${SCAN_SPEED:-0.5}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
. tests/lib_scan.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_scan_rt.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
daemon_test_tmp scanrt
url="$LCM_DEFAULT_URL"; out_url=${url/:7667/:7668}
run=(); chrt -f 90 true 2>/dev/null && run=(chrt -f 90)
CONF=tests/step-3nm-thesis.conf
H=3e-9; POS=2e-7; EDGE=2e-8 # the step of $CONF (judge reads these)

scan_client_build "$BUILD" "$T/scan_client" || exit 1

read -r -a dargs <<< "${SCAN_DAEMON_ARGS:-}"
"$D" --config "$CONF" --speed "$SPEED" --quiet "${dargs[@]}" 2> "$T/d.err" & DPID=$!
if [ -n "${SCAN_SIDE_CPU:-}" ]; then taskset -p -c "$SCAN_SIDE_CPU" $$ > /dev/null; fi
listen --channels status --json --count 1 --timeout 5 > /dev/null 2>&1 # up
listen --channels status --json --timeout 60 > "$T/st.jsonl" 2>/dev/null & LPID=$!
timeout 120 "${run[@]}" "$T/scan_client" image --lcm-url "$url" --lcm-out-url "$out_url" \
  --from 1e-7 --to 3e-7 --speed 1e-7 --ratio 0.8 --kp 0.2 --ki 300 --engage 0.1 --dwell 0.05 \
  --out "$T/img.dat" > "$T/img.out" 2>&1; irc=$?
kill -TERM "$LPID" 2>/dev/null; wait "$LPID" 2>/dev/null
sed 's/^/     /' "$T/img.out"

judge "$T/img.dat" > "$T/a.out"
read -r tag rest < "$T/a.out"
sp=$(echo "$rest" | sed -n 's/.*spread \([0-9.e+-]*\) nm.*/\1/p')
[ "$irc" -eq 0 ] && [ "$tag" = ok ] && python3 -c "import sys; sys.exit(not ${sp:-9} < 0.1)" &&
  ok "(a) outside PI images the 3 nm step on the thesis cantilever: $rest" ||
  bad "(a) outside PI: exit $irc, $rest"

rt_judge "$T/st.jsonl" "${SCAN_RT_CHECK:-0}" "$SPEED" > "$T/b.out"
read -r tag rest < "$T/b.out"
case "$tag" in
  ok) ok "(b) speed $SPEED: $rest" ;;
  info) echo "info (b) speed $SPEED: $rest (not counted: SCAN_RT_CHECK=1 asserts it)" ;;
  *) bad "(b) speed $SPEED: $rest" ;;
esac

sch=$(python3 -c "import json
L=[json.loads(l) for l in open('$T/st.jsonl') if l.strip()]
print(L[-1].get('rt_scheme', '?') if L else '?', '|', L[-1].get('rt_scheme_reason', '') if L else '')")
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
[ "$drc" -eq 0 ] && ok "(c) daemon stopped cleanly; it ran the ${sch%% |*} scheme (${sch#*| })" ||
  bad "(c) daemon exit $drc ($(tail -2 "$T/d.err"))"

"$A" scan --config "$CONF" --x0 1e-7 --size-x 2e-7 --pixels 40 --line-rate 2.5 --kp 0.2 --ki 300 \
  --json > "$T/off.jsonl" 2> "$T/off.err"; orc=$?
cmp_out=$(python3 - "$T/img.dat" "$T/off.jsonl" <<'EOF'
import json, sys
R = [list(map(float, l.split())) for l in open(sys.argv[1]) if l.strip()]
L = [json.loads(l) for l in open(sys.argv[2]) if l.strip()]
tr = [d for d in L if not d.get('retrace')]
def mean(v): return sum(v) / len(v) if v else float('nan')
def on(x, a, b): return a <= x <= b
dlo = mean([r[4] for r in R if on(r[1], 1.1e-7, 1.7e-7)]); dhi = mean([r[4] for r in R if on(r[1], 2.4e-7, 3.0e-7)])
olo = mean([d['z_m'] for d in tr if on(d['x_m'], 1.1e-7, 1.7e-7)]); ohi = mean([d['z_m'] for d in tr if on(d['x_m'], 2.4e-7, 3.0e-7)])
ds, os_ = dhi - dlo, ohi - olo
good = abs(ds - os_) <= 0.05e-9 and abs(dlo - olo) <= 0.2e-9 and abs(dhi - ohi) <= 0.2e-9
print("%s daemon step %.4f nm, offline %.4f nm; plateau Z %.4f / %.4f nm daemon, %.4f / %.4f nm offline" %
      ("ok" if good else "FAIL", ds * 1e9, os_ * 1e9, dlo * 1e9, dhi * 1e9, olo * 1e9, ohi * 1e9))
EOF
)
[ "$orc" -eq 0 ] && [ "${cmp_out%% *}" = ok ] &&
  ok "(d) the controller's image against afmtwin scan's offline one: ${cmp_out#ok }" ||
  bad "(d) against the offline scan: exit $orc, $cmp_out $(head -2 "$T/off.err")"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
