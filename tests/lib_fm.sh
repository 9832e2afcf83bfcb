# lib_fm.sh -- sourced by the FM tests (test_fm_daemon.sh, test_fm_self_daemon.sh,
# test_fm_self_replay.sh) after lib_daemon.sh's daemon_test_init: what they share, so that
# the three run the same probe the same way -- the lumped vdW probe at Z 6 nm, the JSON
# getter, the offline reference of the self drive, a daemon's start-up and the clean-up --
# and check the daemon's loops the same way (its harmonics records, a refused dither).
# Sets T (a temporary directory), Z, DPID/LPID/LOGPIDS (processes to kill at exit) and the
# EXIT trap.
T=$(mktemp -d /tmp/afmtwin-fm.XXXXXX)
DPID=""
LPID=""
LOGPIDS=""
fm_cleanup() {
  [ -n "$DPID" ] && kill -KILL "$DPID" 2>/dev/null
  [ -n "$LPID" ] && kill -KILL "$LPID" 2>/dev/null
  for p in $LOGPIDS; do kill -KILL "$p" 2>/dev/null; done
  rm -rf "$T"
}
trap fm_cleanup EXIT
Z=6e-9

# fm_conf CONTROL [DRIVE] -- the probe of config/lumped-vdw-fold.conf at Z 6 nm, amplitude
# set-point 1 nm, tone 0 started 2 kHz below the resonance (the loops find it); fm.control
# CONTROL ("internal" or "none"), fm.drive DRIVE if given ("pll" or "self")
fm_conf() {
  local drive=""
  [ -n "${2:-}" ] && drive=" drive = \"$2\";"
  cat <<EOF
model = { kind = "lumped"; lumped = { stiffness_n_m = 2.0; resonance_hz = 300e3; };
          quality_factor = [2000.0]; };
forces = { inclination_deg = 0.0; radius_m = 1e-8;
           vdw_contact = { hamaker_j = 1.29e-19; a0_m = 2.4e-10; reduced_modulus_pa = 7e10; }; };
drive = { separation_m = $Z; tones = ( { amplitude_m = 6e-13; frequency_hz = 298e3; } ); };
sim = { sample_rate_hz = 14.06e6; integrator = "rt"; };
fm = { control = "$1";$drive amplitude_setpoint_m = 1.0e-9; };
EOF
}

# jget FILE K -- JSON field K of the last line of FILE ("" if none)
jget() { python3 -c "import json,sys
L=[l for l in open('$1') if l.strip()]
v=json.loads(L[-1]).get('$2') if L else None
print('' if v is None else v)"; }

# fm_self_reference CONF -- `afmtwin approach --mode fm --fm-drive self` at Z on CONF, the
# offline reference of the self drive: counted (locked, says self), sa its frequency shift
# (Hz); returns 1 when it failed
fm_self_reference() {
  "$A" approach --config "$1" --mode fm --fm-drive self --from $Z --to $Z --step 1e-9 \
    --json > "$T/approach.json" 2> "$T/approach.err"
  sa=$(jget "$T/approach.json" frequency_shift_hz)
  [ -n "$sa" ] && [ "$(jget "$T/approach.json" lock_state)" = locked ] &&
    [ "$(jget "$T/approach.json" fm_drive)" = self ] &&
    { ok "approach --mode fm --fm-drive self at Z 6 nm: locked, shift $sa Hz"; return 0; }
  bad "approach --fm-drive self: $(tail -2 "$T/approach.err")"
  return 1
}

# fm_daemon_up ERR OTHERS DAEMON-OPTIONS... -- afmtwind with those options in real time
# (DPID; stderr to ERR; the other real-time processes into OTHERS, lib_daemon.sh's
# rt_others), returning after its first status and a whole second of running, from which
# realtime_factor_1s is valid
fm_daemon_up() {
  local err=$1 others=$2
  shift 2
  "$D" "$@" --quiet 2> "$err" &
  DPID=$!
  rt_others "$others" "$DPID" &
  listen --channels status --json --count 1 --timeout 5 > /dev/null 2>&1 # up
  sleep 1.2
}

# fm_harm_check FILE REF SHIFT DRIVE N TOL -- the harmonics records in FILE (listen --json)
# under the daemon's FM loops: at least N, each locked with fm.drive DRIVE, its fe_hz its
# tone 0, its fm_frequency_shift_hz that tone less REF (the status's reference, 1e-6 Hz)
# and within TOL Hz of SHIFT, its phase error under 0.1 deg. Prints "N records, fm_drive
# DRIVE, shift S Hz, phase error P deg", or the failed assertion; 0 when all held.
fm_harm_check() {
  python3 - "$@" <<'PY'
import json, sys
h = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
ref, shift, drive = float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
n, tol = int(sys.argv[5]), float(sys.argv[6])
assert len(h) >= n, len(h)
for r in h:
    assert r["fm_lock_state"] == "locked", r.get("fm_lock_state")
    assert r["fm_drive"] == drive, r.get("fm_drive")
    f0 = r["tones"][0]["frequency_hz"]
    assert r["fe_hz"] == f0, (r["fe_hz"], f0)
    assert abs(r["fm_frequency_shift_hz"] - (f0 - ref)) < 1e-6, (r["fm_frequency_shift_hz"], f0 - ref)
    assert abs(r["fm_frequency_shift_hz"] - shift) < tol, (r["fm_frequency_shift_hz"], shift)
    assert abs(r["fm_phase_error_deg"]) < 0.1, r["fm_phase_error_deg"]
print("%d records, fm_drive %s, shift %.4f Hz, phase error %.2e deg" %
      (len(h), drive, h[-1]["fm_frequency_shift_hz"], h[-1]["fm_phase_error_deg"]))
PY
}

# fm_dither_refused CONF WHAT STATUS -- a dither command (checked against CONF) while the
# daemon's FM loops own tone 0: refused by the twin with the reason (status `refused`: valid,
# but not taken), counted (refused one more than in STATUS, a status from before), still
# locked, fe_hz unchanged above 299 kHz. Counted as ok or bad, named "dither under WHAT".
fm_dither_refused() {
  local rej0 rej1 out src fl2 fe2
  rej0=$(jget "$3" refused)
  out=$("${run[@]}" "$A" send dither --freq 298kHz --amp 0.6pm --config "$1" --wait 2>&1); src=$?
  listen --channels status --json --count 1 --timeout 3 > "$T/s2.json" 2>/dev/null
  rej1=$(jget "$T/s2.json" refused); fl2=$(jget "$T/s2.json" fm_lock_state)
  fe2=$(jget "$T/s2.json" fe_hz)
  [ "$src" -eq 1 ] && echo "$out" | grep -q 'under the daemon.s FM control' &&
    [ -n "$rej0" ] && [ "$rej1" = $((rej0 + 1)) ] && [ "$fl2" = locked ] &&
    awk -v a="$fe2" 'BEGIN{exit !(a > 299000)}' &&
    ok "dither under $2: refused ($(echo "$out" | head -1 | cut -c1-90)...), counted, still locked at $fe2 Hz" ||
    bad "dither under $2: exit $src, '$out', refused $rej0 -> $rej1, lock $fl2, fe $fe2"
}
