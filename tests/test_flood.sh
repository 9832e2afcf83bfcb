#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_flood.sh BUILD [--long] -- the daemon under a junk flood (afmtwin flood), inside a
# private network namespace (loopback only), every flood bounded:
#  A. The ASan+LSan+UBSan daemon (BUILD/san, `make sanitize-build`; model time at 0.1x the
#     wall clock, so that the instrumented integrator keeps up; a 6.9 MHz tone with
#     --harmonics-max-hz 0.001, which overflowed an int) takes each kind of junk --
#     random bytes, truncated messages, wrong types, NaN/inf/out-of-range values, crafted
#     lengths -- at 20000 messages a second, valid setpoints among them: no sanitizer report
#     (also none at exit: LSan), flat memory (RSS), every valid setpoint applied or (lost
#     with the junk before any handler, when the instrumented daemon falls behind) counted
#     as dropped, and received = applied + rejected + refused + dropped.
#  B. The daemon as deployed (BUILD, threads at SCHED_FIFO) on default.conf, tapping, under
#     a mixed flood of 20000 junk messages a second from a sender at normal priority: the
#     real-time factor of every second of the flood >= 0.99 and no resync in --long, >= 0.9
#     and at most one resync in the short run (from the 10 Hz status: model time over wall
#     time), every valid setpoint applied, the counts add up. The short run's daemon runs at
#     --speed 0.5 (AFMTWIN_RT_SPEED), --long at 1: the factor is a share of the speed.
# Short (make test): 1 s per kind in A, 3 s in B. --long (make flood): 10 s per kind, 15 s.
BUILD=${1:-build}
MODE=${2:-short}
cd "$(dirname "$0")/.." || exit 1
if [ "${3:-}" != "--inside" ]; then
  if ! unshare -n true 2>/dev/null; then
    echo "FAIL test_flood.sh: 'unshare -n' is not permitted here (no private network namespace)"
    echo "0 passed, 1 failed"; exit 1
  fi
  . tests/san_build.sh
  san_build "$BUILD" bin/afmtwind
  exec unshare -n sh -c 'ip link set lo up && ip link set lo multicast on &&
    ip route add 224.0.0.0/4 dev lo && exec bash "$0" "$1" "$2" --inside' "$0" "$BUILD" "$MODE"
