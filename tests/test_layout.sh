#!/usr/bin/env bash
# test_layout.sh BUILD -- the LCM layout with LCM's own tools and what the CLI says about it,
# inside a private network namespace: lcm-logger on the output URL (port + 1) records
# harmonics and status and no samples, on the samples URL (port + 2) only samples;
# lcm-logplayer plays a command log into the daemon; every output channel's msg_seq runs
# without gaps; `listen` reports a gap (a log with one message cut out), exits 1 when nothing
# came within --timeout and 0 with a summary on SIGINT and SIGTERM; `send --wait` exits 0 on
# the echo of its seq and 1 with the daemon's reason on a rejection; `send --check` says
# which config it used and refuses to guess one. Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_layout.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
daemon_test_tmp layout
CMD_URL="$LCM_DEFAULT_URL"; OUT_URL=${CMD_URL/:7667/:7668}; SMP_URL=${CMD_URL/:7667/:7669}
jnum() { sed -n "s/.*\"$1\":\([^,}]*\).*/\1/p"; }
# CHANNELS OF LOG: "CHANNEL COUNT" lines (afmtwin listen --log --json)
channels_of() { "$A" listen --log "$1" --json 2>/dev/null | sed -n 's/^{"channel":"\([^"]*\)".*/\1/p' | sort | uniq -c; }

"$D" --config config/default.conf 2>"$T/daemon.err" &
DPID=$!
s=$(listen --channels status --json --count 1 --timeout 5 2>/dev/null)
[ -n "$s" ] && ok "daemon up" || { bad "no status: $(cat "$T/daemon.err")"; echo "$pass passed, $fail failed"; exit 1; }
grep -q "outputs udpm://239.255.76.67:7668.*samples udpm://239.255.76.67:7669" "$T/daemon.err" &&
  ok "the daemon names its three URLs: $(grep -o 'LCM commands.*' "$T/daemon.err" | head -1)" ||
  bad "daemon start line: $(head -2 "$T/daemon.err")"

# --- lcm-logger: outputs and samples on their own ports ----------------------------------
rt=(); chrt -f 90 true 2>/dev/null && rt=(chrt -f 90)
"${rt[@]}" timeout -s INT 1.5 lcm-logger --lcm-url "$OUT_URL" -f "$T/out.lcmlog" >/dev/null 2>&1
"${rt[@]}" timeout -s INT 1.5 lcm-logger --lcm-url "$SMP_URL" -f "$T/smp.lcmlog" >/dev/null 2>&1
co=$(channels_of "$T/out.lcmlog"); cs=$(channels_of "$T/smp.lcmlog")
nh=$(echo "$co" | awk '$2 == "AFMTWIN_HARMONICS" {print $1}'); ns=$(echo "$co" | awk '$2 == "AFMTWIN_STATUS" {print $1}')
echo "$co" | grep -q SAMPLES && bad "the output URL carries samples: $co" ||
  { [ "${nh:-0}" -gt 0 ] && [ "${ns:-0}" -gt 0 ] &&
    ok "lcm-logger on $OUT_URL: $nh harmonics, $ns status, no samples in 1.5 s" || bad "output log: $co"; }
nsm=$(echo "$cs" | awk '$2 == "AFMTWIN_SAMPLES" {print $1}')
[ "$(echo "$cs" | wc -l)" -eq 1 ] && [ "${nsm:-0}" -gt 0 ] &&
  ok "lcm-logger on $SMP_URL: $nsm samples messages, nothing else" || bad "samples log: $cs"
# msg_seq per channel: consecutive in what the logger got (a loss would be a gap)
out=$("$A" listen --log "$T/out.lcmlog" --channels harmonics,status 2>&1 >/dev/null)
echo "$out" | grep -q "; 0 lost" && ok "msg_seq of the logged harmonics and status: no gaps ($out)" ||
  bad "gaps in the logged outputs: $out"

# --- lcm-logplayer: a command log played into the daemon ---------------------------------
"$A" send setpoint --z 31e-9 --seq 77 --log "$T/cmd.lcmlog" --log-time 0 --quiet
"$A" send setpoint --z 32e-9 --seq 78 --log "$T/cmd.lcmlog" --log-time 0.2 --quiet
lcm-logplayer --lcm-url "$CMD_URL" "$T/cmd.lcmlog" >/dev/null 2>&1; rc=$?
sleep 0.4
s=$(listen --channels status --json --count 1 --timeout 3 2>/dev/null)
[ $rc -eq 0 ] && [ "$(echo "$s" | jnum seq_applied)" = 78 ] &&
  awk -v z="$(echo "$s" | jnum separation_m)" 'BEGIN{exit !(z > 31.99e-9 && z < 32.01e-9)}' &&
  ok "lcm-logplayer --lcm-url $CMD_URL: both commands applied (seq 78, Z 32 nm)" ||
  bad "logplayer: exit $rc, status $(echo "$s" | cut -c1-200)"

# --- listen: gaps, timeout, signals ------------------------------------------------------
# A status-only log (equal-size events) with its second event cut out: one message lost.
"$A" replay --config config/default.conf --in "$T/cmd.lcmlog" --out "$T/st.lcmlog" \
  --channels status --tail 0.35 --quiet
n=$("$A" listen --log "$T/st.lcmlog" 2>/dev/null | wc -l); sz=$(stat -c %s "$T/st.lcmlog")
ev=$((sz / n))
{ head -c "$ev" "$T/st.lcmlog"; tail -c +$((2 * ev + 1)) "$T/st.lcmlog"; } > "$T/gap.lcmlog"
out=$("$A" listen --log "$T/gap.lcmlog" 2>&1 >/dev/null); rc=$?
[ $((sz % n)) -eq 0 ] && [ $rc -eq 0 ] && echo "$out" | grep -q "AFMTWIN_STATUS: 1 messages lost (msg_seq 0 -> 2)" &&
  echo "$out" | grep -q "status $((n - 1)) (1 lost in 1 gaps)" &&
  ok "listen reports the gap as it shows and at exit: $(echo "$out" | tr '\n' '|')" ||
  bad "listen on a log with a gap (n $n, size $sz): exit $rc: $out"
