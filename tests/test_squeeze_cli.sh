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

# The daemon's other force outputs (the same replay's log, read with `listen --log`): the
# force harmonics and the sample stream's force channel carry the tip-sample force (at 1 um
# the vdW attraction, ~1e-16 N), the status the squeeze film's E_sq beside its peak force.
# Before, harmonic 1 of the force was the squeeze film's 5.9e-10 N, the stream's force swung
# +-5.9e-10 N, and the status had no E_sq.
"$A" listen --log "$T/out.log" --json >"$T/far.json" 2>/dev/null || bad "listen --log of the replay"
if r=$(python3 - "$T/far.json" $EV <<'PY'
import json, sys
ev = float(sys.argv[2])
h = st = None
fmax = 0.0
for line in open(sys.argv[1]):
    o = json.loads(line)
    if o["type"] == "harmonics": h = o
    if o["type"] == "status": st = o
    if o["type"] == "samples" and o["t0_s"] > 0.005:  # both streams, past the filters' start
        fmax = max(fmax, abs(o["force_n"]["min"]), abs(o["force_n"]["max"]))
f1 = h["force_amplitude_n"][0]
esq = st.get("squeeze_dissipated_energy_j")
print(f"force harmonic 1 {f1:.3g} N, sample streams |force| <= {fmax:.3g} N, status E_sq "
      f"{esq / ev if esq is not None else float('nan'):.1f} eV")
sys.exit(0 if f1 < 1e-14 and fmax < 1e-14 and esq is not None and 500 < esq / ev < 700 else 1)
PY
); then
  ok "Z 1 um, the daemon's force outputs are tip-sample: $r (the squeeze film's force harmonic was 5.9e-10 N)"
else
  bad "Z 1 um, the daemon's force outputs: $r"
fi

# In contact (Z 40 nm, tapping at ~61 nN): the harmonics record's tip-sample figures are
# approach's within 1 % (peak force, E_ts; E_sq within 1e-3), and the dissipative part of
# the force harmonic 1, pi A1 F1 sin(phi_x1 - phi_F1), is E_ts's within 0.15 E_sq (A1 and
# phi_x1 are the OBD signal's, which is not the tip's to better than ~0.4 deg; before, the
# harmonic carried the squeeze film too: E_ts + 1.0 E_sq).
"$A" approach --config $C --from 40e-9 --to 40e-9 --step 1e-9 --json >"$T/ap40.json" 2>/dev/null ||
  bad "approach at Z 40 nm failed"
"$A" send setpoint --config $C --z 40e-9 --seq 1 --log "$T/cmd40.log" --log-time 0 --quiet &&
  "$A" replay --config $C --in "$T/cmd40.log" --out "$T/out40.log" --tail 0.02 \
    --harmonics-every 1 --quiet && "$A" listen --log "$T/out40.log" --json --channels harmonics \
    2>/dev/null | tail -1 >"$T/h40.json" || bad "replay at Z 40 nm failed"
if r=$(python3 - "$T/h40.json" "$T/ap40.json" $EV <<'PY'
import json, math, sys
h = json.load(open(sys.argv[1]))
ap = [json.loads(l) for l in open(sys.argv[2]) if l.strip()][-1]
ev = float(sys.argv[3])
a1, f1 = h["deflection_amplitude_m"][0], h["force_amplitude_n"][0]
d = math.radians(h["deflection_phase_deg"][0] - h["force_phase_deg"][0])
e1 = math.pi * a1 * f1 * math.sin(d)
rel = lambda a, b: abs(a / b - 1)
rp = rel(h["peak_force_n"], ap["peak_force_n"])
re = rel(h["dissipated_energy_j"], ap["dissipated_energy_j"])
rs = rel(h["squeeze_dissipated_energy_j"], ap["squeeze_dissipated_energy_j"])
esq = ap["squeeze_dissipated_energy_j"]
r1 = abs(e1 - ap["dissipated_energy_j"]) / esq
print(f"peak force {h['peak_force_n']:.5g} / {ap['peak_force_n']:.5g} N ({rp:.2g}), E_ts "
      f"{h['dissipated_energy_j'] / ev:.4g} / {ap['dissipated_energy_j'] / ev:.4g} eV ({re:.2g}), "
      f"E_sq {h['squeeze_dissipated_energy_j'] / ev:.4g} / {esq / ev:.4g} eV ({rs:.2g}); "
      f"force harmonic 1 {f1:.4g} N, its dissipation {e1 / ev:.4g} eV (E_ts + {r1:.2g} E_sq)")
sys.exit(0 if rp < 1e-2 and re < 1e-2 and rs < 1e-3 and r1 < 0.15 else 1)
PY
); then
  ok "Z 40 nm, daemon (replay) vs approach: $r"
else
  bad "Z 40 nm, daemon (replay) vs approach: $r"
fi
check_done
