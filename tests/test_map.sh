#!/bin/bash
# test_map.sh -- `afmtwin map` (issue 31): a small fe x Z map of thesis-fig-4-2 is the same
# file, byte for byte, without mpirun and under mpirun with 1, 2 and 3 ranks (oversubscribed
# on two cores); a map stopped after one line (--stop-after), one cut in the middle of a
# line and one killed midway resume to the same file; a corrupt, a mismatched and a foreign
# resume file and bad arguments get clear errors (exit 2) and leave the file as it was; the
# up line equals `afmtwin sweep` (to the 15 digits its JSON prints); `afmtwin plot map` draws it, and its .gsf
# files are read by Gwyddion's own reader with the map's size and values; `plot map --curves
# --contour-force` puts the LPC / PD curves and the peak-force contour in its script; plan's
# top pair is checked by a sweep from its imaging to its patterning point. A build without
# MPI (AFMTWIN_MPI=0) runs as one process and refuses mpirun.
# MPI runs in a private network namespace (loopback only); as root Open MPI wants the
# OMPI_ALLOW_RUN_AS_ROOT pair. Prints "N passed, N failed".
. "$(dirname "$0")/lib_check.sh"
check_init map "${1:-build}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader \
  OMPI_MCA_oob_tcp_if_include=lo OMPI_MCA_rmaps_base_oversubscribe=1
netns() { unshare -n sh -c 'ip link set lo up; exec "$@"' sh "$@"; }
CONF=config/thesis-fig-4-2.conf
MAP=(map --config $CONF --x fe 80000 88000 6 --y z 2e-8 3e-8 3 --max-periods 1500)

"$A" map --help > "$T/help.txt"; rc=$?
[ $rc -eq 0 ] && grep -q "lag behind the" "$T/help.txt" && grep -q -- "--resume" "$T/help.txt" \
  && ok "map --help: exit 0, states the phase convention and --resume" || bad "map --help (exit $rc)"

# ---- the same bytes whatever the number of ranks ----
netns "$A" "${MAP[@]}" --out "$T/single.map" 2> "$T/single.err"; rc=$?
n_e=$(grep -c '^E ' "$T/single.map" 2>/dev/null)
n_p=$(grep -c '^P ' "$T/single.map" 2>/dev/null)
[ $rc -eq 0 ] && [ "$n_e" = 3 ] && [ "$n_p" = 36 ] \
  && ok "map without mpirun (singleton): 3 lines, 36 points (6 x 3, up and down)" \
  || bad "map without mpirun: exit $rc, $n_e lines, $n_p points: $(tail -2 "$T/single.err")"
NOMPI=0; grep -q "built without MPI" "$T/help.txt" && NOMPI=1
if [ $NOMPI -eq 1 ]; then # AFMTWIN_MPI=0 (the arm64 cross build): one process, mpirun refused
  cp "$T/single.map" "$T/np2.map"
  netns mpirun -np 2 "$A" "${MAP[@]}" --out "$T/np2.map" > "$T/np2.out" 2>&1; rc=$?
  [ $rc -ne 0 ] && cmp -s "$T/single.map" "$T/np2.map" && grep -q "built without MPI" "$T/np2.out" \
    && ok "a build without MPI under mpirun -np 2: refused (exit $rc), the file unchanged" \
    || bad "a build without MPI under mpirun -np 2: exit $rc: $(tail -2 "$T/np2.out")"
elif command -v mpirun > /dev/null; then
  for n in 1 2 3; do
    netns mpirun -np $n "$A" "${MAP[@]}" --out "$T/np$n.map" > "$T/np$n.out" 2>&1; rc=$?
    [ $rc -eq 0 ] && cmp -s "$T/single.map" "$T/np$n.map" \
      && ok "mpirun -np $n: the same file, byte for byte" \
      || bad "mpirun -np $n: exit $rc or a different file: $(tail -3 "$T/np$n.out")"
  done
else
  bad "mpirun not found (package openmpi-bin: make deps)"
fi

# ---- resume ----
netns "$A" "${MAP[@]}" --out "$T/r1.map" --stop-after 1 2> "$T/r1.err"; rc=$?
[ $rc -eq 0 ] && [ "$(grep -c '^E ' "$T/r1.map")" = 1 ] && grep -q "stopped after line 1" "$T/r1.err" \
  && ok "--stop-after 1: one whole line written: $(tail -1 "$T/r1.err")" \
  || bad "--stop-after 1: exit $rc, $(grep -c '^E ' "$T/r1.map") lines"
cp "$T/r1.map" "$T/r1.keep"
netns "$A" "${MAP[@]}" --out "$T/r1.map" --resume 2> "$T/r1b.err"; rc=$?
[ $rc -eq 0 ] && cmp -s "$T/single.map" "$T/r1.map" && grep -q "1 of 3 lines done" "$T/r1b.err" \
  && ok "--resume after one line: the same file as the uninterrupted run" \
  || bad "--resume after one line: exit $rc or a different file"
