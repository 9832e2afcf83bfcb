#!/usr/bin/env bash
# test_squeeze_cli.sh BUILD -- forces by origin in what a user reads (issue 30): at Z = 1 um
# on default.conf (squeeze film on) `afmtwin approach --json` and a daemon curve (`afmtwin
# replay` of a setpoint, the daemon's path and its harmonics records, into `afmtwin curve
# --json`) report a tip-sample peak force below 1e-12 N and a tip-sample dissipation within
# 0.01 eV of 0 per period, and the squeeze film's own dissipation beside them, 589 eV
# (500..700); the two tools agree on it within 1e-4. Before, both printed the squeeze film's
# 0.59 nN and 589 eV as the tip-sample peak force and dissipation, and had no squeeze field.
# The estimator itself: tests/test_squeeze_split.c. No network.
BUILD=${1:-build}
. "$(dirname "$0")/lib_check.sh"
check_init squeeze_cli "$BUILD"
C=config/default.conf
EV=1.602176634e-19
"$A" approach --config $C --from 1e-6 --to 1e-6 --step 1e-9 --json >"$T/ap.json" 2>/dev/null ||
  bad "approach at Z 1 um failed"
"$A" send setpoint --config $C --z 1e-6 --seq 1 --log "$T/cmd.log" --log-time 0 --quiet &&
  "$A" replay --config $C --in "$T/cmd.log" --out "$T/out.log" --tail 0.01 --harmonics-every 1 \
    --quiet && "$A" curve "$T/out.log" --json >"$T/curve.json" ||
  bad "replay of a setpoint at 1 um into curve failed"
val() { # KEY FILE: the number of KEY in the last record of FILE that has it ("nan" if none)
  grep "\"$1\":" "$2" | tail -1 | sed -e "s/.*\"$1\":\([^,}]*\).*/\1/" | grep . || echo nan
}
for f in ap curve; do
  pk=$(val peak_force_n "$T/$f.json")
  ed=$(val dissipated_energy_j "$T/$f.json")
  es=$(val squeeze_dissipated_energy_j "$T/$f.json")
  echo "     $f: peak force $pk N, tip-sample $ed J, squeeze film $es J per period"
  awk -v x="$pk" 'BEGIN { exit !(x == x + 0 && x < 1e-12 && x > -1e-12) }' &&
    ok "$f, Z 1 um: tip-sample peak force $pk N, |.| < 1e-12 (the squeeze film's was 5.9e-10)" ||
    bad "$f, Z 1 um: peak force $pk N (the squeeze film counted as tip-sample?)"
  awk -v x="$ed" -v ev=$EV 'BEGIN { exit !(x == x + 0 && x / ev < 0.01 && x / ev > -0.01) }' &&
    ok "$f, Z 1 um: tip-sample dissipation $ed J, within 0.01 eV of 0 (was 589 eV)" ||
    bad "$f, Z 1 um: tip-sample dissipation $ed J"
  awk -v x="$es" -v ev=$EV 'BEGIN { exit !(x == x + 0 && x / ev > 500 && x / ev < 700) }' &&
    ok "$f, Z 1 um: the squeeze film's dissipation beside it, $es J (500..700 eV)" ||
    bad "$f, Z 1 um: squeeze_dissipated_energy_j $es"
done
a=$(val squeeze_dissipated_energy_j "$T/ap.json")
b=$(val squeeze_dissipated_energy_j "$T/curve.json")
awk -v a="$a" -v b="$b" 'BEGIN { r = (a - b) / b; exit !(b == b + 0 && r < 1e-4 && r > -1e-4) }' &&
  ok "approach and the daemon curve agree on the squeeze film's dissipation ($a / $b J)" ||
  bad "squeeze film's dissipation: approach $a J, daemon curve $b J"
check_done
