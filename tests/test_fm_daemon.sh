#!/usr/bin/env bash
# test_fm_daemon.sh BUILD -- FM-AFM in the daemon (issue 32), inside a private network
# namespace, on a lumped vdW probe (config/lumped-vdw-fold.conf's, at Z 6 nm, amplitude
# set-point 1 nm):
#  (a) internal control (fm.control = "internal"): the status says "internal" and "locked",
#      and its frequency and frequency shift equal `afmtwin approach --mode fm` at the same Z
#      within 0.01 Hz (both run the accurate scheme: the daemon at --speed 0.25); a dither command
#      is refused with the reason and counted, tone 0 unchanged;
#  (c) (run between a and b) internal control in real time with the NCO stepping every 64
#      samples (update_samples = 64, the fast scheme): realtime_factor_1s median >= 0.95 and
#      >= 0.5 in every second (counted; the strict 0.99 printed), the loops locked;
#  (b) an outside FM controller (examples/fm_pll.c, a PLL and an amplitude PI over LCM,
#      dither commands at $FM_RATE per second, default 1000, for $FM_AFTER wall seconds after
#      its lock, default 5, the daemon at --speed $FM_SPEED, default RT_SPEED of lib_daemon.sh;
#      `make soak` and `make fm-stream` run 10 kHz for 60 s at --speed 1 with FM_RT_CHECK=1; the
#      controller at SCHED_FIFO $FM_CLIENT_PRIO, default 75, below the integrator) locks within 2 s of model time
#      to the twin's shifted resonance (the same shift within 0.5 Hz: the daemon runs the fast
#      scheme in real time), and while it streams the daemon applies every command it sent
#      (none rejected, refused or dropped); with FM_RT_CHECK=1 also no resync and a real-time
#      factor (of the speed) >= 0.99 in every status under the stream. Not by default: on
#      this shared 2-core VM it depends on the other load (1 kHz at --speed 0.5: min 0.990-1.000
#      in 6 of 8 runs, 5 and 51 resyncs in two at load 13-16; 10 kHz at --speed 1 not held at
#      load 8-20; README, FM), so the check is reported as "info". Then (FM_REPLAY=0:
#      not) `afmtwin replay --applied` of the log the daemon wrote (--applied-log: every
#      command at the sample it applied) gives every harmonics record the daemon published,
#      bit for bit (every field but the time stamp and message numbers), whether real time
#      held or not.
# Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_fm_daemon.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
. tests/lib_fm.sh # T, Z, DPID, LPID, LOGPIDS, fm_conf, jget, fm_daemon_up, fm_harm_check, ...
RATE=${FM_RATE:-1000}
AFTER=${FM_AFTER:-5} # wall seconds fm_pll streams after its lock (make soak: 60 at 10 kHz)
SPEED=${FM_SPEED:-$RT_SPEED} # (b): the daemon's --speed (lib_daemon.sh: make test 0.5, soak 1)
REPLAY=${FM_REPLAY:-1} # (b): the daemon logs the commands it applied, replayed (0: not)
url="$LCM_DEFAULT_URL"; out_url=${url/:7667/:7668}
run=(); chrt -f 90 true 2>/dev/null && run=(chrt -f 90)
PARTS=${FM_PARTS:-acb} # which of (a) and (c) to run (make fm-stream: "b", neither); (b) and
                       # (a)'s offline approach, which (b) compares with, always run
PLL_SRC=${FM_PLL_SRC:-examples/fm_pll.c} # (b)'s controller (another build's, to compare)
# (b)'s controller runs SCHED_FIFO $FM_CLIENT_PRIO (default 75): below the integrator (80),
# above the daemon's receive, publish and LCM threads (70) and the output chain (60) at the
# default --rt-priority. Its 1 ms bursts of sends then end before LCM's thread reads them
# all in one wake-up (~1300 a second at 10 kHz; at 50, below LCM's thread, every send woke
# it: ~4700 a second, and the controller starved whenever the twin was behind); at 90 it
# preempted the integrator too (docs/realtime.md, "Command intake"). "" runs it without chrt.
CLIENT_PRIO=${FM_CLIENT_PRIO-75}
client=(); [ -n "$CLIENT_PRIO" ] && chrt -f "$CLIENT_PRIO" true 2>/dev/null &&
  client=(chrt -f "$CLIENT_PRIO")

fm_conf internal > "$T/fm.conf" # the PLL (fm.drive's default)
fm_conf none > "$T/out.conf"