# a write cut in the middle of line 1 (an interruption while writing): dropped and redone
e1=$(grep -b '^E 0 ' "$T/single.map" | cut -d: -f1)
cut_at=$((e1 + 200 + $(grep -m1 '^E 0 ' "$T/single.map" | wc -c)))
head -c $cut_at "$T/single.map" > "$T/cut.map"
RANKS=(mpirun -np 2); [ $NOMPI -eq 1 ] && RANKS=()
netns "${RANKS[@]}" "$A" "${MAP[@]}" --out "$T/cut.map" --resume > "$T/cut.err" 2>&1; rc=$?
[ $rc -eq 0 ] && cmp -s "$T/single.map" "$T/cut.map" \
  && ok "--resume (${RANKS[*]:-one process}) of a file cut inside line 1: the partial line redone, same file" \
  || bad "--resume of a cut file: exit $rc: $(tail -2 "$T/cut.err")"
# killed while running: as soon as line 0 is on disk
# (not through the netns function: in the background it would be a subshell, and $! not the
# map's pid; unshare and sh exec, so $! is the map itself)
unshare -n sh -c 'ip link set lo up; exec "$@"' sh "$A" "${MAP[@]}" --out "$T/kill.map" 2> /dev/null &
pid=$!
for i in $(seq 1 300); do
  grep -q '^E 0 ' "$T/kill.map" 2> /dev/null && break
  sleep 0.05
done
kill -KILL $pid 2> /dev/null; wait $pid 2> /dev/null
lines_at_kill=$(grep -c '^E ' "$T/kill.map")
netns "$A" "${MAP[@]}" --out "$T/kill.map" --resume 2> "$T/kill.err"; rc=$?
[ $rc -eq 0 ] && cmp -s "$T/single.map" "$T/kill.map" && [ "$lines_at_kill" -lt 3 ] \
  && ok "killed (SIGKILL) with $lines_at_kill of 3 lines written, resumed: the same file" \
  || bad "kill and resume: exit $rc, $lines_at_kill lines at the kill, or a different file"

# ---- bad resume files: exit 2, file unchanged ----
resume_refused() { # NAME FILE WHAT EXTRA-ARGS...: --resume on FILE must fail and change nothing
  local name=$1 f=$2 want=$3; shift 3
  cp "$f" "$T/before"
  netns "$A" "${MAP[@]}" "$@" --out "$f" --resume > /dev/null 2> "$T/e.txt"; local rc=$?
  [ $rc -eq 2 ] && cmp -s "$T/before" "$f" && grep -q "$want" "$T/e.txt" \
    && ok "$name: exit 2, file unchanged: $(grep -v -E "= [-0-9.e+]+ (Hz|m)$" "$T/e.txt" | head -c 200)" \
    || bad "$name: exit $rc, $(cmp -s "$T/before" "$f" && echo unchanged || echo CHANGED): $(head -2 "$T/e.txt")"
}
cp "$T/r1.keep" "$T/corrupt.map"
sed -i '0,/^P 0 u 2 /s/^\(P 0 u 2 [^ ]* [^ ]* \)\([0-9]\)/\19/' "$T/corrupt.map"
cmp -s "$T/corrupt.map" "$T/r1.keep" && bad "the corruption did not change the file"
resume_refused "a corrupt resume file (a digit changed)" "$T/corrupt.map" "checksum"
cp "$T/r1.keep" "$T/other.map"
resume_refused "a resume file of other arguments (--x ... 7 points)" "$T/other.map" "other arguments" \
  --x fe 80000 88000 7
resume_refused "a resume file of another --direction" "$T/other.map" "other arguments" --direction up
printf 'hello\n' > "$T/foreign.map"
resume_refused "a resume file that is no map" "$T/foreign.map" "not an afmtwin map"
cp "$T/r1.keep" "$T/junk.map"; printf 'X garbage\n' >> "$T/junk.map"
resume_refused "a resume file with a foreign record after line 0" "$T/junk.map" "corrupt"

