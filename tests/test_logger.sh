#!/usr/bin/env bash
# test_logger.sh BUILD -- README's recording recipe works as written on two cores (issue
# 30): inside a private network namespace, a realtime afmtwind on default.conf, and the two
# lcm-logger lines of README ("LCM layout") run exactly as README writes them for 5 s; every
# message the daemon published on a channel between the first and the last one logged
# (msg_seq numbers them per channel from 0) must be in the log: `afmtwin listen --log`
# counts the gaps. Plain lcm-logger lost 18-1594 of ~9800 sample messages per run here.
# And the sample streams' rate and low-pass, on the daemon's start-up and in the messages.
# Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_logger.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
T=$(mktemp -d /tmp/afmtwin-logger.XXXXXX)
DPID=""
LPIDS=""
cleanup() {
  for p in $LPIDS; do kill -KILL "$p" 2>/dev/null; done
  [ -n "$DPID" ] && kill -KILL "$DPID" 2>/dev/null
  rm -rf "$T"
}
trap cleanup EXIT

# README's two lcm-logger lines, as written (their comment cut off)
# (AFMTWIN_README: another README, e.g. an older one, to see this test fail on it)
recipe=$(grep -E '^    (chrt [^#]*)?lcm-logger ' "${AFMTWIN_README:-README.md}" | sed 's/ *#.*$//; s/^ *//')
n=$(echo "$recipe" | grep -c 'lcm-logger')
[ "$n" -eq 2 ] && echo "$recipe" | grep -q 'outputs.lcmlog$' && echo "$recipe" | grep -q 'samples.lcmlog$' &&
  ok "README's recipe: two lcm-logger lines ($(echo "$recipe" | head -1 | cut -c1-70)...)" ||
  { bad "README's recipe: $n lcm-logger lines: $recipe"; echo "$pass passed, $fail failed"; exit 1; }

"$D" --config config/default.conf 2>"$T/daemon.err" &
DPID=$!
s=$(listen --channels status --json --count 1 --timeout 5 2>/dev/null)
[ -n "$s" ] && ok "daemon up (realtime, default.conf)" ||
  { bad "no status: $(cat "$T/daemon.err")"; echo "$pass passed, $fail failed"; exit 1; }
# the lines run in $T (the logs' names are relative), each in the background
(cd "$T" && while IFS= read -r line; do
   eval "exec $line" >/dev/null 2>&1 &
   echo $!
 done <<<"$recipe") >"$T/pids"
LPIDS=$(cat "$T/pids")
sleep 5
kill -INT $LPIDS 2>/dev/null
for i in $(seq 1 20); do
  alive=0; for p in $LPIDS; do kill -0 "$p" 2>/dev/null && alive=1; done
  [ $alive -eq 0 ] && break; sleep 0.25
done
kill -TERM "$DPID"; wait "$DPID" 2>/dev/null; DPID=""
# `listen --log`: "N messages from LOG: samples N (L lost in G gaps) harmonics N ...; L lost"
for f in outputs samples; do
  sum=$("$A" listen --log "$T/$f.lcmlog" 2>&1 >/dev/null | grep 'messages from' | tail -1)
  total=$(echo "$sum" | sed -n 's/.*: \([0-9]*\) messages from.*/\1/p')
  lost=$(echo "$sum" | sed -n 's/.*; \([0-9]*\) lost,.*/\1/p')
  min=$([ $f = samples ] && echo 5000 || echo 2500) # ~1950 and ~1000 a second
  if [ "${total:-0}" -ge "$min" ] && [ "${lost:-1}" -eq 0 ]; then
    ok "$f.lcmlog: $total messages in 5 s, none of the daemon's msg_seq missing ($(echo "$sum" | sed 's/.*lcmlog: //'))"
  else
    bad "$f.lcmlog: ${total:-no} messages (want >= $min), ${lost:-?} lost: $sum"
  fi
done
# the stream's rate and filter, stated by the daemon and in every samples message (issue 30)
grep -q "sample streams (2): 0: 878.75 kHz (decimation 16), every channel low-pass 351.5 kHz (-80 dB from 527.25 kHz)" "$T/daemon.err" &&
  ok "the daemon states its sample streams' rate and low-pass" || bad "no sample streams line: $(grep -m1 'streams' "$T/daemon.err")"
j=$("$A" listen --log "$T/samples.lcmlog" --json --count 50 2>/dev/null | grep -m1 '"stream":0')
echo "$j" | grep -q '"rate_hz":878750,"decimation":16,"passband_hz":351500,"stopband_hz":527250' &&
  ok "the logged samples messages carry decimation 16, passband 351.5 kHz, stopband 527.25 kHz" ||
  bad "samples message: $(echo "$j" | cut -c1-300)"
grep -q "resyncs 0 " "$T/daemon.err" || echo "note: the daemon resynced: $(grep -m1 'resyncs [1-9]' "$T/daemon.err" | cut -c1-160)"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