# ---- (a) internal control ------------------------------------------------------------
"$A" approach --config "$T/fm.conf" --mode fm --from $Z --to $Z --step 1e-9 --json \
  > "$T/approach.json" 2> "$T/approach.err"
fa=$(jget "$T/approach.json" frequency_hz); sa=$(jget "$T/approach.json" frequency_shift_hz)
[ -n "$fa" ] && [ "$(jget "$T/approach.json" lock_state)" = locked ] &&
  ok "approach --mode fm at Z 6 nm: locked, f $fa Hz, shift $sa Hz" ||
  bad "approach --mode fm: $(tail -2 "$T/approach.err")"

if [[ $PARTS == *a* ]]; then
# realtime at a quarter speed: the accurate scheme (approach's) and the loops fit the budget
# (freerun would keep both cores busy at SCHED_FIFO and starve this script)
"$D" --config "$T/fm.conf" --speed 0.25 --scheme accurate --quiet 2> "$T/d1.err" & DPID=$!
st=""
for _ in $(seq 1 50); do # up to 10 s: locked (~30 ms of model time)
  sleep 0.2
  listen --channels status --json --count 1 --timeout 3 > "$T/s1.json" 2>/dev/null || continue
  [ "$(jget "$T/s1.json" fm_lock_state)" = locked ] && { st=locked; break; }
done
sleep 0.5 # settled: a few tens of lock times more
listen --channels status --json --count 1 --timeout 3 > "$T/s1.json" 2>/dev/null
fc=$(jget "$T/s1.json" fm_control); fl=$(jget "$T/s1.json" fm_lock_state)
fdr=$(jget "$T/s1.json" fm_drive)
fd=$(jget "$T/s1.json" fm_frequency_hz); sd=$(jget "$T/s1.json" fm_frequency_shift_hz)
ref=$(jget "$T/s1.json" fm_reference_hz); pe=$(jget "$T/s1.json" fm_phase_error_deg)
dr=$(jget "$T/s1.json" fm_drive_amplitude_m)
[ "$st" = locked ] && [ "$fc" = internal ] && [ "$fl" = locked ] && [ "$fdr" = pll ] &&
  ok "internal FM: status fm_control internal, fm_drive pll, locked (phase error $pe deg, drive $dr m, reference $ref Hz)" ||
  bad "internal FM: fm_control '$fc', fm_drive '$fdr', lock '$fl' ($(tail -2 "$T/d1.err"))"
# Tolerance 0.01 Hz (6e-5 of the shift): the same integrator, loops and lock-in as approach;
# what differs is the NCO's 1 mHz resolution, the status being one update against a window's
# mean, and the reference (mode 1's f0 against the frequency locked at Z 1 um: 3e-5 Hz here).
# The fast scheme is 0.23 Hz off: a wrong scheme, reference or loop fails it.
[ -n "$fd" ] && [ -n "$fa" ] &&
  awk -v a="$fd" -v b="$fa" -v c="$sd" -v e="$sa" 'BEGIN{d = a - b; g = c - e;
    exit !(d <= 0.01 && d >= -0.01 && g <= 0.01 && g >= -0.01)}' &&
  ok "daemon's FM: f $fd Hz, shift $sd Hz = approach's $fa Hz, $sa Hz within 0.01 Hz" ||
  bad "daemon's FM: f ${fd:-?} Hz, shift ${sd:-?} Hz; approach $fa Hz, $sa Hz (0.01 Hz)"
# the harmonics records carry the loops too (issue 32): lock state, the shift = the period's
# tone 0 (tones[0], = fe_hz) less the status's reference, the phase error
listen --channels harmonics --json --count 20 --timeout 3 > "$T/h1.jsonl" 2>/dev/null
if fm_harm_check "$T/h1.jsonl" "$ref" "$sd" pll 10 0.01 > "$T/h.out" 2>&1
then ok "harmonics records under internal FM: $(cat "$T/h.out"); locked, shift = tone 0 - reference = the status's within 0.01 Hz"
else bad "harmonics records under internal FM: $(tail -2 "$T/h.out") $(head -c 400 "$T/h1.jsonl")"; fi
# a dither command while the loops own tone 0: refused, counted, nothing changed
fm_dither_refused "$T/fm.conf" "internal FM" "$T/s1.json"
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
[ "$drc" -eq 0 ] && ok "daemon (internal FM) stopped cleanly" || bad "daemon exit $drc"
fi # (a)