# ---- bad arguments: exit 2, nothing written ----
cp "$T/r1.keep" "$T/args.map"
badarg() { # NAME WHAT ARGS...
  local name=$1 want=$2; shift 2
  "$A" map "$@" > /dev/null 2> "$T/e.txt"; local rc=$?
  [ $rc -eq 2 ] && cmp -s "$T/r1.keep" "$T/args.map" && grep -q -- "$want" "$T/e.txt" \
    && ok "$name: exit 2: $(grep -v -E "= [-0-9.e+]+ (Hz|m)$" "$T/e.txt" | head -1)" \
    || bad "$name: exit $rc: $(grep -v -E "= [-0-9.e+]+ (Hz|m)$" "$T/e.txt" | head -2)"
}
O=(--out "$T/args.map")
badarg "unknown parameter" "unknown parameter 'q'" --config $CONF --x q 1 2 3 --y z 20nm 30nm 2 "${O[@]}"
badarg "FROM above TO" "FROM must be below TO" --config $CONF --x fe 88kHz 80kHz 5 --y z 20nm 30nm 2 "${O[@]}"
badarg "the same parameter twice" "different parameters" --config $CONF --x fe 80kHz 88kHz 5 --y fe 80kHz 88kHz 2 "${O[@]}"
badarg "N 0" "integer in 1" --config $CONF --x fe 80kHz 88kHz 0 --y z 20nm 30nm 2 "${O[@]}"
badarg "a length for fe" "wants" --config $CONF --x fe 80nm 88nm 3 --y z 20nm 30nm 2 "${O[@]}"
badarg "--x with too few words" "wants NAME FROM TO N" --config $CONF --y z 20nm 30nm 2 "${O[@]}" --x fe 80kHz
badarg "no --out" "required" --config $CONF --x fe 80kHz 88kHz 5 --y z 20nm 30nm 2
badarg "--direction sideways" "--direction wants one of up, down, both, got 'sideways'" --config $CONF --x fe 80kHz 88kHz 5 --y z 20nm 30nm 2 --direction sideways "${O[@]}"
badarg "Z above 1 mm" "values must be in" --config $CONF --x fe 80kHz 88kHz 5 --y z 20nm 2mm 2 "${O[@]}"
badarg "fe above half the sample rate" "half the sample rate" --config $CONF --x fe 80kHz 5MHz 5 --y z 20nm 30nm 2 "${O[@]}"
badarg "a geometry parameter on --x" "put it on --y" --config $CONF --x model.beam.length_m 1e-4 2e-4 2 --y fe 80kHz 88kHz 3 "${O[@]}"
badarg "an unknown named parameter" "unknown parameter 'forces.bogus'" --config $CONF --x fe 80kHz 88kHz 5 --y forces.bogus 1 2 2 "${O[@]}"
badarg "a named value out of its range" "out of range" --config $CONF --x fe 80kHz 88kHz 5 --y forces.vdw_contact.hamaker_j -1e-19 2e-19 2 "${O[@]}"

# ---- a live parameter as the y axis (Hamaker constant): each line is `afmtwin sweep` of the
# config with that value (set as `afmtwin send param` sets it; compared to the 1e-14 of
# sweep's JSON), the same bytes under mpirun -np 2, the unit in the header and the plot's
# label ----
HMAP=(map --config $CONF --x fe 80000 88000 6 --y forces.vdw_contact.hamaker_j 1e-19 2e-19 2
  --direction up --max-periods 1500)
netns "$A" "${HMAP[@]}" --out "$T/h.map" 2> "$T/h.err"; rc=$?
[ $rc -eq 0 ] && grep -q '^y forces.vdw_contact.hamaker_j 9.9999999999999998e-20 2e-19 2 J$' "$T/h.map" \
  && [ "$(grep -c '^P ' "$T/h.map")" = 12 ] \
  && ok "map --y forces.vdw_contact.hamaker_j: 2 lines of 6, the header names it with its unit (J)" \
  || bad "map --y forces.vdw_contact.hamaker_j: exit $rc: $(head -c 300 "$T/h.err") $(sed -n 5p "$T/h.map")"
sed 's/hamaker_j = 1.29e-19/hamaker_j = 2e-19/' $CONF > "$T/h2.conf"
grep -q 'hamaker_j = 2e-19' "$T/h2.conf" || bad "test set-up: no hamaker_j = 1.29e-19 in $CONF"
"$A" sweep --config "$T/h2.conf" --from 80000 --to 88000 --step 1600 --max-periods 1500 --json \
  > "$T/hsweep.json" 2> /dev/null
h_ok=$(python3 - "$T/hsweep.json" "$T/h.map" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
pts = {}
for l in open(sys.argv[2]):
    f = l.split()
    if f[:3] == ["P", "1", "u"]:
        pts[int(f[3])] = [float(v) for v in f[4:14]] + [int(v) for v in f[14:]]
bad = 0
for i, o in enumerate(rows):
    h = [x for x in o["harmonics"] if x["k"] == 1][0]
    p = pts.get(i)
    want = [o["fe_hz"], h["deflection_amplitude_m"], h["phase_lag_deg"], o["periodicity"],
            o["settle_periods"]]
    if p is None or p[1] != 2e-19 or any(abs(a - b) > 1e-14 * abs(a) for a, b in
                                        zip(want, [p[0], p[2], p[3], p[10], p[12]])):
        bad += 1
        print("point", i, want, p, file=sys.stderr)
print("ok" if bad == 0 and len(rows) == 6 else "bad")
EOF
)
[ "$h_ok" = ok ] \
  && ok "the Hamaker 2e-19 J line equals afmtwin sweep of the config with hamaker_j = 2e-19 (fe, A1, lag, p, periods to 1e-14)" \
  || bad "the Hamaker 2e-19 J line differs from afmtwin sweep of that config"
