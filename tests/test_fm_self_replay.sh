#!/usr/bin/env bash
# test_fm_self_replay.sh BUILD -- the self-excited FM drive (fm.drive = "self", issue 32) in
# the daemon's runner (afm_runner) as `afmtwin replay` runs it: in model time, bit for bit
# reproducible, no wall clock -- so the comparison with the offline tool is exact to the
# controller's own scatter. Why its own file: test_fm_self_daemon.sh runs the daemon
# (lockstep and real time); this one needs no daemon and checks what the replay log shows.
# On test_fm_daemon.sh's lumped vdW probe (lumped-vdw-fold.conf's, Z 6 nm, amplitude
# set-point 1 nm, tone 0 started 2 kHz off), a log with one control run and, at 30 ms of
# model time, a dither command, replayed 60 ms:
#  (a) the last status says internal and locked, its frequency shift equals `afmtwin approach
#      --mode fm --fm-drive self` at the same Z within 0.02 Hz;
#  (b) the harmonics records of the last 20 ms: all locked, shift = their own tone 0 less the
#      status's reference, mean shift within 0.01 Hz of approach's, |phase error| (lock-in lag
#      - set-point: a check under self-excitation, not a control input) < 0.05 deg;
#  (c) tone 0 re-synthesised at every update (fm_tone_changes = the updates run; the PLL
#      steps its NCO only on leaving the 1 mHz quantum);
#  (d) the dither command is not applied, with the FM reason, and the loop stays locked;
#  (e) replay --block 700 gives the same harmonics records byte for byte;
#  (f) `afmtwin plot fm` of the log draws the records' own shift and lock state.
# Inside a private network namespace as the daemon tests (send and listen are LCM tools,
# though here they only write and read logs). Prints "N passed, N failed".
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/lib_daemon.sh
[ "${2:-}" = "--inside" ] || netns_reexec test_fm_self_replay.sh "$0" "$BUILD"
daemon_test_init "$BUILD"
. tests/lib_fm.sh # T, Z, fm_conf, jget, fm_self_reference
fm_conf internal self > "$T/self.conf"

# ---- the offline reference ----------------------------------------------------------------
fm_self_reference "$T/self.conf" || sa=0

# ---- replay: the runner in model time -------------------------------------------------------
"$A" send control run --config "$T/self.conf" --seq 1 --log "$T/in.log" --log-time 0 --quiet &&
  "$A" send dither --freq 298kHz --amp 0.6pm --config "$T/self.conf" --seq 2 --log "$T/in.log" \
    --log-time 0.03 --quiet || bad "send --log"
"$A" replay --config "$T/self.conf" --in "$T/in.log" --out "$T/out.log" --tail 0.03 \
  --channels harmonics,status --harmonics-every 10 2> "$T/replay.err" ||
  bad "replay: $(tail -2 "$T/replay.err")"
"$A" listen --log "$T/out.log" --channels status --json > "$T/st.jsonl" 2>/dev/null
"$A" listen --log "$T/out.log" --channels harmonics --json > "$T/h.jsonl" 2>/dev/null
# Tolerances. The status is one controller update: the counted frequency of that update,
# low-passed at fm.pll_bandwidth_hz, scatters by +-8 mHz from period to period here (the
# delay line's phase is exact for a sinusoid; the tip force's harmonics move it slightly),
# so 0.02 Hz; the harmonics records' mean over 20 ms (~600 records, every 10th period)
# averages that to < 1 mHz against approach's window mean, so 0.01 Hz (6e-5 of the shift,
# test_fm_daemon's tolerance for the PLL). The references differ by < 1e-6 Hz (mode 1's f0
# = 300 kHz for the runner, the self-excited free frequency at Z 1 um for approach, which
# runs at 300000.000000 Hz: README, "Self-excited drive"). Both run the accurate scheme. A
# drive not re-synthesised stays near the start frequency, unlocked.
python3 - "$T/st.jsonl" "$T/h.jsonl" "$sa" 14.06e6 1024 > "$T/a.out" 2>&1 <<'PY'
import json, sys
st = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
h = [json.loads(l) for l in open(sys.argv[2]) if l.strip()]
sa, rate, upd = float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
out = []
def check(cond, msg):
    out.append(("ok   " if cond else "FAIL ") + msg)
s = st[-1]
check(s["fm_control"] == "internal" and s["fm_drive"] == "self" and
      s["fm_lock_state"] == "locked" and abs(s["fm_frequency_shift_hz"] - sa) <= 0.02,
      "replay, self drive: status %s, fm_drive %s, %s, shift %.4f Hz = approach's %.4f within 0.02 Hz "
      "(phase error %.2e deg, drive %.4g m)" % (s["fm_control"], s["fm_drive"], s["fm_lock_state"],
      s["fm_frequency_shift_hz"], sa, s["fm_phase_error_deg"], s["fm_drive_amplitude_m"]))
t_end = h[-1]["t_s"] if h else 0
w = [r for r in h if r["t_s"] >= t_end - 0.02]
mean = sum(r["fm_frequency_shift_hz"] for r in w) / len(w) if w else float("nan")
spread = max(abs(r["fm_frequency_shift_hz"] - mean) for r in w) if w else float("nan")
lk = all(r["fm_lock_state"] == "locked" and r["fm_drive"] == "self" for r in w)
pe = max(abs(r["fm_phase_error_deg"]) for r in w) if w else float("nan")
tone = all(abs(r["fm_frequency_shift_hz"] - (r["tones"][0]["frequency_hz"] -
           s["fm_reference_hz"])) < 1e-6 for r in w)