if [[ $PARTS == *c* ]]; then
# ---- (c) real time under the internal loops, the NCO at its fastest ----------------------
# update_samples = 64 (a controller update every 4.6 us of model time; tone 0 steps whenever
# the loop's frequency leaves its 1 mHz quantum: thousands of steps a second), in real time
# with the fast scheme, as the daemon runs here. Each step reaches every tone-0 estimator
# (here and in the chain) as an O(1) phase-continuous retune (afm_track_rebase). Measured on
# this 2-core VM at load 9-12 (other sessions' builds and daemons): before, the estimators
# rebuilt their tables thousands of times a second and realtime_factor_1s had a median of
# 0.13-0.39 (min 0.02-0.32, 28-41 resyncs in 5 s); after, a median of 1.000 (min 0.90; 0.35
# with a callgrind run beside it). The guard, as test_collapse's: the median >= 0.95 and
# every second >= 0.5 (a loaded machine dips, the collapse stays far below); the strict level
# (>= 0.99 in every second, no resync) is printed, not counted.
sed 's/amplitude_setpoint_m = 1.0e-9;/amplitude_setpoint_m = 1.0e-9; update_samples = 64;/' \
  "$T/fm.conf" > "$T/fm64.conf"
fm_daemon_up "$T/d3.err" "$T/others3" --config "$T/fm64.conf" --scheme fast
listen --channels status --json --count 40 --timeout 10 > "$T/st3.jsonl" 2>/dev/null
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
python3 - "$T/st3.jsonl" > "$T/rt3.out" <<'EOF'
import json, sys
w = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
if len(w) < 20:
    print("FAIL internal FM, update every 64 samples: %d statuses" % len(w)); sys.exit()