if [ $NOMPI -eq 0 ] && command -v mpirun > /dev/null; then
  netns mpirun -np 2 "$A" "${HMAP[@]}" --out "$T/h2.map" > "$T/h2.out" 2>&1; rc=$?
  [ $rc -eq 0 ] && cmp -s "$T/h.map" "$T/h2.map" \
    && ok "a named y axis under mpirun -np 2: the same file, byte for byte" \
    || bad "a named y axis under mpirun -np 2: exit $rc or a different file: $(tail -2 "$T/h2.out")"
fi
# ---- a force or damping parameter along x: set with the state carried (as `afmtwin send
# param` applies it in the daemon: new force constants, or a new model's simulator continuing
# the state), each point the settled orbit of a fresh start at that value (a map with that x
# alone): amplitude within 1e-4 relative and lag within 0.01 deg. Both runs stop once a
# period changes by under --tol 1e-6, i.e. up to ~tol Q / pi = 6e-5 from the orbit at Q 200;
# measured 7.5e-6 and 0.0004 deg. One step of each parameter moves the orbit far more
# (Hamaker 1e-19 -> 1.5e-19 J: 4e-4, 0.07 deg; damping ratio 0.002 -> 0.0025: 3e-4, 2.1 deg),
# so a point left on the old value fails ----
carried() { # NAME V0 V1 V2
  local name=$1; shift
  netns "$A" map --config $CONF --x "$name" $1 $3 3 --y fe 80000 84000 2 --direction up \
    --max-periods 1500 --out "$T/cx.map" 2> "$T/cx.err"; local rc=$?
  for v in "$@"; do
    netns "$A" map --config $CONF --x "$name" $v $v 1 --y fe 80000 84000 2 --direction up \
      --max-periods 1500 --out "$T/cx-$v.map" 2>> "$T/cx.err"
  done
  local r; r=$(python3 - "$T/cx.map" "$T/cx-$1.map" "$T/cx-$2.map" "$T/cx-$3.map" <<'EOF'
import sys
def pts(path):
    return {(int(f[1]), int(f[3])): f for f in (l.split() for l in open(path)) if f[:1] == ["P"]}
m = pts(sys.argv[1]); worst_a = worst_l = 0; bad = 0
for ix, path in enumerate(sys.argv[2:]):
    for iy in (0, 1):
        a, b = m.get((iy, ix)), pts(path).get((iy, 0))
        if not a or not b or a[4] != b[4] or a[14] != b[14] or a[15] != "1":
            bad += 1; continue
        da = abs(float(a[6]) / float(b[6]) - 1); dl = abs(float(a[7]) - float(b[7]))
        worst_a = max(worst_a, da); worst_l = max(worst_l, dl)
        bad += da > 1e-4 or dl > 1e-2
print("%s worst %.2g relative, %.2g deg" % ("ok" if bad == 0 and len(m) == 6 else "bad", worst_a, worst_l))
EOF
)
  [ $rc -eq 0 ] && [ "${r%% *}" = ok ] && [ -n "$(awk -v n="$name" '$1 == "x" && $2 == n && $5 == 3' "$T/cx.map")" ] \
    && ok "$name along x ($1 -> $3, state carried): each point = a fresh start at its value (${r#ok })" \
    || bad "$name along x: exit $rc, $r $(head -c 200 "$T/cx.err")"
}
carried forces.vdw_contact.hamaker_j 1e-19 1.5e-19 2e-19
carried "model.damping_ratio[0]" 0.002 0.0025 0.003
"$A" plot map "$T/h.map" --out "$T/h.png" --script "$T/h.gp" 2> "$T/hp.err"; rc=$?
[ $rc -eq 0 ] && grep -q "set ylabel 'forces.vdw_contact.hamaker_j (J)'" "$T/h.gp" \
  && ok "plot map of a named y axis: labelled with its name and unit" \
  || bad "plot map of a named y axis: exit $rc: $(head -2 "$T/hp.err")"
# a unit of two words (forces.viscoelastic.eta_pa_s: "Pa s") reads back whole
sed 's/^\(y forces.vdw_contact.hamaker_j .*\) J$/\1 Pa s/' "$T/h.map" > "$T/hpa.map"
"$A" plot map "$T/hpa.map" --out "$T/hpa.png" --script "$T/hpa.gp" 2> /dev/null \
  && grep -q "set ylabel 'forces.vdw_contact.hamaker_j (Pa s)'" "$T/hpa.gp" \
  && ok "a named axis's unit of two words (Pa s) reads back whole" \
  || bad "a named axis's unit of two words: $(grep ylabel "$T/hpa.gp" 2>/dev/null)"
badarg "a missing config" "cannot" --config /no/such.conf --x fe 80kHz 88kHz 5 --y z 20nm 30nm 2 "${O[@]}"

# ---- a map line is `afmtwin sweep` ----
"$A" sweep --config $CONF --z 2e-8 --from 80000 --to 88000 --step 1600 --max-periods 1500 --json \
  > "$T/sweep.json" 2> /dev/null
