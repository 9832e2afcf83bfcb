#!/usr/bin/env bash
# test_applied_log.sh BUILD -- `afmtwind --applied-log` and `afmtwin replay --applied`, inside a
# private network namespace. A real-time daemon (default.conf, fast scheme, --speed $RT_SPEED)
# takes a plain sequence of every command kind that changes the twin in real time: a Z step,
# a Z ramp, frequency and amplitude steps, four tones and back, a force constant, a damping
# change (a model built off the real-time threads and swapped in), pause and run, a reset
# (whose clearing of the output chain's queues took the records waiting there with it in
# the daemon, not in replay, which takes them before each command: 1522 of 1715 found before
# afm_runner_chain_seq_next stopped at a reset too).
# Where each applies is decided by real time (the next ring item, later while the chain is
# behind), so a replay of the arrival times differs; the daemon's log stamps each with the
# sample it applied at. Checked: the log holds every applied command and the scheme events;
# `replay --applied` of it applies every one (none rejected) and gives every harmonics record
# the daemon published (as lcm-logger caught them) with the same period start and every field
# to the bit (time stamp and message numbers aside), at least 99 % of them found; the same
# on a log whose sample stamps are shifted by one (made here from the daemon's) does not
# (the check sees a one-sample error); and bad uses are refused with a reason.
# Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_applied_log.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
T=$(mktemp -d /tmp/afmtwin-applied.XXXXXX)
DPID=""; LP=""
cleanup() {
  [ -n "$DPID" ] && kill -KILL "$DPID" 2>/dev/null
  [ -n "$LP" ] && kill -KILL "$LP" 2>/dev/null
  [ -n "${KEEP:-}" ] && echo "kept $T" || rm -rf "$T"
}
trap cleanup EXIT
url="$LCM_DEFAULT_URL"; out_url=${url/:7667/:7668}
S() { "$A" send "$@" --quiet || bad "send $*"; }

# the same harmonics cadence in both (the automatic one follows tone 0's frequency, and where
# the twin takes it when the drive changes is a matter of timing, not of the model)
K=300
"$D" --config config/default.conf --quiet --scheme fast --speed "$RT_SPEED" \
  --harmonics-every $K --applied-log "$T/applied.lcmlog" 2> "$T/d.err" &
DPID=$!
listen --channels status --json --count 1 --timeout 10 > /dev/null 2>&1 # up
lcm-logger -q -f -c AFMTWIN_HARMONICS --lcm-url "$out_url" "$T/harm.lcmlog" & LP=$!
sleep 0.3
S setpoint --z 30e-9
sleep 0.2
for f in 338.0e3 338.05e3 338.1e3; do S dither --freq $f --amp 0.087e-9; sleep 0.1; done
S dither --freq 338.1e3 --amp 0.07e-9
S dither --freq 338.1e3,676.2e3,1014.3e3,1352.4e3 --amp 0.07e-9,1e-12,1e-12,1e-12
sleep 0.2
S dither --freq 338.112e3 --amp 0.087e-9
S setpoint --z 25e-9 --ramp 2e-6
sleep 0.3
S param forces.vdw_contact.hamaker_j=1.6e-19
S param 'model.damping_ratio[0]=0.0025'
sleep 0.3
S control pause
sleep 0.1
S control run
sleep 0.2
S control reset
sleep 0.3
kill -INT "$LP"; wait "$LP" 2>/dev/null; LP=""
kill -TERM "$DPID"; wait "$DPID"; drc=$?; DPID=""
[ "$drc" -eq 0 ] && ok "daemon stopped cleanly" || bad "daemon exit $drc: $(tail -3 "$T/d.err")"
line=$(sed -n 's/^afmtwind: --applied-log [^:]*: //p' "$T/d.err")
nev=$(echo "$line" | sed -n 's/^\([0-9]*\) events.*/\1/p')
napp=$(sed -n 's/^afmtwind: final: .* applied \([0-9]*\) .*/\1/p' "$T/d.err")
# the log's events by channel: the commands applied, and the scheme (at sample 0, at the end,
# and right after the damping change: the model swapped in starts in its config's scheme, and
# the daemon sets the fast one it was told to run again at that sample)
python3 - "$T/applied.lcmlog" > "$T/ev.out" <<'EOF'
import collections, struct, sys
b = open(sys.argv[1], "rb").read()
i, c = 0, collections.Counter()
while i < len(b):
    sync, num, ts, cl, dl = struct.unpack(">IqqII", b[i:i + 28])
    c[b[i + 28:i + 28 + cl].decode().replace("AFMTWIN_", "")] += 1
    i += 28 + cl + dl