r = sorted(d['realtime_factor_1s'] for d in w)
med, lo = r[len(r) // 2], r[0]
res = w[-1]['resyncs'] - w[0]['resyncs']
dt = w[-1]['model_time_s'] - w[0]['model_time_s']
steps = (w[-1]['fm_tone_changes'] - w[0]['fm_tone_changes']) / dt if dt > 0 else 0
strict = "held" if lo >= 0.99 and res == 0 else "NOT held"
ok = med >= 0.95 and lo >= 0.5 and w[-1]['fm_lock_state'] == 'locked'
print("%s internal FM, update every 64 samples, realtime (%d statuses, %.0f NCO steps per s "
      "of model time, %s): realtime_factor_1s median %.3f min %.3f, resyncs %d; >= 0.95 median, "
      ">= 0.5 every second; strict level (>= 0.99, no resync) %s" %
      ("ok  " if ok else "FAIL", len(w), steps, w[-1]['fm_lock_state'], med, lo, res, strict))
EOF
read -r tag rest < "$T/rt3.out"
if [ "$tag" = ok ]; then ok "$rest"; else
  bad "$rest (other real-time processes: $(cat "$T/others3" 2>/dev/null)-- the FM collapse, or a loaded machine)"; fi
[ "$drc" -eq 0 ] && ok "daemon (internal FM, update 64) stopped cleanly" || bad "daemon exit $drc"
fi # (c)

# ---- (b) the outside controller over LCM ----------------------------------------------
# built as a client builds it, from the message library and headers (test_client.sh builds
# every example from a staged install through pkg-config)
if cc -std=c11 -O2 -Wall -Wextra -Werror -D_POSIX_C_SOURCE=200809L -I"$BUILD/gen" -Imsgtypes \
     -o "$T/fm_pll" "$PLL_SRC" "$BUILD/lib/libafmtwin_msg.a" -llcm -lm 2> "$T/cc.err"; then
  ok "$PLL_SRC builds"
else
  bad "fm_pll build: $(head -3 "$T/cc.err")"; echo "$pass passed, $fail failed"; exit 1
fi
# FM_DAEMON_ARGS: more daemon options (the CPU plan, e.g. "--cpu 1 --chain-cpu 0 --aux-cpu 1");
# FM_SIDE_CPU: the CPUs the controller and the status listener run on (this shell's affinity,
# which they inherit, until the stream's part ends); the loggers too, unless FM_LOGGER_CPU
# names theirs (below)
read -r -a dargs <<< "${FM_DAEMON_ARGS:-}"
applog=(); [ "$REPLAY" = 1 ] && applog=(--applied-log "$T/applied.lcmlog")
fm_daemon_up "$T/d2.err" "$T/others" --config "$T/out.conf" --scheme fast --speed "$SPEED" \
  "${applog[@]}" "${dargs[@]}"
allcpu=$(taskset -p $$ | sed 's/.*: //')
if [ -n "${FM_SIDE_CPU:-}" ]; then taskset -p -c "$FM_SIDE_CPU" $$ > /dev/null; fi
listen --channels status --json --timeout $((AFTER + 10)) > "$T/st.jsonl" 2>/dev/null & LPID=$!
# LCM's logger: the daemon's harmonics (the commands: the daemon's --applied-log), at SCHED_FIFO 1:
# below every thread of the daemon (at 90 the command logger took 25 % of a core above it at
# 10 000 commands/s), above the other sessions' work (a plain logger kept 140 000 of 600 800
# commands at 10 kHz under load), its socket buffer (recv_buf_size, 4 MB) holding the rest.
# Enough at 1000 commands/s (all logged); at 10 000/s, with the daemon behind and taking 1.3
# cores, it kept 344 485 of 584 947 (README, FM).
# FM_LOGGER_PRIO sets another priority (0: SCHED_OTHER, which make fm-stream uses: loggers at
# SCHED_FIFO count against the kernel's real-time throttling, 95 % of each second on a CPU,
# and a full CPU of them stalls every SCHED_FIFO thread there for the rest of the second;
# docs/realtime.md, "Command intake": 74, just below the
# controller, tried at 10 kHz).
LOGGER_PRIO=${FM_LOGGER_PRIO:-1}
logrt=(); [ "$LOGGER_PRIO" -gt 0 ] && chrt -f "$LOGGER_PRIO" true 2>/dev/null && logrt=(chrt -f "$LOGGER_PRIO")
# FM_LOGGER_CPU: the CPUs of the loggers (default: this shell's)
[ -n "${FM_LOGGER_CPU:-}" ] && logrt=(taskset -c "$FM_LOGGER_CPU" "${logrt[@]}")
if [ "$REPLAY" = 1 ]; then
  "${logrt[@]}" lcm-logger -q -f -c AFMTWIN_HARMONICS --lcm-url "$out_url" "$T/harm.lcmlog" &
  LOGPIDS="$!"
fi
sleep 0.3
timeout $((AFTER + 15)) "${client[@]}" "$T/fm_pll" --lcm-url "$url" --lcm-out-url "$out_url" \
  --f0 300e3 --q 2000 --amplitude 1e-9 --rate "$RATE" --seconds 2 --after "$AFTER" \
  > "$T/pll.out" 2>&1; prc=$?
# the daemon's threads' context switches over its life (voluntary: wake-ups), for the record
for f in /proc/"$DPID"/task/*/status; do
  awk '/^Name:/{n=$2} /^voluntary_ctxt/{v=$2} /^nonvoluntary_ctxt/{w=$2} END{printf "%s %s/%s  ", n, v, w}' "$f" 2>/dev/null
done > "$T/ctx.out"; echo >> "$T/ctx.out"
sleep 0.5
kill -TERM "$LPID" 2>/dev/null; wait "$LPID" 2>/dev/null; LPID=""
for p in $LOGPIDS; do kill -INT "$p" 2>/dev/null; wait "$p" 2>/dev/null; done; LOGPIDS=""
sed 's/^/     /' "$T/pll.out" | cut -c1-200
echo "info daemon threads' context switches (voluntary/involuntary), client at ${client[*]:-no chrt}: $(cat "$T/ctx.out")"
lk=$(grep '^locked after' "$T/pll.out")
tl=$(echo "$lk" | sed -n 's/^locked after \([0-9.]*\) s.*/\1/p')
sh=$(echo "$lk" | sed -n 's/.*(\([-+0-9.]*\) Hz from f0).*/\1/p')
[ "$prc" -eq 0 ] && [ -n "$tl" ] && [ -n "$sh" ] && [ -n "$sa" ] &&
  awk -v t="$tl" -v s="$sh" -v a="$sa" 'BEGIN{d = s - a; exit !(t <= 2 && d <= 0.5 && d >= -0.5)}' &&
  ok "fm_pll locks over LCM after $tl s of model time, shift $sh Hz (approach $sa Hz, 0.5 Hz)" ||
  bad "fm_pll: exit $prc, '$lk' (approach shift $sa Hz)"
sent=$(sed -n 's/^sent \([0-9]*\) commands.*/\1/p' "$T/pll.out")
python3 - "$T/st.jsonl" "${sent:-0}" "${FM_RT_CHECK:-0}" "$SPEED" "$T/held" > "$T/acc.out" <<'EOF'
import json, sys
L = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
sent = int(sys.argv[2])
speed = float(sys.argv[4])
SEQ0 = 6000000
# the window under the controller: from the first status after its first command was applied
# to the first that shows its last one
w = [d for d in L if d['seq_applied'] >= SEQ0]
end = next((i for i, d in enumerate(w) if d['seq_applied'] == SEQ0 + sent - 1), None)
if not w or end is None:
    print("FAIL no status shows the controller's last command (seq %d)" % (SEQ0 + sent - 1)); sys.exit()
w = w[:end + 1]
last = w[-1]
rtf = [d['realtime_factor_1s'] / speed for d in w] # of the speed asked for
rs = sorted(rtf)
res = last['resyncs'] - w[0]['resyncs']
acc = (last['applied'], last['received'], last['rejected'], last['refused'], last['dropped'])
okc = acc[0] == sent and acc[1] == sent and acc[2:] == (0, 0, 0) and \
    (last['fm_control'], last['fm_drive']) == ('none', 'none')
okr = res == 0 and min(rtf) >= 0.99
open(sys.argv[5], "w").write("1" if okr else "0")
if not okr and sys.argv[3] != "1":
    okr = None
print("%s applied %d of %d sent (received %d, rejected %d, refused %d, dropped %d; fm_control "
      "%s, fm_drive %s)" % ("ok  " if okc else "FAIL", acc[0], sent, acc[1], acc[2], acc[3],
      acc[4], last['fm_control'], last['fm_drive']) +
      ("; last refusal: %s" % last.get('last_refusal') if acc[3] else ""))
tag = {True: "ok  ", False: "FAIL", None: "info"}[okr]
print("%s under the stream at --speed %g (%d statuses, %.1f s of model time): resyncs %d, "
      "realtime_factor_1s / speed min %.4f median %.4f" %
      (tag, speed, len(w), w[-1]['model_time_s'] - w[0]['model_time_s'], res, min(rtf),
       rs[len(rs) // 2]))
EOF
while read -r tag rest; do
  if [ "$tag" = ok ]; then ok "$rest"; elif [ "$tag" = info ]; then
    echo "info $rest (not counted: set FM_RT_CHECK=1; other real-time processes: $(cat "$T/others" 2>/dev/null))"
  else bad "$rest (other real-time processes: $(cat "$T/others" 2>/dev/null))"; fi
done < "$T/acc.out"
[ -s "$T/acc.out" ] || bad "no statuses under the stream"
taskset -p "$allcpu" $$ > /dev/null
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
[ "$drc" -eq 0 ] && ok "daemon (outside FM) stopped cleanly" || bad "daemon exit $drc"

# ---- (b) replayed: the daemon's log of the commands it applied, through `afmtwin replay` --
# lcm-logger's time stamps are wall time at reception, and the daemon applies a command at its
# next ring item (later while the output chain is behind): a replay by those times matched the
# daemon's records only to ~1e-11 of the lock-in amplitude under the stream. The daemon's own
# --applied-log stamps each command with the sample it applied at (and the scheme in force),
# and `afmtwin replay --applied` applies it there: every harmonics record the daemon published
# (as lcm-logger caught them) must come out of the replay with the same period start t_s and
# every other field equal to the bit (utime, seq_applied and msg_seq aside: when a record was
# handed out, not what it says), at least 99 % of them found (the replay runs to the daemon's
# last sample, on the daemon's default harmonics cadence). Real time held or not: the log
# says where each command went.
if [ "$REPLAY" = 1 ]; then
  grep -q "^afmtwind: --applied-log .*: [0-9]* events (the commands" "$T/d2.err" &&
    ok "the daemon's applied log: $(sed -n 's/^afmtwind: --applied-log [^:]*: //p' "$T/d2.err")" ||
    bad "the daemon's applied log: $(grep -e '--applied-log' "$T/d2.err" | head -2)"
  "$A" replay --config "$T/out.conf" --in "$T/applied.lcmlog" --applied --out "$T/rp.lcmlog" \
    --tail 0 --channels harmonics 2> "$T/rp.err" ||
    bad "replay --applied of the daemon's log: $(tail -2 "$T/rp.err")"
  "$A" listen --log "$T/harm.lcmlog" --channels harmonics --json > "$T/dh.jsonl" 2>/dev/null
  "$A" listen --log "$T/rp.lcmlog" --channels harmonics --json > "$T/rh.jsonl" 2>/dev/null
  applied=$(sed -n 's/.*: \([0-9]*\) commands applied, \([0-9]*\) rejected.*/\1 \2/p' "$T/rp.err")
  what="replay --applied (${applied/ / commands applied, } rejected; ${sent:-0} sent by the controller)"
  if res=$(python3 tests/harm_identical.py "$T/dh.jsonl" "$T/rh.jsonl"); then
    ok "$what: $res"
  else
    bad "$what: ${res:-no comparison}"
  fi
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