sw_ok=$(python3 - "$T/sweep.json" "$T/single.map" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
pts = {}
for l in open(sys.argv[2]):
    f = l.split()
    if f[:3] == ["P", "0", "u"]:
        pts[int(f[3])] = [float(v) for v in f[4:14]] + [int(v) for v in f[14:]]
bad = n1 = 0
for i, o in enumerate(rows):
    h = [x for x in o["harmonics"] if x["k"] == 1][0]
    p = pts[i]
    want = [o["fe_hz"], h["deflection_amplitude_m"], h["phase_lag_deg"], o["periodicity"],
            o["settle_periods"]]
    got = [p[0], p[2], p[3], p[10], p[12]]
    if o["periodicity"] == 1:  # the map's per-period metrics span the p-period orbit
        want += [o["cycle"]["peak_force_n"], o["cycle"]["indentation_m"],
                 o["cycle"]["contact_time_s"], o["cycle"]["dissipated_energy_j"]]
        got += [p[4], p[7], p[8], p[9]]
        n1 += 1
    # cJSON prints 15 digits when they read back within its epsilon: compare to 1e-14
    if any(abs(a - b) > 1e-14 * abs(a) for a, b in zip(want, got)):
        bad += 1
        print("point", i, want, got, file=sys.stderr)
print("ok" if bad == 0 and len(rows) == 6 and n1 >= 2 else "bad")
EOF
)
[ "$sw_ok" = ok ] \
  && ok "the up line at Z 20 nm equals afmtwin sweep (to the 1e-14 of its JSON: fe, A1, lag, p, periods; at p 1 also peak force, indentation, contact time, energy)" \
  || bad "map line vs afmtwin sweep differ"

# ---- plot and Gwyddion files ----
"$A" plot map "$T/single.map" --out "$T/map.png" --gsf "$T/g" 2> "$T/p.err"; rc=$?
[ $rc -eq 0 ] && [ "$(head -c 4 "$T/map.png" | tail -c 3)" = PNG ] \
  && ok "plot map: a PNG of the heat maps" || bad "plot map: exit $rc: $(head -2 "$T/p.err")"
# its title names the model and the drive as every plot's does (plot_info.h), and E_ts
"$A" plot map "$T/single.map" --out "$T/map2.png" --script "$T/map.gp" 2> /dev/null
# (the config's name once: on the model's line, not again with its path on the first)
grep -m1 '^set multiplot' "$T/map.gp" | grep -q "title 'afmtwin map (up sweep, [0-9]* x [0-9]*)'.*'thesis-fig-4-2.conf: f0 80.8205 kHz, Q 200, k 2.821 N/m; drive fe 80-88 kHz, Ae 700 pm; Z 20-30 nm" &&
  [ "$(grep -m1 '^set multiplot' "$T/map.gp" | grep -o 'thesis-fig-4-2' | wc -l)" = 1 ] &&
  grep -q "E_ts tip-sample dissipated (eV)" "$T/map.gp" &&
  ok "plot map: the title names the config once, f0, Q, k and the drive; the energy panel is E_ts" ||
  bad "plot map title: $(grep -m1 '^set multiplot' "$T/map.gp")"
ng=$(ls "$T"/g-*.gsf 2> /dev/null | wc -l)
[ "$ng" = 21 ] && ok "plot map --gsf: 21 files (10 quantities x 2 directions, bistable)" \
  || bad "plot map --gsf: $ng files"
h="$T/g-up-amplitude.gsf"
grep -aq '^XRes = 6$' "$h" && grep -aq '^YRes = 3$' "$h" && grep -aq '^XYUnits = Hz$' "$h" \
  && grep -aq '^ZUnits = m$' "$h" && grep -aq '^XReal = 9600$' "$h" && grep -aq '^XOffset = 79200$' "$h" \
  && ok "amplitude .gsf header: 6 x 3, x 79.2..88.8 kHz (pixels centred on the grid), Hz, m" \
  || bad "amplitude .gsf header: $(head -c 200 "$h" | tr '\n\0' ' .')"
off=$(($(stat -c %s "$h") - 4 * 18))
px_ok=1
for k in 0 7 17; do # pixel k = (iy, ix) = (k / 6, k % 6)
  got=$(od -An -t f4 -j $((off + 4 * k)) -N 4 "$h" | tr -d ' ')
  want=$(awk -v iy=$((k / 6)) -v ix=$((k % 6)) '$1=="P" && $2==iy && $3=="u" && $4==ix {print $7}' "$T/single.map")
  awk -v a="$got" -v b="$want" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= 1e-6 * b) }' || px_ok=0
done
[ $px_ok -eq 1 ] && ok "amplitude .gsf pixels equal the map's values (float precision)" \
  || bad "amplitude .gsf pixels differ from the map"
if command -v gwyddion-thumbnailer > /dev/null; then
  gsf_thumbnails "$T"/g-*.gsf && ok "gwyddion-thumbnailer reads all 21 map .gsf files" \
    || bad "gwyddion-thumbnailer refused a map .gsf file"