out=$("$A" listen --log "$T/st.lcmlog" 2>&1 >/dev/null)
echo "$out" | grep -q "; 0 lost" && ok "... and none in the whole log" || bad "whole log: $out"
t0=$(date +%s%N)
out=$(listen --prefix NOBODY_ --timeout 1 2>&1); rc=$?
ms=$(( ($(date +%s%N) - t0) / 1000000 ))
[ $rc -eq 1 ] && echo "$out" | grep -q "nothing received within 1 s" && [ $ms -lt 10000 ] &&
  ok "listen with nothing arriving: exit 1 after ${ms} ms, '$(echo "$out" | head -1)'" ||
  bad "listen, nothing: exit $rc after $ms ms: $out"
for sig in INT TERM; do
  # exec: $! is listen itself (a background subshell would ignore SIGINT); bounded by --timeout
  ( exec "${rt[@]}" "$A" listen --channels status,harmonics --timeout 20 ) > "$T/l.out" 2> "$T/l.err" &
  lp=$!; sleep 1.5; kill -$sig $lp; wait $lp; rc=$?
  [ $rc -eq 0 ] && grep -q "stopped by a signal" "$T/l.err" && grep -q "messages in .* s: .*status [0-9]" "$T/l.err" &&
    ! grep -q "receive failed" "$T/l.err" && [ -s "$T/l.out" ] &&
    ok "listen on SIG$sig: exit 0 with a summary: $(tail -1 "$T/l.err")" || bad "listen SIG$sig: exit $rc: $(cat "$T/l.err")"
done
# Live: no gaps in 2 s of status and harmonics from the daemon (they never meet the samples)
out=$(listen --channels status,harmonics --timeout 2 2>&1 >/dev/null); rc=$?
echo "$out" | grep -q "; 0 lost" && [ $rc -eq 0 ] && ok "listen live, 2 s: $(echo "$out" | tail -1)" ||
  bad "listen live: exit $rc: $out"

# --- send --wait and --check -------------------------------------------------------------
out=$("$A" send setpoint --z 33e-9 --seq 90 --wait 2>&1); rc=$?
[ $rc -eq 0 ] && echo "$out" | grep -q "applied: the daemon's status echoes seq 90" &&
  ok "send --wait: exit 0 on the echo: $(echo "$out" | tr '\n' '|')" || bad "send --wait: exit $rc: $out"
out=$("$A" send tick --n 100 --seq 91 --wait 2>&1); rc=$?   # valid, but not in realtime mode
[ $rc -eq 1 ] && echo "$out" | grep -q "rejected by the daemon: tick: the daemon runs in realtime mode.*\[seq 91\]" &&
  ok "send --wait of a command the daemon rejects: exit 1, '$(echo "$out" | grep rejected)'" || bad "send --wait tick: exit $rc: $out"
out=$("$A" send setpoint --z -1e-9 --seq 92 --no-check --wait 2>&1); rc=$?
[ $rc -eq 1 ] && echo "$out" | grep -q "rejected by the daemon: AFMTWIN_SETPOINT: .*separation_m -1e-09" &&
  ok "send --no-check --wait of a bad value: exit 1, '$(echo "$out" | grep rejected)'" || bad "send --wait, bad value: exit $rc: $out"
out=$("$A" send setpoint --z 34e-9 --wait --wait-timeout 1 --prefix NOBODY_ 2>&1); rc=$?
[ $rc -eq 1 ] && echo "$out" | grep -q "no status on NOBODY_STATUS within 1 s.*nothing sent" &&
  ok "send --wait without a daemon: exit 1, nothing sent" || bad "send --wait, no daemon: exit $rc: $out"
kill -TERM "$DPID"; wait "$DPID"; DPID=""
# --check outside the repository: the limits of a named config, never a silent guess
A_ABS=$(readlink -f "$A"); C_ABS=$(readlink -f config/default.conf)
out=$(cd /tmp && env -u AFMTWIN_CONFIG "$A_ABS" send dither --freq 7.03e6 --amp 1e-10 --check 2>&1); rc=$?
if [ -e /etc/afmtwin/afmtwind.conf ] || [ -e /usr/local/etc/afmtwin/afmtwind.conf ]; then
  ok "send --check without --config: an installed service config exists here (not tested: $out)"
else
  [ $rc -eq 2 ] && echo "$out" | grep -q "no config to check against" &&
    ok "send --check outside the repo, no config anywhere: exit 2, '$out'" || bad "send --check, no config: exit $rc: $out"
fi
out=$(cd /tmp && env -u AFMTWIN_CONFIG "$A_ABS" send dither --freq 7.03e6 --amp 1e-10 --check --config "$C_ABS" 2>&1); rc=$?
[ $rc -eq 2 ] && echo "$out" | grep -q "half the sample rate" && ok "send --check --config: the daemon's limit ('$out')" ||
  bad "send --check --config, 7.03 MHz: exit $rc: $out"
out=$(cd /tmp && AFMTWIN_CONFIG="$C_ABS" "$A_ABS" send dither --freq 338e3 --amp 1e-10 --check 2>&1); rc=$?
[ $rc -eq 0 ] && [ "$out" = "ok (checked against $C_ABS)" ] && ok "send --check names the config it used: '$out'" ||
  bad "send --check with AFMTWIN_CONFIG: exit $rc: $out"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
