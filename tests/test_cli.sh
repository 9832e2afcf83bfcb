#!/usr/bin/env bash
# test_cli.sh BUILD -- the afmtwin command line: help texts, `modes --json` keys and shape,
# exit codes for bad usage and bad configs. Prints "N passed, N failed".
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
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