else
  bad "gwyddion-thumbnailer not found (package gwyddion: make deps)"
fi
"$A" plot map "$T/foreign.map" --out "$T/x.png" > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "not an afmtwin map" "$T/e.txt" \
  && ok "plot map of a file that is no map: exit 2: $(head -1 "$T/e.txt")" \
  || bad "plot map of a foreign file: exit $rc"

# ---- plot map overlays: the LPC / PD curves of continue --param2, a peak-force contour ----
cat > "$T/curves.json" <<'JSON'
{"type": "LPC", "branch": 0, "param_name": "fe", "param": 82000}
{"type": "curve_point", "curve": 0, "kind": "LPC", "side": 0, "param_name": "fe", "param": 82000, "param2_name": "z", "param2": 2.5e-8}
{"type": "curve_point", "curve": 0, "kind": "LPC", "side": 0, "param_name": "fe", "param": 81800, "param2_name": "z", "param2": 2.7e-8}
{"type": "curve_end", "curve": 0, "kind": "LPC", "side": 0, "param_name": "fe", "param": 81800, "param2_name": "z", "param2": 2.7e-8}
{"type": "curve_point", "curve": 0, "kind": "LPC", "side": 1, "param_name": "fe", "param": 82200, "param2_name": "z", "param2": 2.3e-8}
{"type": "curve_point", "curve": 1, "kind": "PD", "side": 0, "param_name": "fe", "param": 84000, "param2_name": "z", "param2": 2.5e-8}
{"type": "curve_point", "curve": 1, "kind": "PD", "side": 0, "param_name": "fe", "param": 84500, "param2_name": "z", "param2": 2.2e-8}
{"type": "summary", "points": 5}
JSON
F_C=40e-9
"$A" plot map "$T/single.map" --out "$T/over.png" --curves "$T/curves.json" --contour-force $F_C \
  --script "$T/over.gp" 2> "$T/p.err"; rc=$?
block() { awk -v b="\$$1 << EOD" '$0 == b {on = 1; next} on && $0 == "EOD" {exit} on' "$2"; }
# side 1 starts again at the curve's start point (82 kHz, 25 nm): the two sides one line
want_lpc=$(printf '\n82 25\n81.8 27\n\n82 25\n82.2 23')
want_pd=$(printf '\n84 25\n84.5 22')
[ $rc -eq 0 ] && [ "$(head -c 4 "$T/over.png" | tail -c 3)" = PNG ] \
  && [ "$(block lpc "$T/over.gp")" = "$want_lpc" ] && [ "$(block pd "$T/over.gp")" = "$want_pd" ] \
  && grep -q "\$lpc using 1:2 with lines" "$T/over.gp" && grep -q "\$pd using 1:2 with lines" "$T/over.gp" \
  && ok "plot map --curves: the LPC and PD curves in kHz x nm, the two sides joined at the start point, drawn" \
  || bad "plot map --curves: exit $rc: $(head -2 "$T/p.err"); lpc [$(block lpc "$T/over.gp" | tr '\n' '|')]"
# the same curves with the two parameters the other way round
sed -e 's/"param_name": "fe", "param": \([0-9]*\), "param2_name": "z", "param2": \([0-9.e-]*\)/"param_name": "z", "param": \2, "param2_name": "fe", "param2": \1/' \
  "$T/curves.json" > "$T/curves-swap.json"
"$A" plot map "$T/single.map" --out "$T/swap.png" --curves "$T/curves-swap.json" --script "$T/swap.gp" 2> /dev/null; rc=$?
[ $rc -eq 0 ] && grep -q '"param_name": "z"' "$T/curves-swap.json" && [ "$(block lpc "$T/swap.gp")" = "$want_lpc" ] \
  && ok "plot map --curves in (z, fe) on an (fe, z) map: the same curves" \
  || bad "plot map --curves swapped: exit $rc [$(block lpc "$T/swap.gp" | tr '\n' '|')]"
# a second run's output appended: its curve 0 (a fold of a period-2 branch) is a curve of
# its own in $lpc2 (not joined to the first run's curve 0 at its start), $lpc unchanged
{
  cat "$T/curves.json"
  echo '{"type": "curve_point", "curve": 0, "kind": "LPC", "side": 0, "period": 2, "param_name": "fe", "param": 85000, "param2_name": "z", "param2": 2.4e-8}'
  echo '{"type": "curve_point", "curve": 0, "kind": "LPC", "side": 1, "period": 2, "param_name": "fe", "param": 85500, "param2_name": "z", "param2": 2.1e-8}'
  echo '{"type": "summary", "points": 2}'
} > "$T/curves-two.json"
"$A" plot map "$T/single.map" --out "$T/two.png" --curves "$T/curves-two.json" --script "$T/two.gp" 2> /dev/null; rc=$?
want_lpc2=$(printf '\n85 24\n\n85 24\n85.5 21')
[ $rc -eq 0 ] && [ "$(block lpc "$T/two.gp")" = "$want_lpc" ] && [ "$(block lpc2 "$T/two.gp")" = "$want_lpc2" ] \
  && [ "$(block pd "$T/two.gp")" = "$want_pd" ] && grep -q "\$lpc2 using 1:2 with lines" "$T/two.gp" \
  && ok "plot map --curves of two runs concatenated: the second run's period-2 fold a curve of its own (\$lpc2), drawn" \
  || bad "plot map --curves of two runs: exit $rc lpc [$(block lpc "$T/two.gp" | tr '\n' '|')] lpc2 [$(block lpc2 "$T/two.gp" | tr '\n' '|')]"
