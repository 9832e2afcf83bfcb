#!/usr/bin/env bash
# test_fm_cli.sh BUILD -- `afmtwin approach --mode fm` (issue 32): a short FM approach of a
# lumped vdW probe (JSON: every step locked and settled, the shift negative and growing
# towards the sample, the drive and amplitude held), the text table's header, and bad usage
# (an unknown mode, --rate with fm, a bad fm group) refused with exit 2.
. "$(dirname "$0")/lib_check.sh"
check_init fm-cli "${1:-build}"

cat > "$T/fm.conf" <<'CONF'
model = { kind = "lumped"; lumped = { stiffness_n_m = 40.0; resonance_hz = 300e3; };
          quality_factor = [300.0]; };
forces = { inclination_deg = 0.0; radius_m = 1e-8;
  vdw_contact = { hamaker_j = 1.29e-19; a0_m = 2.4e-10; reduced_modulus_pa = 7e10; }; };
drive = { separation_m = 5e-9; tones = ( { amplitude_m = 3.3e-14; frequency_hz = 300e3; } ); };
sim = { sample_rate_hz = 14.06e6; integrator = "rt"; };
fm = { pll_bandwidth_hz = 200.0; amplitude_bandwidth_hz = 100.0; };
CONF

if "$A" approach --config "$T/fm.conf" --mode fm --from 5e-9 --to 3e-9 --step 1e-9 --json \
    > "$T/fm.json" 2> "$T/fm.err"; then
  ok "approach --mode fm runs"
else
  bad "approach --mode fm runs: $(cat "$T/fm.err")"
fi
if python3 - "$T/fm.json" <<'PY'
import json, sys
r = [json.loads(l) for l in open(sys.argv[1])]
assert len(r) == 3, len(r)
for x in r:
    for k in ("z_m", "frequency_shift_hz", "frequency_hz", "free_frequency_hz",
              "drive_amplitude_m", "amplitude_m", "phase_error_deg", "locked", "lock_state",
              "settled", "amplitude_setpoint_m", "dissipated_energy_j"):
        assert k in x, k
    assert x["mode"] == "fm" and x["fm_drive"] == "pll" and x["locked"] and x["lock_state"] == "locked" and x["settled"]
    assert abs(x["amplitude_m"] / x["amplitude_setpoint_m"] - 1) < 1e-3
    assert abs(x["phase_error_deg"]) < 0.01
    assert abs(x["free_frequency_hz"] - 300e3) < 0.05
    assert abs(x["frequency_hz"] - x["free_frequency_hz"] - x["frequency_shift_hz"]) < 1e-6
s = [x["frequency_shift_hz"] for x in r]
assert s[0] < 0 and s[1] < s[0] and s[2] < s[1], s
PY
then ok "fm JSON: 3 steps locked and settled, shift < 0 growing towards the sample"
else bad "fm JSON: $(head -c 600 "$T/fm.json")"; fi

# the self-excited drive (fm.drive = "self", --fm-drive self) on the same approach: the same
# frequency shift as the PLL's (both settle to --fm-tol 1e-3 Hz a window: 1e-4 relative, or
# 2 mHz, whichever is larger), amplitude held, lag 90 deg
if "$A" approach --config "$T/fm.conf" --mode fm --fm-drive self --from 5e-9 --to 3e-9 \
    --step 1e-9 --json > "$T/self.json" 2> "$T/self.err" &&
    python3 - "$T/fm.json" "$T/self.json" <<'PY'
import json, sys
p = [json.loads(l) for l in open(sys.argv[1])]
s = [json.loads(l) for l in open(sys.argv[2])]
assert len(s) == len(p) == 3
for a, b in zip(p, s):
    assert b["fm_drive"] == "self" and a["fm_drive"] == "pll"
    assert b["locked"] and b["settled"], b
    assert abs(b["z_m"] - a["z_m"]) < 1e-15
    d = abs(b["frequency_shift_hz"] - a["frequency_shift_hz"])
    assert d <= max(2e-3, 1e-4 * abs(a["frequency_shift_hz"])), (a["frequency_shift_hz"], b["frequency_shift_hz"])
    assert abs(b["amplitude_m"] / b["amplitude_setpoint_m"] - 1) < 1e-3
    assert abs(b["phase_error_deg"]) < 0.01
    print("# Z %.1f nm: shift pll %.5f Hz, self %.5f Hz" % (a["z_m"] * 1e9, a["frequency_shift_hz"], b["frequency_shift_hz"]))