fi
if [ "$MODE" = --long ]; then PER_KIND=10; RT_S=15; else PER_KIND=1; RT_S=3; fi
# B's daemon speed: 1 in --long (make flood); in the short run AFMTWIN_RT_SPEED or 0.5, as in
# tests/lib_daemon.sh (this 2-core machine kind runs default.conf at capacity at 1x); the
# real-time factor is judged as a share of it.
if [ "$MODE" = --long ]; then SPEED=1; else SPEED=${AFMTWIN_RT_SPEED:-0.5}; fi
RATE=20000
A="$BUILD/bin/afmtwin"
export LCM_DEFAULT_URL='udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304'
export AFMTWIN_CONFIG=config/default.conf  # what `afmtwin send` checks against
pass=0; fail=0
ok()  { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
T=$(mktemp -d /tmp/afmtwin-flood.XXXXXX)
DPID=""
cleanup() { [ -n "$DPID" ] && kill -KILL "$DPID" 2>/dev/null; rm -rf "$T"; }
trap cleanup EXIT
if chrt -f 90 true 2>/dev/null; then hi() { chrt -f 90 "$@"; }; else hi() { "$@"; }; fi
jnum() { sed -n "s/.*\"$1\":\([^,}]*\).*/\1/p"; }
status() { hi "$A" listen --channels status --json --count 1 --timeout 3 2>/dev/null; }
rss_kb() { awk '/^VmRSS/{print $2}' "/proc/$1/status" 2>/dev/null; }
# The counts of a status line add up? Prints them; exit status 0 if they do.
adds_up() { # STATUS
  local r a j f d
  r=$(echo "$1" | jnum received); a=$(echo "$1" | jnum applied); j=$(echo "$1" | jnum rejected)
  f=$(echo "$1" | jnum refused); d=$(echo "$1" | jnum dropped)
  echo "received $r = applied $a + rejected $j + refused $f + dropped $d"
  [ -n "$r" ] && [ "$r" -eq $((a + j + f + d)) ]
}
# Status once the queue has drained: received has stopped moving and every message received
# has been handled (a parameter change counts as applied only after its model build, so
# received alone can stand still while one is still in flight). Waits while the daemon makes
# progress (handled grows): gives up after 20 statuses without progress or 240 in all.
settled() {
  local s p="" h hp="" idle=0
  for _ in $(seq 1 240); do
    s=$(status)
    [ -n "$s" ] && [ "$(echo "$s" | jnum received)" = "$p" ] && adds_up "$s" >/dev/null \
      && { echo "$s"; return; }
    p=$(echo "$s" | jnum received)
    h=""; for k in applied rejected refused dropped; do h="$h $(echo "$s" | jnum $k)"; done
    if [ "$h" = "$hp" ]; then idle=$((idle + 1)); [ $idle -ge 20 ] && break; else idle=0; fi
    hp=$h; sleep 0.5
  done
  echo "$s"
}

# ---- A. the sanitized daemon, one kind of junk after the other ----------------------------
SAN="$BUILD/san/bin/afmtwind"
if [ ! -x "$SAN" ]; then
  bad "A: no sanitized daemon $SAN (make sanitize-build)"
else
  mkdir -p "$T/asan"
  # A small quarantine (ASan keeps freed blocks there, 256 MB by default), so that RSS
  # shows the daemon's memory and not ASan's.
  ASAN_OPTIONS="detect_leaks=1:halt_on_error=0:quarantine_size_mb=1:log_path=$T/asan/report" \
  UBSAN_OPTIONS="print_stacktrace=1:log_path=$T/asan/ubsan" \
    "$SAN" --config config/default.conf --speed 0.1 --harmonics-max-hz 0.001 --quiet \
    2>"$T/san.err" &
  DPID=$!
  s=""; for _ in $(seq 1 40); do s=$(status); [ -n "$s" ] && break; sleep 0.25; done
  [ -n "$s" ] && ok "A: the sanitized daemon is up" || bad "A: no status from the sanitized daemon"
  # issue 13: harmonics every ceil(fe / harmonics_max_hz) periods was an int overflow (UB)
  # for 6.9 MHz / 0.001 Hz; UBSan reports it (checked at the end) unless it is bounded.
  "$A" send dither --freq 6.9e6 --amp 1e-12 --seq 999999 --quiet
  sleep 1
  rss0=$(rss_kb $DPID); rss_first=""; valid=0; seq0=1000000; last_seq=""
  for kind in random truncated wrongtype values lengths; do
    out=$("$A" flood --kinds $kind --rate $RATE --seconds $PER_KIND --valid-rate 20 --seq0 $seq0 --seed $seq0)
    v=$(echo "$out" | sed -n 's/.*+ \([0-9]*\) valid.*/\1/p'); valid=$((valid + v))
    if [ "${v:-0}" -gt 0 ]; then
      last_seq=$(echo "$out" | sed -n 's/.*valid (seq [0-9]*\.\.\([0-9]*\)).*/\1/p')
      seq0=$((last_seq + 1))
    fi
    sleep 0.5
    rss=$(rss_kb $DPID)
    [ -z "$rss_first" ] && rss_first=$rss
    if kill -0 $DPID 2>/dev/null; then
      ok "A: $kind: $(echo "$out" | sed 's/^flood: //'); daemon alive, RSS $((rss / 1024)) MB"
    else
      bad "A: $kind: the daemon died: $(tail -3 "$T/san.err")"; break
    fi
  done
  s=$(settled)
  msg=$(adds_up "$s") && ok "A: counts add up: $msg" || bad "A: counts do not add up: $msg"
  ap=$(echo "$s" | jnum applied); sq=$(echo "$s" | jnum seq_applied)
  # The instrumented daemon may fall behind a flood: a valid setpoint lost with the junk
  # before any handler must then be among the dropped ones (B, the deployed daemon, shows all
  # applied in make flood).
  dr=$(echo "$s" | jnum dropped)
  [ -n "$ap" ] && [ "$sq" = "$last_seq" ] && [ $((valid + 1 - ap)) -le "${dr:-0}" ] \
    && ok "A: $((ap - 1)) of $valid valid setpoints applied, the rest among the $dr dropped (the last seq $sq applied)" \
    || bad "A: valid setpoints: $valid sent (last seq $last_seq), applied $ap - 1, dropped $dr, seq_applied $sq"
  rss_end=$(rss_kb $DPID)
  grow=$(( (rss_end - rss_first) / 1024 ))
  [ -n "$rss_end" ] && [ -n "$rss_first" ] && [ "$grow" -le 4 ] \
    && ok "A: memory flat: RSS $((rss0 / 1024)) MB before, $((rss_first / 1024)) MB after the first kind, $((rss_end / 1024)) MB at the end (+$grow MB)" \
    || bad "A: memory grew by $grow MB over the floods ($((rss_first / 1024)) -> $((rss_end / 1024)) MB)"
  kill -TERM $DPID; wait $DPID; rc=$?; DPID=""
  n=$(cat "$T"/asan/* 2>/dev/null | grep -cE 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:')
  [ $rc -eq 0 ] && [ "$n" -eq 0 ] \
    && ok "A: SIGTERM: exit 0, no ASan, LSan or UBSan report (at exit either)" \
    || { bad "A: exit $rc, $n sanitizer report(s)"; cat "$T"/asan/* 2>/dev/null | head -40; }
fi

# ---- B. the deployed daemon, real time, SCHED_FIFO ------------------------------------------
D="$BUILD/bin/afmtwind"
"$D" --config config/default.conf --speed "$SPEED" 2>"$T/rt.err" &
DPID=$!
s=""; for _ in $(seq 1 40); do s=$(status); [ -n "$s" ] && break; sleep 0.25; done
[ -n "$s" ] || bad "B: no status from the daemon"
"$A" send setpoint --z 40e-9 --seq 5 --quiet   # tapping: Z below the 57 nm free amplitude
sleep 1.5
pol=$(chrt -p $DPID 2>/dev/null | head -1 | sed 's/.*: //')
s0=$(status); rs0=$(echo "$s0" | jnum resyncs)
hi "$A" listen --channels status --json --timeout $((RT_S + 2)) > "$T/status.json" 2>/dev/null &
LP=$!
sleep 0.5
out=$("$A" flood --rate $RATE --seconds $RT_S --valid-rate 20 --seq0 2000000 --seed 7)
wait $LP
v=$(echo "$out" | sed -n 's/.*+ \([0-9]*\) valid.*/\1/p')
last_seq=$(echo "$out" | sed -n 's/.*valid (seq [0-9]*\.\.\([0-9]*\)).*/\1/p')
got=$(echo "$out" | sed -n 's/.* s (\([0-9]*\) msg\/s).*/\1/p')
what="B: sender at normal priority (the daemon's threads $pol): $(echo "$out" | sed 's/^flood: //')"
# The sender's rate depends on what other processes leave it (the daemon's threads are
# above it): a check in --long (make flood), said in the short run.
if [ "$MODE" != --long ] || [ "${got:-0}" -ge $((RATE * 95 / 100)) ]; then ok "$what"
else bad "$what: below 95% of $RATE msg/s (a loaded machine? run again)"; fi
# Real-time factor per second of the flood: model time over wall time between statuses
# one second apart (utime: the daemon's wall clock at publish, us).
per_s=$(awk -F'[:,]' -v speed="$SPEED" '
  { for (i = 1; i < NF; i++) { if ($i ~ /"utime"/) u = $(i+1); if ($i ~ /"model_time_s"/) m = $(i+1) }
    n++; U[n] = u / 1e6; M[n] = m }
  END { j = 1
        for (i = 1; i <= n; i++) if (U[i] - U[j] >= 1.0) {
          r = (M[i] - M[j]) / (U[i] - U[j]) / speed; printf "%.4f ", r; if (min == "" || r < min) min = r; j = i }
        printf "| %s\n", min }' "$T/status.json")
min=${per_s##*| }
nsec=$(echo "${per_s%|*}" | wc -w)
# The bound: 0.99 and no resync in --long (make flood); the short run (make test) fails below
# 0.9 or on more than one resync (a machine shared with other work, CI's, dips a few per
# cent now and then; a flood that stalled the daemon would take it far below) and prints
# whether the strict level held.
rt_min=0.99; rs_max=0
[ "$MODE" = --long ] || { rt_min=0.9; rs_max=1; }
strict=$(awk -v m="${min:-0}" 'BEGIN{print (m >= 0.99) ? "the strict 0.99 held" : "below the strict 0.99 (make flood asks it)"}')
if [ -n "$min" ] && [ "$nsec" -ge $((RT_S - 1)) ] && awk -v m="$min" -v b=$rt_min 'BEGIN{exit !(m >= b)}'; then
  ok "B (--speed $SPEED): real-time factor (of the speed asked for) of each of $nsec seconds >= $rt_min: ${per_s%|*}(min $min; $strict)"
else
  bad "B (--speed $SPEED): real-time factor (of the speed asked for) per second: ${per_s%|*}(min ${min:-none}, $nsec seconds; want >= $rt_min)"
fi
# resyncs over the status the listener took: the flood and 1.5 s after it
rs=$(tail -1 "$T/status.json" | jnum resyncs)
[ -n "$rs" ] && [ $((rs - ${rs0:-0})) -le $rs_max ] && ok "B: at most $rs_max resync during the flood ($rs0 -> $rs)" \
  || bad "B: resyncs $rs0 -> $rs (at most $rs_max)"
s=$(settled)
sq=$(echo "$s" | jnum seq_applied); ap=$(echo "$s" | jnum applied)
# Every valid setpoint applied; in the short run (make test, beside the test pool) one lost
# with the junk before any handler, in LCM's or the kernel's full queues while the pool held
# the receiving thread, passes when it is among the counted drops (as in A), and says so;
# make flood (--long) keeps the strict check. The counts must add up either way (below).
drb=$(echo "$s" | jnum dropped)
if [ "$sq" = "$last_seq" ] && [ "$ap" -eq $((v + 1)) ]; then
  ok "B: every valid setpoint applied ($v + the tapping one; the last seq $sq)"
elif [ "$MODE" != --long ] && [ "$sq" = "$last_seq" ] && [ -n "$ap" ] &&
  [ "$ap" -le $((v + 1)) ] && [ $((v + 1 - ap)) -le "${drb:-0}" ]; then
  ok "B: $((ap - 1)) of $v valid setpoints applied, $((v + 1 - ap)) among the $drb dropped (the pool's load; make flood asks every one; the last seq $sq applied)"
else
  bad "B: valid setpoints: $v sent (last $last_seq), applied $ap (want $((v + 1))), dropped $drb, seq_applied $sq"
fi
msg=$(adds_up "$s") && ok "B: counts add up: $msg" || bad "B: counts do not add up: $msg"
# stderr: at most 5 reason lines a second, the rest summed up (it was one line per reject:
# 28 MB for 300k messages); the attacker's bytes (names with ESC, CR, LF) never raw in it.
nrej=$(grep -c "^afmtwind: rejected: " "$T/rt.err")
nsum=$(grep -c "more rejections/refusals in the last second" "$T/rt.err")
lim=$(( (RT_S + 4) * 5 ))
[ "$nrej" -le "$lim" ] && [ "$nsum" -ge 1 ] \
  && ok "B: stderr: $nrej reason lines for $(echo "$s" | jnum rejected) rejections, $nsum summaries ($(wc -c < "$T/rt.err") bytes)" \
  || bad "B: stderr: $nrej reason lines (at most $lim), $nsum summaries"
esc=$(tr -cd '\033\r' < "$T/rt.err" | wc -c)
[ "$esc" -eq 0 ] && ok "B: no raw ESC or CR from the junk on stderr (names quoted as \\xNN)" \
  || bad "B: $esc raw control bytes on stderr"

# ---- C. a blow-up that recurs pauses the twin, loudly --------------------------------------
# Free (Z = 1 mm), 150 nm at the resonance: 99 um free amplitude, within the limits; then
# the damping goes (xi 1e-9): the tip runs past 1 mm every ~6 ms. After 3 blow-ups the twin
# pauses itself, the status says why, stderr says it; control run resumes.
"$A" send setpoint --z 1e-3 --seq 10 --quiet
"$A" send dither --freq 338112 --amp 150e-9 --seq 11 --quiet
sleep 0.3
"$A" send dither --freq 338112 --amp 160e-9 --seq 12 --quiet 2>"$T/lim.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "free tip" "$T/lim.txt" \
  && ok "C: send refuses 160 nm at resonance: $(cut -c1-150 "$T/lim.txt")" || bad "C: send 160 nm: exit $rc: $(cat "$T/lim.txt")"
"$A" send param model.damping_ratio[0]=1e-9 --seq 13 --quiet
s=""; for _ in $(seq 1 20); do s=$(status); [ "$(echo "$s" | jnum auto_paused)" = 1 ] && break; sleep 0.25; done
pr=$(echo "$s" | sed -n 's/.*"pause_reason":"\([^"]*\)".*/\1/p')
[ "$(echo "$s" | jnum auto_paused)" = 1 ] && [ "$(echo "$s" | jnum running)" = 0 ] && [ "$(echo "$s" | jnum blowups)" -ge 3 ] \
  && ok "C: paused itself after $(echo "$s" | jnum blowups) blow-ups: $pr" \
  || bad "C: no auto-pause: $s"
t1=$(echo "$s" | jnum model_time_s); sleep 0.5; t2=$(status | jnum model_time_s)
[ "$t1" = "$t2" ] && ok "C: paused: model time stands at $t1 s (no spinning through resets)" \
  || bad "C: model time moved while paused: $t1 -> $t2"
sleep 1.2
grep -q "afmtwind: PAUSED: paused by itself" "$T/rt.err" && grep -q "numerical blow-up(s) in the last second" "$T/rt.err" \
  && ok "C: stderr says it: $(grep -m1 "afmtwind: PAUSED:" "$T/rt.err" | cut -c1-100)..." || bad "C: stderr says nothing of the pause"
"$A" send param model.damping_ratio[0]=0.0012 --seq 14 --quiet
"$A" send control run --seq 15 --quiet
sleep 0.5
s=$(status)
[ "$(echo "$s" | jnum running)" = 1 ] && [ "$(echo "$s" | jnum auto_paused)" = 0 ] \
  && ok "C: damping back, control run: running again" || bad "C: after control run: $s"
kill -TERM $DPID; wait $DPID; DPID=""

# ---- D. what is lost before any handler is counted too --------------------------------------
# The daemon stopped (SIGSTOP): 0.05 s of valid parameter changes at 10000/s (each needs a
# model build), 0.55 s of valid setpoints at 10000/s and then 0.5 s of junk at 40000/s go
# into the command socket, whose 4 MB receive buffer overflows (the kernel drops); at
# SIGCONT, LCM's receive thread reads what the buffer held far faster than the daemon takes
# it, and LCM's subscription queues (1000) overflow: every command behind a build in flight
# waits in the receive thread's hold ring (4096, cmd_in.c), so the 500 builds and the 5500
# setpoints behind them fill it, and the receive thread then waits for the builds. (With
# 4000 commands, 0.4 s, the hold ring took them all, and whether LCM's queues overflowed
# depended on how fast the receive thread rejected the junk: a fresh-clone make test of
# 2026-12-07 saw none. 6000 parameter changes did it too, but the daemon then builds ~5200
# models, ~25 ms each: 130 s of the section's 190; a setpoint behind them needs none.)
# Every message sent is in received, and received = applied + rejected + refused + dropped.
"$D" --config config/default.conf --quiet 2>"$T/d.err" &
DPID=$!
s=""; for _ in $(seq 1 40); do s=$(status); [ -n "$s" ] && break; sleep 0.25; done
kill -STOP $DPID
o1=$("$A" flood --rate 1 --seconds 0.02 --valid-rate 10000 --valid-kind param --seq0 3000000)
o3=$("$A" flood --rate 1 --seconds 0.58 --valid-rate 10000 --valid-kind setpoint --seq0 3100000)
o2=$("$A" flood --rate 40000 --seconds 0.5 --valid-rate 0 --seed 3)
kill -CONT $DPID
sent=0
for o in "$o1" "$o3" "$o2"; do
  j=$(echo "$o" | sed -n 's/^flood: sent \([0-9]*\) junk.*/\1/p'); v=$(echo "$o" | sed -n 's/.*+ \([0-9]*\) valid.*/\1/p')
  sent=$((sent + j + v))
done
s=$(settled)
ld=$(echo "$s" | sed -n 's/.*"last_drop":"\([^"]*\)".*/\1/p')
msg=$(adds_up "$s") && ok "D: counts add up: $msg" || bad "D: counts do not add up: $msg"
[ "$(echo "$s" | jnum received)" = "$sent" ] \
  && ok "D: every one of the $sent messages sent is in received" \
  || bad "D: $sent sent, received $(echo "$s" | jnum received)"
echo "$ld" | grep -q "LCM dropped [1-9]" && echo "$ld" | grep -qE "the kernel [1-9]" \
  && ok "D: drops seen in LCM's queues and in the kernel: $ld" || bad "D: last_drop: '$ld'"
kill -TERM $DPID; wait $DPID; DPID=""
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