sed 's/"param2_name": "z"/"param2_name": "ae"/' "$T/curves.json" > "$T/curves-ae.json"
"$A" plot map "$T/single.map" --out "$T/x.png" --curves "$T/curves-ae.json" > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "the map is in (fe, z)" "$T/e.txt" && [ ! -e "$T/x.png" ] \
  && ok "plot map --curves in (fe, ae) on an (fe, z) map: exit 2: $(head -1 "$T/e.txt")" \
  || bad "plot map --curves of other parameters: exit $rc: $(head -1 "$T/e.txt")"
"$A" plot map "$T/single.map" --out "$T/x.png" --curves "$T/single.map" > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "not a record of" "$T/e.txt" \
  && ok "plot map --curves of a file that is no continue output: exit 2" \
  || bad "plot map --curves of a foreign file: exit $rc: $(head -1 "$T/e.txt")"
# the contour: every segment end lies on a grid edge where the peak force, interpolated
# linearly between the edge's two points, is F; every cell whose corners straddle F has a
# segment
cont_ok=$(python3 - "$T/over.gp" "$F_C" <<'PY'
import sys, math
lines = open(sys.argv[1]).read().split("\n")
F = float(sys.argv[2]) * 1e9
def block(name):
    i = lines.index("$%s << EOD" % name)
    return lines[i + 1:lines.index("EOD", i)]
grid = {}
for l in block("map"):
    f = l.split()
    if f:
        grid[(float(f[0]), float(f[1]))] = float(f[2]) if f[2] != "NaN" else math.nan
xs, ys = sorted({k[0] for k in grid}), sorted({k[1] for k in grid})
segs, cur = [], []
for l in block("cont"):
    if l.strip():
        cur.append(tuple(map(float, l.split())))
    elif cur:
        segs.append(cur)
        cur = []
if cur:
    segs.append(cur)
def crossing(a, b, t):
    return (a >= F) != (b >= F) and abs(a + t * (b - a) - F) < 1e-6 * F
def on_edge(x, y):
    for i in range(len(xs) - 1):
        for yy in ys:  # an edge along x at a grid y
            if abs(y - yy) < 1e-9 and xs[i] - 1e-9 <= x <= xs[i + 1] + 1e-9 and \
               crossing(grid[(xs[i], yy)], grid[(xs[i + 1], yy)], (x - xs[i]) / (xs[i + 1] - xs[i])):
                return True
    for j in range(len(ys) - 1):
        for xx in xs:  # an edge along y at a grid x
            if abs(x - xx) < 1e-9 and ys[j] - 1e-9 <= y <= ys[j + 1] + 1e-9 and \
               crossing(grid[(xx, ys[j])], grid[(xx, ys[j + 1])], (y - ys[j]) / (ys[j + 1] - ys[j])):
                return True
    return False
good = all(len(s) == 2 and all(on_edge(*p) for p in s) for s in segs)
cells = 0
for i in range(len(xs) - 1):
    for j in range(len(ys) - 1):
        c = [grid[(xs[i], ys[j])], grid[(xs[i + 1], ys[j])], grid[(xs[i + 1], ys[j + 1])],
             grid[(xs[i], ys[j + 1])]]
        if all(not math.isnan(v) for v in c) and len({v >= F for v in c}) == 2:
            cells += 1
            box = (xs[i] - 1e-9, xs[i + 1] + 1e-9, ys[j] - 1e-9, ys[j + 1] + 1e-9)
            if not any(all(box[0] <= p[0] <= box[1] and box[2] <= p[1] <= box[3] for p in s)
                       for s in segs):
                good = False
print("%s %d %d" % ("ok" if good and segs and cells else "bad", len(segs), cells))
PY
)
[ "${cont_ok%% *}" = ok ] && grep -q "\$cont using 1:2 with lines" "$T/over.gp" \
  && ok "plot map --contour-force 40 nN: $(echo "$cont_ok" | cut -d' ' -f2) segments, each end where the interpolated peak force is 40 nN, all $(echo "$cont_ok" | cut -d' ' -f3) straddling cells crossed" \
  || bad "plot map --contour-force: $cont_ok"