PY
then ok "--fm-drive self: the PLL's shift at every Z (1e-4 or 2 mHz), amplitude held, lag 90"
else bad "--fm-drive self: $(cat "$T/self.err") $(head -c 600 "$T/self.json")"; fi
"$A" approach --config "$T/fm.conf" --mode fm --fm-drive nco --from 4e-9 --to 4e-9 \
  > /dev/null 2> "$T/e4"
rc=$?
[ $rc -eq 2 ] && grep -q -- "--fm-drive wants one of pll, self, got 'nco'" "$T/e4" && ok "an unknown --fm-drive: exit 2, said" \
  || bad "an unknown --fm-drive: exit $rc, $(cat "$T/e4")"
sed 's/amplitude_bandwidth_hz = 100.0;/amplitude_bandwidth_hz = 100.0; drive = "selfish";/' \
  "$T/fm.conf" > "$T/bad2.conf"
"$A" approach --config "$T/bad2.conf" --mode fm --from 4e-9 --to 4e-9 > /dev/null 2> "$T/e5"
rc=$?
[ $rc -eq 2 ] && grep -q "fm.drive" "$T/e5" && ok "a bad fm.drive: exit 2 with the key" \
  || bad "a bad fm.drive: exit $rc, $(cat "$T/e5")"

"$A" approach --config "$T/fm.conf" --mode fm --from 4e-9 --to 4e-9 > "$T/fm.txt" 2>&1
if grep -q "free resonance f_free" "$T/fm.txt" && grep -q "^approach.*locked" "$T/fm.txt"; then
  ok "fm text table: the header names f_free, the step is locked"
else bad "fm text table: $(cat "$T/fm.txt")"; fi

"$A" approach --config "$T/fm.conf" --mode pm --from 4e-9 --to 4e-9 > /dev/null 2> "$T/e1"
rc=$?
[ $rc -eq 2 ] && grep -q -- "--mode wants one of am, fm, got 'pm'" "$T/e1" && ok "an unknown --mode: exit 2, said" \
  || bad "an unknown --mode: exit $rc, $(cat "$T/e1")"
"$A" approach --config "$T/fm.conf" --mode fm --rate 1e-6 --from 5e-9 --to 4e-9 --step 1e-9 \
  > /dev/null 2> "$T/e2"
rc=$?
[ $rc -eq 2 ] && grep -q "am only" "$T/e2" && ok "--rate with --mode fm: exit 2, said" \
  || bad "--rate with --mode fm: exit $rc, $(cat "$T/e2")"
sed 's/pll_bandwidth_hz = 200.0/pll_bandwidth_hz = 5000.0/' "$T/fm.conf" > "$T/bad.conf"
"$A" approach --config "$T/bad.conf" --mode fm --from 4e-9 --to 4e-9 > /dev/null 2> "$T/e3"
rc=$?
[ $rc -eq 2 ] && grep -q "fm.pll_bandwidth_hz.*too fast for the lock-in" "$T/e3" \
  && ok "an fm bandwidth too fast for the lock-in: exit 2 with the key and why" \
  || bad "a too fast fm bandwidth: exit $rc, $(cat "$T/e3")"
# afmtwin plot approach on an FM approach: its own panels (frequency shift, drive change,
# amplitude against its set-point, E_ts), not the AM ones (which have no data in it)
if "$A" plot approach "$T/fm.json" -o "$T/fm.png" --csv "$T/fm.csv" 2> "$T/pe" &&
    [ -s "$T/fm.png" ] && head -1 "$T/fm.csv" | grep -q "frequency_shift (Hz)" &&
    python3 - "$T/fm.json" "$T/fm.csv" <<'PY'
import json, sys
r = [json.loads(l) for l in open(sys.argv[1])]
rows = [l.strip().split(",") for l in open(sys.argv[2])][1:]
assert len(rows) == len(r), (len(rows), len(r))
for x, c in zip(r, rows):
    assert abs(float(c[1]) - x["z_m"] * 1e9) < 1e-6
    assert abs(float(c[2]) - x["frequency_shift_hz"]) < 1e-6 * max(1, abs(x["frequency_shift_hz"]))
PY
then ok "plot approach of an fm run: png, and the CSV's shift per Z is the JSON's"
else bad "plot approach of an fm run: $(cat "$T/pe") $(head -3 "$T/fm.csv" 2>/dev/null)"; fi
check_done
