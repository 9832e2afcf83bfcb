#!/usr/bin/env bash
# test_cli.sh BUILD -- the afmtwin command line: help texts, `modes --json` keys and shape,
# exit codes for bad usage and bad configs, SI suffixes, and the progress line of every long
# command on a terminal (none off one). Prints "N passed, N failed".
BUILD=${1:-build}
A="$BUILD/bin/afmtwin"
pass=0; fail=0
ok()  { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
expect_rc() { # WANT DESCRIPTION CMD...
  local want=$1 what=$2; shift 2
  "$@" >/dev/null 2>&1; local rc=$?
  [ "$rc" -eq "$want" ] && ok "$what (exit $rc)" || bad "$what: exit $rc, want $want"
}
expect_rc 0 "afmtwin help" "$A" help
expect_rc 2 "afmtwin without command" "$A"
expect_rc 2 "afmtwin unknown command" "$A" frobnicate
expect_rc 0 "afmtwin modes --help" "$A" modes --help
expect_rc 2 "modes without --config" "$A" modes
expect_rc 2 "modes with a missing file" "$A" modes --config /nonexistent.conf
expect_rc 2 "modes with a bad config" "$A" modes --config tests/bad-configs/unknown-key.conf
"$A" modes --help | grep -q -- "--json" && ok "modes --help names --json" || bad "modes --help lacks --json"
out=$("$A" modes --config config/thesis-table-3-1.conf --json)
for key in frequencies_hz analytical unreduced reduced mac tip_static_stiffness_n_per_m effective_mass_kg; do
  echo "$out" | grep -q "\"$key\"" && ok "modes --json has $key" || bad "modes --json lacks $key"
done
[ "$(echo "$out" | wc -l)" -eq 1 ] && ok "modes --json is one line" || bad "modes --json is not one line"
# 4 reduced modes -> a 4 x 4 MAC: 5 opening brackets after "mac"
n=$(echo "$out" | sed 's/.*"mac":\(\[\[[^]]*\]\(,\[[^]]*\]\)*\]\).*/\1/' | tr -cd '[' | wc -c)
[ "$n" -eq 5 ] && ok "modes --json mac is 4 rows" || bad "modes --json mac rows: $((n-1))"
"$A" modes --config config/default.conf >/dev/null && ok "modes on default.conf" || bad "modes on default.conf"

# sweep: bad values are rejected with a message and exit 2
C=config/thesis-1dof.conf
sweep_bad() { # DESCRIPTION ARGS...
  local what=$1; shift
  msg=$("$A" sweep --config $C "$@" 2>&1 >/dev/null); rc=$?
  if [ "$rc" -eq 2 ] && [ -n "$msg" ]; then ok "sweep rejects $what: $(echo "$msg" | head -1)"
  else bad "sweep $what: exit $rc, message '$msg'"; fi
}
sweep_bad "NaN amplitude" --from 3e5 --to 3e5 --ae nan
sweep_bad "negative Z" --from 3e5 --to 3e5 --z -1e-9
sweep_bad "frequency at half the sample rate" --from 7.03e6 --to 7.03e6
sweep_bad "zero step" --from 3e5 --to 3.1e5 --step 0
sweep_bad "negative frequency" --from -3e5 --to 3e5 --step 1e3
sweep_bad "unknown option" --from 3e5 --to 3e5 --frobnicate
expect_rc 0 "sweep --help" "$A" sweep --help
# sweep --json: one object per step with the issue's keys
out=$("$A" sweep --config $C --from 299e3 --to 300e3 --step 1e3 --harmonics 1,2 --json 2>/dev/null)
[ "$(echo "$out" | wc -l)" -eq 2 ] && ok "sweep --json: one line per step" || bad "sweep --json lines: $(echo "$out" | wc -l)"
for key in fe_hz periodicity settle_periods min_deflection_m max_deflection_m max_force_n contacts \
           pre_contact_velocity_m_s harmonics deflection_amplitude_m deflection_phase_deg \
           force_amplitude_n force_phase_deg phase_diff_deg; do
  echo "$out" | head -1 | grep -q "\"$key\"" && ok "sweep --json has $key" || bad "sweep --json lacks $key"
done
# bench --json: one object with cases (quick run)
out=$("$A" bench --quick --runs 1 --json 2>/dev/null)
for key in cases config integrator ns_per_sample realtime_factor error_rel; do
  echo "$out" | grep -q "\"$key\"" && ok "bench --json has $key" || bad "bench --json lacks $key"
done
# the tools' option tables (tools/opts.c): a value out of range, no number, an unknown option
# and a missing value each exit 2 with the option named
opt_bad() { # DESCRIPTION PATTERN ARGS...
  local what=$1 pat=$2; shift 2
  msg=$("$A" "$@" 2>&1 >/dev/null); rc=$?
  if [ "$rc" -eq 2 ] && echo "$msg" | grep -q -- "$pat"; then ok "$what: $(echo "$msg" | head -1)"
  else bad "$what: exit $rc, message '$msg'"; fi
}
opt_bad "listen --count 0" "--count wants an integer >= 1, got '0'" listen --count 0
opt_bad "replay --block out of range" "--block wants an integer in 1..1048576, got '0'" replay --block 0
opt_bad "replay --block above its range" "--block wants an integer in 1..1048576, got '2000000'" replay --block 2000000
opt_bad "approach --rate above 1 m/s" "--rate wants (0, 1\] m/s, got '2'" approach --rate 2
opt_bad "replay --tail not a number" "--tail wants a number, got 'x'" replay --tail x
opt_bad "lockstep --timeout 0 (must be > 0)" "--timeout wants" lockstep --timeout 0
opt_bad "soak --min-rtf NaN" "--min-rtf wants a number, got 'nan'" soak --min-rtf nan
opt_bad "flood --kinds unknown kind" "--kinds wants" flood --kinds frob
opt_bad "bench-daemon --commands 5" "--commands wants an integer in 10..100000" bench-daemon --commands 5
opt_bad "thermal --modes 1.5" "--modes wants" thermal --modes 1.5
opt_bad "modes unknown option" "unknown or incomplete option '--frobnicate' (see --help)" modes --frobnicate
opt_bad "listen missing value" "unknown or incomplete option '--timeout'" listen --timeout
expect_rc 0 "flood --help" "$A" flood --help
# the daemon's options go through the same table parser (daemon/cli/afm_opts.c): the same
# words, exit 2, nothing started
D=${A%/afmtwin}/afmtwind
dopt_bad() { # DESCRIPTION PATTERN ARGS...
  local what=$1 pat=$2; shift 2
  msg=$("$D" "$@" 2>&1 >/dev/null); rc=$?
  if [ "$rc" -eq 2 ] && echo "$msg" | grep -q -- "$pat"; then ok "afmtwind $what: $(echo "$msg" | head -1)"
  else bad "afmtwind $what: exit $rc, message '$msg'"; fi
}
if [ -x "$D" ]; then
  dopt_bad "--speed 0" "afmtwind: --speed wants a number in 0.001..1000, got '0'" --config config/default.conf --speed 0
  dopt_bad "--speed not a number" "afmtwind: --speed wants a number, got 'x'" --config config/default.conf --speed x
  dopt_bad "--cpu 1.5" "afmtwind: --cpu wants an integer in 0..1023, got '1.5'" --config config/default.conf --cpu 1.5
  dopt_bad "--mode bogus" "afmtwind: --mode wants one of realtime, freerun, lockstep, got 'bogus'" --config config/default.conf --mode bogus
  dopt_bad "unknown option" "afmtwind: unknown or incomplete option '--frob' (see --help)" --frob 1
  dopt_bad "missing value" "afmtwind: unknown or incomplete option '--exit-after'" --config config/default.conf --exit-after
  dopt_bad "no --config" "afmtwind: --config FILE is required" --quiet
  expect_rc 0 "afmtwind --help" "$D" --help
  # a choice: each word of its list taken (the line parsed to --help, exit 0)
  expect_rc 0 "afmtwind --mode lockstep --scheme adaptive taken" "$D" --config config/default.conf \
    --mode lockstep --scheme adaptive --help
fi
# a choice (AFMT_CHOICE, cli/afm_opts.h): a word of its list is stored (the run names what it
# ran), any other word -- a prefix, another case -- is refused naming the option, the words and
# the value given, exit 2
opt_bad "sweep --integrator bogus" "afmtwin sweep: --integrator wants one of rt, reference, arkode-erk, got 'bogus'" \
  sweep --config $C --from 3e5 --to 3e5 --integrator bogus
opt_bad "sweep --scheme Fast (no case folding)" "afmtwin sweep: --scheme wants one of accurate, fast, got 'Fast'" \
  sweep --config $C --from 3e5 --to 3e5 --scheme Fast
opt_bad "map --direction u (no prefixes)" "afmtwin map: --direction wants one of up, down, both, got 'u'" \
  map --direction u
for sch in fast accurate; do
  out=$("$A" sweep --config $C --from 3e5 --to 3e5 --integrator rt --scheme $sch 2>&1); rc=$?
  [ $rc -eq 0 ] && echo "$out" | grep -q "integrator rt (scheme $sch)" &&
    ok "sweep --integrator rt --scheme $sch taken: exit 0, the run names it" ||
    bad "sweep --integrator rt --scheme $sch: exit $rc, $(echo "$out" | head -2)"
done

# SI suffixes on lengths and frequencies (tools/opts.c, afmt_parse_si): the same message as
# the plain SI number (send --log writes it byte for byte), the value echoed in SI on stderr
# only when a suffix was given, a suffix of the other unit or an unknown one refused (exit 2)
T=$(mktemp -d /tmp/afmtwin-cli.XXXXXX)
trap 'rm -rf "$T"' EXIT
send_log() { # FILE ARGS...: one message into the log FILE, fixed seq and times
  local f=$1; shift
  # not --quiet, which silences the SI echoes too (test_examples.sh): stdout dropped instead
  "$A" send "$@" --config config/default.conf --seq 1 --utime 1 --log-time 0 --log "$f" >/dev/null
}
send_log "$T/z_si.log" setpoint --z 30nm 2>"$T/z_si.err" && send_log "$T/z.log" setpoint --z 30e-9 2>"$T/z.err" &&
  cmp -s "$T/z_si.log" "$T/z.log" && ok "send setpoint --z 30nm: the message of --z 30e-9" ||
  bad "send setpoint --z 30nm differs from --z 30e-9: $(cat "$T/z_si.err")"
grep -qx "afmtwin send setpoint: --z 30nm = 3e-08 m" "$T/z_si.err" && ok "--z 30nm echoed: $(cat "$T/z_si.err")" ||
  bad "--z 30nm echo: '$(cat "$T/z_si.err")'"
[ ! -s "$T/z.err" ] && ok "--z 30e-9 (no suffix): no echo" || bad "--z 30e-9 echoed: $(cat "$T/z.err")"
send_log "$T/d_si.log" dither --freq 338kHz --amp 0.087nm 2>"$T/d_si.err" &&
  send_log "$T/d.log" dither --freq 338000 --amp 0.087e-9 2>/dev/null &&
  cmp -s "$T/d_si.log" "$T/d.log" && ok "send dither --freq 338kHz --amp 0.087nm: the message of 338000, 0.087e-9" ||
  bad "send dither --freq 338kHz differs: $(cat "$T/d_si.err")"
grep -q -- "--freq 338kHz = 338000 Hz" "$T/d_si.err" && ok "--freq 338kHz echoed as 338000 Hz" ||
  bad "--freq 338kHz echo: '$(cat "$T/d_si.err")'"
send_log "$T/um.log" setpoint --z 1e-6 2>/dev/null
for v in 1um 1µm 1e-6m "1 um" 1000nm 0.001mm 1000000pm; do
  rm -f "$T/v.log"; send_log "$T/v.log" setpoint --z "$v" 2>/dev/null && cmp -s "$T/v.log" "$T/um.log" &&
    ok "send setpoint --z '$v' = 1e-6 m" || bad "send setpoint --z '$v' is not 1e-6 m"
done
send_log "$T/mhz.log" dither --freq 1.5MHz,5kHz --amp 5pm,1fm --no-check 2>/dev/null &&
  send_log "$T/hz.log" dither --freq 1500000,5000 --amp 5e-12,1e-15 --no-check 2>/dev/null &&
  cmp -s "$T/mhz.log" "$T/hz.log" && ok "send dither --freq 1.5MHz,5kHz --amp 5pm,1fm: in SI" ||
  bad "send dither --freq 1.5MHz,5kHz --amp 5pm,1fm differs from SI"
"$A" approach --from 11nm --help 2>&1 >/dev/null | grep -q . && bad "approach --help echoed a value" ||
  ok "no echo with --help"
out=$("$A" sweep --config $C --from 338.112kHz --to 338.112kHz --z 1um --ae 0.087nm --json 2>"$T/sw.err")
echo "$out" | grep -q '"fe_hz":338112[,}]' && ok "sweep --from 338.112kHz runs at fe 338112 Hz" ||
  bad "sweep --from 338.112kHz: $(echo "$out" | head -c 200) $(cat "$T/sw.err")"
for e in "--from 338.112kHz = 338112 Hz" "--z 1um = 1e-06 m" "--ae 0.087nm = 8.7e-11 m"; do
  grep -q -- "afmtwin sweep: $e\$" "$T/sw.err" && ok "sweep echoes '$e'" || bad "sweep lacks '$e': $(cat "$T/sw.err")"
done
opt_bad "sweep --z 30kHz (a frequency for a length)" "--z wants a length in m (or with a suffix: mm, um, µm, nm, pm, fm), got '30kHz': not a unit of length" \
  sweep --config $C --from 3e5 --to 3e5 --z 30kHz
opt_bad "approach --fe 11nm (a length for a frequency)" "--fe wants a frequency in Hz (or with a suffix: kHz, MHz, GHz), got '11nm'" \
  approach --config $C --from 20nm --to 10nm --fe 11nm
opt_bad "send setpoint --z 30kHz" "--z wants a length in m" send setpoint --z 30kHz --config config/default.conf --check
opt_bad "sweep --z 30xnm (garbage suffix)" "--z wants a number (m, or with a suffix: mm, um, µm, nm, pm, fm), got '30xnm'" \
  sweep --config $C --from 3e5 --to 3e5 --z 30xnm
opt_bad "scan --size-x 4 furlongs" "--size-x wants a number (m" scan --config config/scan-grating.conf --size-x 4furlong
opt_bad "send dither --freq 338kHz,5q" "--freq wants 1..4 comma-separated numbers" \
  send dither --freq 338kHz,5q --amp 1nm --config config/default.conf --check
opt_bad "force-curve --from 2mm out of range, the SI value told" "--from wants a Z in 0..1e-3 m, got '2mm' (= 0.002 m)" \
  force-curve --config $C --from 2mm --to 1nm
msg=$("$A" sweep --config $C --from 3e5 --to 3e5 --z 30kHz 2>&1 >/dev/null)
echo "$msg" | grep -q " = " && bad "a refused value was echoed: $msg" || ok "a refused command line echoes nothing"

# progress: a line on stderr ("\r...") when it is a terminal (script(1) gives a pty), none
# when it is not; the progress waits 1 s, so each run is made to take 2.5-3.5 s of CPU on a
# quiet machine (a sweep of 76 steps took 0.85 s there: no line, a failure). Every long
# command draws it through the one afmt_progress (tools/opts.h).
# progress_check NAME PATTERN CMD...: PATTERN (grep, at a line start) in the pty's output
progress_check() {
  local name=$1 pat=$2
  shift 2
  if command -v script >/dev/null 2>&1; then
    script -qc "$* >/dev/null" /dev/null >"$T/tty.txt" 2>&1
    tr '\r' '\n' <"$T/tty.txt" | grep -aq "^$pat" && ok "$name: progress on a terminal" ||
      bad "$name: no progress on a terminal: $(od -c "$T/tty.txt" | head -5)"
  else
    ok "$name progress on a terminal: skipped (no script(1))"
  fi
  "$@" >/dev/null 2>"$T/notty.txt"
  grep -q $'\r' "$T/notty.txt" && bad "$name: progress without a terminal: $(od -c "$T/notty.txt" | head -3)" ||
    ok "$name: no progress without a terminal"
}
progress_check scan "scan: line [0-9]*/64 " "$A" scan --config config/scan-grating.conf --pixels 8 \
  --line-rate 100 --engage 0.002 --lines 64 --size-y 100nm
progress_check sweep "sweep: step [0-9]*/301 " "$A" sweep --config config/default.conf --from 330kHz --to 345kHz \
  --step 50Hz --z 1um
progress_check approach "approach: approach step [0-9]*/33, Z " "$A" approach --config config/default.conf \
  --from 40nm --to 24nm --step 0.5nm
sed -e '/vdw_contact/d' -e '/viscoelastic/d' -e '/squeeze/d' config/thesis-fig-4-2.conf >"$T/lin.conf"
progress_check continue "continue: branch 0 (period 1), [0-9]* records, fe " "$A" continue \
  --config "$T/lin.conf" --param fe --from 80000 --to 82000 --max-points 30
# (approach or retract: on a fast machine the approach is over before the first line)
progress_check force-curve "force-curve: [a-z]*  *[0-9]* %, Z " "$A" force-curve \
  --config config/thesis-1dof.conf --from 30nm --to 0nm --speed 3e-8
"$A" send setpoint --z 1um --seq 1 --log "$T/p.log" --log-time 0 --quiet --no-check ||
  bad "send setpoint --log"
progress_check replay "replay: model time [0-9.]* s, 1 commands" "$A" replay --config config/default.conf \
  --in "$T/p.log" --out "$T/po.log" --tail 2.5
# bench-states --no-fifo: the caller's scheduling (for profilers), said in the header; the
# run's own policy read from /proc while it runs (0: SCHED_OTHER)
out=$("$A" bench-states --only "tapping, Z 40" --runs 1 --no-fifo --scheme fast 2>&1); rc=$?
[ $rc -eq 0 ] && echo "$out" | grep -q "normal priority: --no-fifo" &&
  ok "bench-states --no-fifo: runs at normal priority, says so" ||
  bad "bench-states --no-fifo: exit $rc, $(echo "$out" | head -1)"
# --only: the states not run are left out (they printed as rows of 0.0 and an RT factor of inf)
rows=$(echo "$out" | grep -cE "^  [a-zA-Z].* [0-9]+\.[0-9] +[0-9]+\.[0-9] +[0-9]+\.[0-9] +[0-9]+\.[0-9] ")
[ "$rows" = 1 ] && echo "$out" | grep -q "^  tapping, Z 40" && ! echo "$out" | grep -q " inf " &&
  ok "bench-states --only: only the state run is listed" ||
  bad "bench-states --only: $rows rows: $(echo "$out" | grep -m2 " inf ")"
out=$("$A" bench-states --only "no such state" --runs 1 --no-fifo 2>&1); rc=$?
[ $rc -eq 2 ] && echo "$out" | grep -q "names no state" &&
  ok "bench-states --only matching nothing: exit 2, says so" ||
  bad "bench-states --only matching nothing: exit $rc: $out"
"$A" bench-states --only "tapping, Z 40" --runs 20 --no-fifo --scheme fast > /dev/null 2>&1 & bp=$!
sleep 0.5; pol=$(awk '{print $41}' /proc/$bp/stat 2>/dev/null); wait $bp
[ "${pol:-x}" = 0 ] && ok "bench-states --no-fifo: its policy while it runs is SCHED_OTHER" ||
  bad "bench-states --no-fifo: policy '${pol:-?}' while it runs"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