# ---- plan ----
"$A" plan --map "$T/single.map" --peak-force 60e-9 --imaging-force 40e-9 --top 3 > "$T/plan.txt" 2> "$T/e.txt"; rc=$?
[ $rc -eq 0 ] && [ "$(grep -c '^[0-9]*\. z ' "$T/plan.txt")" = 3 ] && grep -q "crosses: jump" "$T/plan.txt" \
  && ok "plan: 3 imaging / patterning pairs with their path and the jumps crossed: $(sed -n 2p "$T/plan.txt" | head -c 150)" \
  || bad "plan: exit $rc: $(head -3 "$T/plan.txt" "$T/e.txt")"
"$A" plan --map "$T/single.map" > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "required" "$T/e.txt" && ok "plan without --peak-force: exit 2" \
  || bad "plan without --peak-force: exit $rc"
"$A" plan --map "$T/single.map" --peak-force 1e-8 --imaging-force 2e-8 > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "must be below" "$T/e.txt" && ok "plan with the imaging force above the peak force: exit 2" \
  || bad "plan imaging > peak: exit $rc"
# ---- plan's top pair, checked by a separate sweep from the imaging to the patterning point ----
# `afmtwin sweep` from rest at the imaging point, stepping with the map's fe step to the
# patterning point (same config, Z, --max-periods): its first point must be the imaging
# orbit (peak force within the imaging limit), its last reach the patterning force and the
# map's peak force within 1 %, and the jumps between its steps (the map's criteria, read
# from the map's header) must be exactly the ones the plan names. Why 1 %: a settled orbit
# is the exact one to ~Q/pi tol of the deflection (Q 200, tol 1e-6: 6e-5 of ~21 nm, 1.4
# pm), and the peak force goes as indentation^1.5 (0.39 nm): 0.5 %; a period-2 orbit's last
# period (sweep's cycle) may also peak lower than the map's largest of its p periods.
"$A" plan --map "$T/single.map" --peak-force 60e-9 --imaging-force 40e-9 --top 1 > "$T/plan1.txt" 2> /dev/null
read -r pz pfi pfp pdir < <(sed -n 's/^1\. z \([0-9.]*\) nm: image at fe \([0-9.]*\) Hz.*pattern at fe \([0-9.]*\) Hz.*path: \([a-z]*\) pass.*/\1 \2 \3 \4/p' "$T/plan1.txt")
step=$(awk '$1 == "x" {print ($4 - $3) / ($5 - 1)}' "$T/single.map")
if [ -n "$pfp" ]; then
  "$A" sweep --config $CONF --z "${pz}e-9" --from "$pfi" --to "$pfp" --step "$step" --max-periods 1500 --json \
    > "$T/plan-sweep.json" 2> "$T/e.txt"
fi
plan_sw=$(python3 - "$T/plan1.txt" "$T/plan-sweep.json" "$T/single.map" 40e-9 60e-9 <<'PY'
import json, re, sys
plan = open(sys.argv[1]).read().split("\n")[1]
rows = [json.loads(l) for l in open(sys.argv[2]) if l.strip()]
imaging, patterning = float(sys.argv[4]), float(sys.argv[5])
hdr = {}
for l in open(sys.argv[3]):
    if l.startswith("tol "):
        f = l.split()
        hdr = dict(zip(f[0::2], map(float, f[1::2])))
m = re.search(r"pattern at fe \S+ Hz \(peak (\S+) N", plan)
want_peak = float(m.group(1))
named = {(float(a), float(b)) for a, b in re.findall(r"jump fe (\S+) -> (\S+) Hz", plan)}
def a1(o):
    h = [x for x in o["harmonics"] if x["k"] == 1][0]
    return h["deflection_amplitude_m"], h["phase_lag_deg"]
jumps = set()
for p, q in zip(rows, rows[1:]):
    (ap, lp), (aq, lq) = a1(p), a1(q)
    dl = abs(lp - lq) % 360
    if abs(ap - aq) > hdr["jump_tol"] * max(ap, aq) or min(dl, 360 - dl) > hdr["jump_deg"]:
        jumps.add((p["fe_hz"], q["fe_hz"]))
first, last = rows[0]["cycle"]["peak_force_n"], rows[-1]["cycle"]["peak_force_n"]
dev = abs(last - want_peak) / want_peak
good = (rows[0]["settled"] and rows[-1]["settled"] and first <= imaging and last >= patterning
        and dev <= 0.01 and jumps == named and len(named) > 0)
print("%s %d steps, imaging peak %.3g N, patterning peak %.5g N (plan %.5g N, %.2g %%), jumps %s (plan: %s)"
      % ("ok" if good else "bad", len(rows), first, last, want_peak, 100 * dev,
         sorted(jumps), sorted(named)))
PY
)
[ "${plan_sw%% *}" = ok ] \
  && ok "plan's top pair (z $pz nm, fe $pfi -> $pfp Hz, $pdir) by a sweep from the imaging point: ${plan_sw#ok }" \
  || bad "plan's top pair by sweep: $plan_sw $(head -2 "$T/e.txt")"
check_done