print(sum(v for k, v in c.items() if k != "SCHEME"), c["SCHEME"], dict(c))
EOF
read -r ncmd nsch evs < "$T/ev.out"
[ -n "$nev" ] && [ "${ncmd:-x}" = "$napp" ] && [ "$nev" -eq $((ncmd + nsch)) ] && [ "$nsch" -ge 2 ] &&
  ! echo "$line" | grep -q INCOMPLETE &&
  ok "the daemon's applied log: $line; $evs; the status: applied $napp" ||
  bad "the daemon's applied log: '${line:-none}', $evs, applied ${napp:-?}"

# COMPARE LOG WHAT EXPECT(same/differ)
compare() {
  "$A" replay --config config/default.conf --in "$1" --applied --out "$T/rp.lcmlog" --tail 0 \
    --harmonics-every $K --channels harmonics 2> "$T/rp.err" || { bad "$2: replay --applied: $(tail -2 "$T/rp.err")"; return; }
  "$A" listen --log "$T/harm.lcmlog" --channels harmonics --json > "$T/dh.jsonl" 2>/dev/null
  "$A" listen --log "$T/rp.lcmlog" --channels harmonics --json > "$T/rh.jsonl" 2>/dev/null
  local what res rc
  what="$2: replay --applied ($(sed -n 's/.*: \([0-9]* commands applied, [0-9]* rejected\).*/\1/p' "$T/rp.err"))"
  res=$(python3 tests/harm_identical.py "$T/dh.jsonl" "$T/rh.jsonl"); rc=$?
  if [ "$3" = same ]; then
    [ "$rc" -eq 0 ] && echo "ok   $what: $res" || echo "FAIL $what: ${res:-no comparison}"
  else
    [ "$rc" -ne 0 ] && echo "ok   $what: $res (must not all match)" ||
      echo "FAIL $what: $res (must not all match)"
  fi
}
compare "$T/applied.lcmlog" "the daemon's log" same > "$T/c1.out"
read -r tag rest < "$T/c1.out"; [ "$tag" = ok ] && ok "$rest" || bad "$rest"
grep -q " 0 rejected" "$T/rp.err" && ok "replay applied every logged command: $(grep -o '[0-9]* commands applied, [0-9]* rejected' "$T/rp.err")" ||
  bad "replay rejected logged commands: $(tail -1 "$T/rp.err")"
# the same log with every event after sample 0 one sample later: the check must see it
python3 - "$T/applied.lcmlog" "$T/late.lcmlog" <<'EOF'
import struct, sys
b = open(sys.argv[1], "rb").read()
out, i = bytearray(), 0
while i < len(b):
    sync, num, ts, cl, dl = struct.unpack(">IqqII", b[i:i + 28])
    ch = b[i + 28:i + 28 + cl]
    if ts > 0: ts += 1  # all but the scheme at sample 0
    out += struct.pack(">IqqII", sync, num, ts, cl, dl) + b[i + 28:i + 28 + cl + dl]
    i += 28 + cl + dl
open(sys.argv[2], "wb").write(out)
EOF
compare "$T/late.lcmlog" "every command one sample late" differ > "$T/c2.out"
read -r tag rest < "$T/c2.out"; [ "$tag" = ok ] && ok "$rest" || bad "$rest"
# bad uses
"$A" replay --config config/default.conf --in "$T/applied.lcmlog" --applied --lockstep \
  --out "$T/x.lcmlog" 2> "$T/e1" && bad "--applied --lockstep accepted" ||
  ok "replay --applied --lockstep refused: $(head -1 "$T/e1")"
"$A" send setpoint --z 30e-9 --log "$T/wall.lcmlog" --log-time 5 --quiet --no-check 2>/dev/null
"$A" send setpoint --z 31e-9 --log "$T/wall.lcmlog" --log-time 1 --quiet --no-check 2>/dev/null
"$A" replay --config config/default.conf --in "$T/wall.lcmlog" --applied --out "$T/x.lcmlog" \
  2> "$T/e2" && bad "--applied of a log whose stamps go back accepted" ||
  ok "replay --applied of a log whose stamps go back: $(grep -o 'sample .*' "$T/e2" | head -1)"
"$D" --config config/default.conf --applied-log "$T/a2.lcmlog" --start-time 1 2> "$T/e3" &&
  bad "--applied-log with --start-time accepted" ||
  ok "afmtwind --applied-log with --start-time refused: $(grep -e '--applied-log' "$T/e3" | head -1)"
"$D" --config config/default.conf --applied-log /nonexistent/dir/a.lcmlog 2> "$T/e4" &&
  bad "--applied-log into a missing directory accepted" ||
  ok "afmtwind --applied-log into a missing directory: $(grep -e '--applied-log' "$T/e4" | head -1)"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