check(len(w) >= 100 and lk and tone and abs(mean - sa) <= 0.01 and pe < 0.05,
      "harmonics records, last 20 ms: %d, locked (fm_drive self) %s, shift = tone 0 - reference %s, mean "
      "%.4f Hz (+-%.4f) = approach's within 0.01 Hz, |phase error| <= %.2e deg (< 0.05)" %
      (len(w), lk, tone, mean, spread, pe))
updates = int(s["model_time_s"] * rate) // upd
check(s["fm_tone_changes"] >= updates - 2,
      "tone 0 re-synthesised every update: %d tone changes in %d updates" %
      (s["fm_tone_changes"], updates))
check(s["rejected"] == 1 and s["received"] == 2 and s["seq_applied"] == 1 and
      "FM control" in s.get("last_reject", "") and s["fm_lock_state"] == "locked",
      "dither under the self drive: not applied (replay counts it rejected: %d of %d received, "
      "seq_applied %d; '%s'), still locked" %
      (s["rejected"], s["received"], s["seq_applied"], s.get("last_reject", "")[:90]))
print("\n".join(out))
PY
while read -r tag rest; do
  if [ "$tag" = ok ]; then ok "$rest"; elif [ "$tag" = FAIL ]; then bad "$rest"; else
    bad "replay checks: $tag $rest"; fi
done < "$T/a.out"
[ -s "$T/a.out" ] || bad "replay checks: no output ($(head -c 300 "$T/st.jsonl"))"
# (e) how the runner cuts its slices changes no bit: the self drive's delay line is fed every
# sample and its updates fall every update_samples samples counted from the start, whatever
# the block (replay --block 700: slices of 700 cut at the 1024-sample updates)
"$A" replay --config "$T/self.conf" --in "$T/in.log" --out "$T/out700.log" --tail 0.03 \
  --channels harmonics --harmonics-every 10 --block 700 --quiet 2> "$T/replay700.err"
"$A" listen --log "$T/out700.log" --channels harmonics --json > "$T/h700.jsonl" 2>/dev/null
# (the run's end moves with the block -- the logged dither applies at a block boundary and
# the tail runs from there -- so the records both runs made are compared)
n1=$(wc -l < "$T/h.jsonl"); n2=$(wc -l < "$T/h700.jsonl"); n=$((n1 < n2 ? n1 : n2))
[ "$n" -gt 1000 ] && cmp -s <(head -n "$n" "$T/h.jsonl") <(head -n "$n" "$T/h700.jsonl") &&
  ok "replay --block 700: the same $n harmonics records, byte for byte (of $n1 and $n2)" ||
  bad "replay --block 700: harmonics records differ ($n1 against $n2)"
# (f) `afmtwin plot fm` of a replay's log under the PLL (the same commands, fm.drive pll):
# one row per harmonics record with the loops' own shift, phase error (not the lock-in's
# lag, ~90 deg here) and lock state, acquiring then locked; the picture drawn
fm_conf internal > "$T/pll.conf"
"$A" replay --config "$T/pll.conf" --in "$T/in.log" --out "$T/pll.log" --tail 0.03 \
  --channels harmonics --harmonics-every 10 --quiet 2> "$T/replay_pll.err" ||
  bad "replay (PLL): $(tail -2 "$T/replay_pll.err")"
"$A" listen --log "$T/pll.log" --channels harmonics --json > "$T/hp.jsonl" 2>/dev/null
"$A" plot fm "$T/pll.log" -o "$T/fm.png" --data "$T/fm.dat" 2> "$T/plot.err" ||
  bad "plot fm: $(tail -2 "$T/plot.err")"
python3 - "$T/hp.jsonl" "$T/fm.dat" > "$T/f.out" 2>&1 <<'PY'
import json, sys
h = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
rows = [l.split() for l in open(sys.argv[2]) if l.strip() and not l.startswith("#")]
head = open(sys.argv[2]).read()
ok = len(rows) == len(h) and len(h) > 1000
last = rows[-1] if rows else None
st = {"acquiring": 0, "locked": 1, "lost": 2}
same = ok and {0, 1} <= {int(float(r[5])) for r in rows} and all(abs(float(r[1]) - x["fm_frequency_shift_hz"]) <= 1e-6 * max(1, abs(x["fm_frequency_shift_hz"]))
                  and abs(float(r[4]) - x["fm_phase_error_deg"]) <= 1e-6 * max(1, abs(x["fm_phase_error_deg"]))
                  and int(float(r[5])) == st.get(x["fm_lock_state"], x["fm_lock_state"])
                  for r, x in zip(rows, h))
print(("ok   " if same and "internal loops" in head else "FAIL ") +
      "plot fm: %d rows for %d harmonics records (acquiring, then locked), each the record's "
      "shift, phase error and lock state; "
      "the last %s Hz, state %s" % (len(rows), len(h), last[1] if last else "-", last[5] if last else "-"))
PY
while read -r tag rest; do
  if [ "$tag" = ok ]; then ok "$rest"; else bad "$tag $rest"; fi
done < "$T/f.out"
[ -s "$T/fm.png" ] && ok "plot fm: the picture ($(stat -c %s "$T/fm.png") bytes)" || bad "plot fm: no picture"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
