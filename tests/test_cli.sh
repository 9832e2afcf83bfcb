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
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
