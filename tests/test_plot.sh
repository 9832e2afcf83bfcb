#!/usr/bin/env bash
# test_plot.sh BUILD -- every `afmtwin plot` kind drawn from the example runs of
# tools/doc-plots.sh (the runs behind docs/img/): gnuplot succeeded, each output is a PNG of
# the requested size (signature and IHDR), its columns file has data, and bad input is refused
# with exit 2 (a file that is no LCM log given to `plot fm` named so). Then what makes a
# picture fit for a paper (issue 30), read off the gnuplot script each plot keeps (--script):
# no legend on the data, scan images at one scale in x and y ending at the pixels' edges with
# few x tics and colour bars with units, titles that name the config and the drive and not the
# input file, a CSV of each curve with units in its header; and on small hand-written inputs:
# the approach's force peaks clipped (repulsive >= 0, attractive <= 0) and its unsettled steps
# marked, its jump arrow from z_before to z_after (none for a crossover), E_sq beside E_ts, a
# continuation's branches cut at each change of stability (solid stable, dashed unstable).
# Needs no network. Prints "N passed, N failed".
BUILD=${1:-build}
. "$(dirname "$0")/lib_check.sh"
check_init plot "$BUILD"

if sh tools/doc-plots.sh "$BUILD" "$T" >"$T/log.txt" 2>&1; then
  ok "tools/doc-plots.sh: every example run and plot exited 0"
else
  bad "tools/doc-plots.sh failed: $(tail -3 "$T/log.txt")"
fi
# PNG: 8-byte signature, then the IHDR chunk with width and height (big-endian) at 16, 20
png_size() { od -An -tu1 -j16 -N8 "$1" | awk '{print $1*16777216+$2*65536+$3*256+$4 "x" $5*16777216+$6*65536+$7*256+$8}'; }
for k in sweep approach spectrum thermal trace scan continue force-curve; do
  f="$T/$k.png"
  sig=$(od -An -tx1 -N8 "$f" 2>/dev/null | tr -d ' \n')
  if [ "$sig" = "89504e470d0a1a0a" ] && [ "$(png_size "$f")" = "1000x750" ]; then
    ok "plot $k: a 1000x750 PNG ($(wc -c <"$f") bytes)"
  else
    bad "plot $k: not a 1000x750 PNG (signature '$sig', size '$(png_size "$f" 2>/dev/null)')"
  fi
  rows=$(grep -cv '^#\|^$' "$T/$k.dat" 2>/dev/null)
  [ "${rows:-0}" -ge 5 ] && ok "plot $k: columns file with $rows rows" || bad "plot $k: columns file has ${rows:-no} rows"
done
# the approach curve: a jump each way, marked in the columns
[ "$(grep -c '"jump"' "$T/approach.json")" -eq 2 ] && ok "approach example: a jump each way" \
  || bad "approach example: $(grep -c '"jump"' "$T/approach.json") jumps"
"$A" plot sweep "$T/approach.psd-missing" -o "$T/x.png" 2>"$T/e1.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "cannot open" "$T/e1.txt" && ok "a missing input: exit 2, 'cannot open'" \
  || bad "a missing input: exit $rc, $(cat "$T/e1.txt")"
"$A" plot thermal "$T/approach.json" -o "$T/x.png" 2>"$T/e2.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "is no PSD" "$T/e2.txt" && ok "JSON given as a PSD: exit 2, 'is no PSD'" \
  || bad "JSON given as a PSD: exit $rc, $(cat "$T/e2.txt")"
"$A" plot scan "$T/approach.json" -o "$T/x.png" 2>"$T/e5.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "without line or height_m" "$T/e5.txt" && ok "approach JSON as a scan: exit 2" \
  || bad "approach JSON as a scan: exit $rc, $(cat "$T/e5.txt")"
"$A" plot bogus "$T/approach.json" -o "$T/x.png" 2>"$T/e3.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "unknown kind" "$T/e3.txt" && ok "an unknown kind: exit 2" || bad "unknown kind: exit $rc"
"$A" plot sweep "$T/approach.json" -o "$T/x.png" 2>"$T/e4.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "without fe_hz" "$T/e4.txt" && ok "approach JSON as a sweep: exit 2" || bad "approach JSON as a sweep: exit $rc, $(cat "$T/e4.txt")"
"$A" plot fm "$T/approach.json" -o "$T/x.png" 2>"$T/e7.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "approach.json: not an LCM log (no LCM event in its [0-9]* bytes)" "$T/e7.txt" \
  && ok "JSON given to plot fm: exit 2, 'not an LCM log'" || bad "JSON given to plot fm: exit $rc, $(cat "$T/e7.txt")"
: > "$T/empty.log"
"$A" plot fm "$T/empty.log" -o "$T/x.png" 2>"$T/e8.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "empty.log: not an LCM log (no LCM event in its 0 bytes)" "$T/e8.txt" \
  && ok "an empty file given to plot fm: exit 2, 'not an LCM log'" || bad "an empty file given to plot fm: exit $rc, $(cat "$T/e8.txt")"
"$A" plot trace "$T/approach.json" -o "$T/x.png" 2>"$T/e9.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "approach.json: not an LCM log (no LCM event in its [0-9]* bytes)" "$T/e9.txt" \
  && ok "JSON given to plot trace: exit 2, 'not an LCM log'" || bad "JSON given to plot trace: exit $rc, $(cat "$T/e9.txt")"
"$A" plot trace "$T/empty.log" -o "$T/x.png" 2>"$T/e10.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "empty.log: not an LCM log (no LCM event in its 0 bytes)" "$T/e10.txt" \
  && ok "an empty file given to plot trace: exit 2, 'not an LCM log'" || bad "an empty file given to plot trace: exit $rc, $(cat "$T/e10.txt")"
"$A" plot continue "$T/continue.json" 2>"$T/e6.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "\-o FILE.png is required" "$T/e6.txt" && ok "no -o: exit 2, '-o FILE.png is required'" \
  || bad "no -o: exit $rc, $(cat "$T/e6.txt")"
# ---- issue 30: plots fit for a paper ----
# 1. legends: before every plot command the key is outside the panels (at screen, outside,
# a margin) or off; gnuplot's default key (inside, top right) counts as on the data
key_outside() {
  awk '/^set key/ { st = ($0 ~ /outside|at screen|[tblr]margin/) ? "out" : "in"; keys++ }
       /^unset key/ { st = "off" }
       /^plot / { n++; if (st == "" || st == "in") bad++ }
       END { if (n == 0 || keys == 0 || bad > 0) { print n + 0, "plots,", bad + 0, "with a key on the data"; exit 1 } }' "$1"
}
for k in sweep approach spectrum thermal trace scan continue force-curve; do
  if why=$(key_outside "$T/$k.gp" 2>&1); then ok "plot $k: every legend outside the data"
  else bad "plot $k: a legend on the data ($why)"; fi
done
# 2. scan images: size ratio -1, autoscale fix, the axes at the pixels' edges (the plot
# area's aspect that of the x and y ranges: square nm), at most 6 x tic labels, a colour
# bar label with its unit
scan_images() {
  awk -v W=1000 -v H=750 '
    /^set lmargin at screen/ { l = $5 } /^set rmargin at screen/ { r = $5 }
    /^set bmargin at screen/ { b = $5 } /^set tmargin at screen/ { t = $5 }
    /^set size ratio -1/ { ratio = 1 } /^set size noratio/ { ratio = 0 }
    /^set autoscale fix/ { fix = 1 }
    /^set xrange \[/ { split(substr($3, 2, length($3) - 2), a, ":"); x0 = a[1]; x1 = a[2] }
    /^set yrange \[/ { split(substr($3, 2, length($3) - 2), a, ":"); y0 = a[1]; y1 = a[2] }
    /^set xtics [0-9.e+-]+$/ { xs = $3 }
    /^set cblabel / { cb = $0 }
    /^plot .*with image/ {
      n++
      if (!ratio) { print "no size ratio -1"; e++ }
      if (!fix) { print "no autoscale fix"; e++ }
      if (cb !~ /\(.+\)/) { print "colour bar without unit: " cb; e++ }
      if (xs <= 0 || (x1 - x0) / xs + 1 > 6.01) { print "x tics every " xs " over " x1 - x0; e++ }
      asp = ((t - b) * H) / ((r - l) * W); want = (y1 - y0) / (x1 - x0)
      if (asp / want > 1.02 || want / asp > 1.02) { print "aspect " asp " for ranges " want; e++ }
    }
    END { if (n != 4) { print n + 0, "images"; e++ } exit e > 0 }' "$1"
}
if why=$(scan_images "$T/scan.gp" 2>&1); then
  ok "plot scan: 4 images at one scale, pixel-true axes, few x tics, colour bars with units"
else bad "plot scan images: $(echo $why)"; fi
# 6. titles: the config and the drive, never the input file's name
title_of() { grep -m1 '^set multiplot title' "$1"; }
t=$(title_of "$T/sweep.gp")
case "$t" in
  *"thesis-1dof.conf: f0 300 kHz, Q 100, k 40 N/m; drive fe 295-305 kHz, Ae 200 pm"*)
    ok "sweep title: config, f0, Q, k and the drive" ;;
  *) bad "sweep title: $t" ;;
esac
t=$(title_of "$T/approach.gp")
case "$t" in
  *"probe-q300.conf: f0 300 kHz, Q 300"*"fe 300 kHz, Ae 66.67 pm, A0 20 nm; Z 4-22 nm"*)
    ok "approach title: config, f0, Q and the drive (A0 from the records)" ;;
  *) bad "approach title: $t" ;;
esac
if grep -l 'sweep-fwd\|sweep-bwd\|approach\.json\|scan\.json\|continue\.json\|thermal\.psd' \
  "$T"/*.gp >"$T/names.txt"; then bad "input file names in the pictures: $(cat "$T/names.txt")"
else ok "no picture names its input file"; fi
# 7. the CSV of every picture: a header of names with units, as many fields on every line
csv_ok() {
  awk -F, 'NR == 1 { n = NF; for (i = 1; i <= NF; i++) if ($i !~ /^[^()]+ \(.+\)$/) e = e " " $i; next }
           NF != n { rows_bad++ } { rows++ }
           END { if (e != "" || rows_bad || rows < 3) { print "header" e ", rows " rows + 0 ", bad rows " rows_bad + 0; exit 1 } }' "$1"
}
for k in sweep approach spectrum thermal trace scan continue force-curve; do
  if why=$(csv_ok "$T/$k.csv" 2>&1); then ok "plot $k --csv: $(head -1 "$T/$k.csv" | cut -c1-60)..."
  else bad "plot $k --csv: $why"; fi
done

# force-curve: snap-in and pull-off marked (set E: event 1 and 2), the adhesion in the title
ev=$(awk '/^# E/ {e = 1; next} /^#/ {e = 0} e && NF == 3 {n[$3]++} END {print n[1] + 0, n[2] + 0}' "$T/force-curve.dat")
[ "$ev" = "1 1" ] && grep -q 'adhesion (force at pull-off) -3.7[0-9]* nN' "$T/force-curve.gp" &&
  ok "plot force-curve: snap-in and pull-off marked, the adhesion in the title" ||
  bad "plot force-curve: events '$ev' (want '1 1'), title: $(grep -m1 'multiplot title' "$T/force-curve.gp")"

# ---- hand-written inputs ----
cat >"$T/zz-input-name.json" <<'END'
{"fe_hz":299000,"periodicity":1,"settled":true,"min_deflection_m":-5e-9,"max_deflection_m":5e-9,"max_force_n":-1e-13,"lockin":{"phase_deg":40}}
{"fe_hz":300000,"periodicity":0,"settled":false,"min_deflection_m":-6e-9,"max_deflection_m":6e-9,"max_force_n":2e-9,"lockin":{"phase_deg":50}}
{"fe_hz":301000,"periodicity":2,"settled":true,"min_deflection_m":-7e-9,"max_deflection_m":7e-9,"max_force_n":3e-9,"lockin":{"phase_deg":60}}
END
"$A" plot sweep "$T/zz-input-name.json" --config config/thesis-1dof.conf -o "$T/h1.png" \
  --csv "$T/h1.csv" --data "$T/h1d.csv" --script "$T/h1.gp" 2>"$T/h1.err"; rc=$?
if [ $rc -eq 0 ] && [ "$(head -1 "$T/h1.csv")" = "fe (kHz),amplitude (nm),lag (deg),max_force (nN),periodicity (periods),settled (0/1),dissipated (eV),squeeze_dissipated (eV)" ] \
  && [ "$(sed -n 2p "$T/h1.csv")" = "299,5,40,-0.0001,1,1,nan,nan" ] && [ "$(wc -l <"$T/h1.csv")" -eq 4 ] \
  && cmp -s "$T/h1.csv" "$T/h1d.csv"; then
  ok "plot sweep --csv (and --data FILE.csv): a header of names with units, one line per step"
else bad "plot sweep --csv: exit $rc, $(head -2 "$T/h1.csv" 2>/dev/null | tr '\n' '|') $(cat "$T/h1.err")"; fi
if grep -q 'zz-input-name' "$T/h1.gp" 2>/dev/null; then bad "the input's name is in the sweep picture"
elif title_of "$T/h1.gp" 2>/dev/null | grep -q 'thesis-1dof.conf: f0 300 kHz, Q 100, k 40 N/m; drive fe 299-301 kHz, Ae 200 pm; Z 14 nm'; then
  ok "a sweep of zz-input-name.json: titled by its config and drive, not by the file"
else bad "sweep title: $(title_of "$T/h1.gp" 2>&1)"; fi
"$A" plot --help | grep -q -- '--csv FILE' && ok "plot --help documents --csv" || bad "plot --help: no --csv"

# the approach: an attractive step (max force < 0), an unsettled one, a jump between 19
# and 18 nm, two repulsive steps
cat >"$T/ap.json" <<'END'
{"z_m":2e-08,"direction":"approach","amplitude_m":1.98e-08,"phase_lag_deg":97,"peak_force_n":-1e-13,"attractive_force_n":-4.5e-09,"dissipated_energy_j":1e-22,"indentation_m":0,"periodicity":1,"settled":true,"free_amplitude_m":2e-08,"free_phase_lag_deg":90,"harmonics":[{"k":1,"amplitude_m":1.98e-08}]}
{"z_m":1.9e-08,"direction":"approach","amplitude_m":1.91e-08,"phase_lag_deg":107,"peak_force_n":-2e-13,"attractive_force_n":-5.9e-09,"dissipated_energy_j":2e-22,"indentation_m":0,"periodicity":0,"settled":false,"free_amplitude_m":2e-08,"free_phase_lag_deg":90,"harmonics":[{"k":1,"amplitude_m":1.91e-08}]}
{"jump":{"direction":"approach","from":"attractive","to":"repulsive","z_before_m":1.9e-08,"z_after_m":1.8e-08,"amplitude_before_m":1.91e-08,"amplitude_after_m":1.99e-08,"phase_before_deg":107,"phase_after_deg":84}}
{"z_m":1.8e-08,"direction":"approach","amplitude_m":1.99e-08,"phase_lag_deg":84,"peak_force_n":6.2e-09,"attractive_force_n":-5.4e-09,"dissipated_energy_j":3e-22,"indentation_m":1e-10,"periodicity":1,"settled":true,"free_amplitude_m":2e-08,"free_phase_lag_deg":90,"harmonics":[{"k":1,"amplitude_m":1.99e-08}]}
{"z_m":1.7e-08,"direction":"approach","amplitude_m":1.91e-08,"phase_lag_deg":73,"peak_force_n":8.7e-09,"attractive_force_n":-4.8e-09,"dissipated_energy_j":4e-22,"indentation_m":2e-10,"periodicity":1,"settled":true,"free_amplitude_m":2e-08,"free_phase_lag_deg":90,"harmonics":[{"k":1,"amplitude_m":1.91e-08}]}
END
"$A" plot approach "$T/ap.json" -o "$T/ap.png" --csv "$T/ap.csv" --script "$T/ap.gp" 2>"$T/ap.err"; rc=$?
# 3a. the repulsive peak max(F, 0) and the attractive peak min(F, 0): no negative force
# drawn as repulsive
rep=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) { if ($i ~ /^repulsive_peak/) r = i; if ($i ~ /^attractive_peak/) a = i } next }
  r && a { printf "%s/%s ", $r, $a }' "$T/ap.csv" 2>/dev/null)
if [ $rc -eq 0 ] && [ "$rep" = "0/-4.5 0/-5.9 6.2/-5.4 8.7/-4.8 " ] \
  && grep -q "keyentry .*title 'force: attractive peak min(F, 0)'" "$T/ap.gp" \
  && ! grep -q "peak repulsive force" "$T/ap.gp"; then
  ok "approach forces: the repulsive peak clipped at 0, the attractive peak drawn apart ($rep)"
else bad "approach forces: exit $rc, repulsive/attractive '$rep' $(cat "$T/ap.err")"; fi
# 3b. the unsettled step (Z 19 nm) marked on every panel, the marker in the legend
um=$(awk '/^\$UM << EOD/ { f = 1; next } /^EOD/ { f = 0 } f { print $1 }' "$T/ap.gp" 2>/dev/null | tr '\n' ' ')
if [ "$um" = "19 " ] && [ "$(grep -c '^plot .*\$UM using 1:[0-9]* with points ls 12' "$T/ap.gp")" -eq 4 ] \
  && grep -q "keyentry with points ls 12 title 'not settled" "$T/ap.gp"; then
  ok "approach: the unsettled step marked on all 4 panels and explained in the legend"
else bad "approach unsettled marks: '$um', $(grep -c '\$UM' "$T/ap.gp" 2>/dev/null) uses"; fi
# 5. the jump arrow from (z_before, A before) to (z_after, A after), not at the midpoint
jr=$(awk '/^\$J << EOD/ { f = 1; next } /^EOD/ { f = 0 } f' "$T/ap.gp" 2>/dev/null)
if [ "$jr" = "19 18 19.1 19.9 107 84 0 1" ] \
  && grep -q '\$J using 1:(\$7 == 0 && \$8 == 1 ? \$3 : 1/0):(\$2 - \$1):(\$4 - \$3) with vectors' "$T/ap.gp"; then
  ok "approach jump arrow: from Z 19 nm (A 19.1) to Z 18 nm (A 19.9), where the branch changes"
else bad "approach jump: '$jr'"; fi
# 6. a change of regime without a jump of the branch (sharp false): no arrow, no legend entry
sed 's/"phase_after_deg":84}/"phase_after_deg":84,"sharp":false}/' "$T/ap.json" >"$T/ap2.json"
"$A" plot approach "$T/ap2.json" -o "$T/ap2.png" --script "$T/ap2.gp" 2>/dev/null; rc=$?
if [ $rc -eq 0 ] && ! grep -q "keyentry with vectors" "$T/ap2.gp" \
  && [ "$(awk '/^\$J << EOD/ { f = 1; next } /^EOD/ { f = 0 } f' "$T/ap2.gp")" = "19 18 19.1 19.9 107 84 0 0" ]; then
  ok "approach: a crossover (sharp false) is in the data but drawn as no jump"
else bad "approach crossover: exit $rc, $(grep -c 'keyentry with vectors' "$T/ap2.gp") jump keys"; fi
# 7. the squeeze film's dissipation E_sq beside E_ts (issue 30): its own panel under E_ts
# where a record has it, named in the title's note, a column in the data; none without it
sed 's/"dissipated_energy_j":\([0-9e.-]*\),/"dissipated_energy_j":\1,"squeeze_dissipated_energy_j":9.613059804e-17,/' \
  "$T/ap.json" >"$T/ap3.json"
"$A" plot approach "$T/ap3.json" -o "$T/ap3.png" --script "$T/ap3.gp" --data "$T/ap3.dat" 2>/dev/null; rc=$?
if [ $rc -eq 0 ] && grep -q "^set ylabel 'E_sq (eV)'" "$T/ap3.gp" && grep -q "^set ylabel 'E_ts (eV)'" "$T/ap3.gp" \
  && grep -q '^plot \$A using 1:13 ' "$T/ap3.gp" && grep -q 'E_sq by the squeeze film' "$T/ap3.gp" \
  && grep -q '^# A (approach): .* squeeze_dissipated\[eV\]' "$T/ap3.dat" \
  && [ "$(awk '/^\$A << EOD/ { f = 1; next } /^EOD/ { f = 0 } f { print $13; exit }' "$T/ap3.gp")" = 600 ] \
  && ! grep -q "E_sq" "$T/ap.gp"; then
  ok "approach: E_sq (squeeze film, 600 eV) in a panel of its own under E_ts, explained; absent without it"
else bad "approach E_sq: exit $rc, $(grep -c "E_sq" "$T/ap3.gp" 2>/dev/null) E_sq lines"; fi
if grep -q "^set ylabel 'E_ts tip-sample (eV)'" "$T/sweep.gp" && grep -q '^# S0 .*: .*dissipated\[eV\] squeeze_dissipated\[eV\]' "$T/sweep.dat" \
  && ! grep -q "E_sq" "$T/sweep.gp"; then
  ok "sweep: an E_ts panel (tip-sample energy per period), no E_sq panel on a config without a squeeze film"
else bad "sweep energies: $(grep -c 'E_ts' "$T/sweep.gp" 2>/dev/null) E_ts lines, $(sed -n 3p "$T/sweep.dat" | cut -c1-120)"; fi

# 4. a continuation: stable up to a PD at 81.5 kHz, unstable, stable again after 83 kHz
# with no event between (the largest multiplier 1.5 -> 0.5: crosses 1 half way, 83.5 kHz)
pt() { printf '{"type":"%s","param_name":"fe","branch":0,"parent":-1,"param":%s,"period":1,"stable":%s,"min_deflection_m":%s,"amplitude_m":%s,"multipliers":[[%s,0],[0.1,0]]}\n' "$@"; }
{ pt point 80000 true -3.0e-8 3.0e-8 0.5; pt point 81000 true -3.1e-8 3.1e-8 0.9
  pt PD 81500 true -3.15e-8 3.15e-8 -1.0; pt point 82000 false -3.2e-8 3.2e-8 -1.22
  pt point 83000 false -3.3e-8 3.3e-8 -1.5; pt point 84000 true -3.4e-8 3.4e-8 0.5
  echo '{"type":"end","param_name":"fe","branch":0,"parent":-1,"param":84000,"period":1,"points":5,"reason":"end"}'
} >"$T/cont.json"
"$A" plot continue "$T/cont.json" -o "$T/cont.png" --script "$T/cont.gp" 2>"$T/cont.err"; rc=$?
# the segments of $B (blank-line separated): solid or dashed, and their parameters
segs=$(awk '/^\$B << EOD/ { f = 1; next }
  f && (/^EOD/ || NF == 0) { if (n) printf "%s ", s; n = 0; if (/^EOD/) f = 0; next }
  f { s = n ? s "," $1 : ($4 == 1 ? "solid:" : "dashed:") $1; if (n && $4 != st) s = s "!"; st = $4; n++ }' \
  "$T/cont.gp" 2>/dev/null)
if [ $rc -eq 0 ] && [ "$segs" = "solid:80,81,81.5 dashed:81.5,82,83,83.5 solid:83.5,84 " ] \
  && grep -q '\$B using 1:(\$4 == 1 && \$5 == 0 ? \$2 : 1/0) with lines ls 21 notitle' "$T/cont.gp" \
  && grep -q '\$B using 1:(\$4 == 0 && \$5 == 0 ? \$2 : 1/0) with lines ls 22 notitle' "$T/cont.gp" \
  && grep -q "^set style line 22 .* dt 2" "$T/cont.gp" && ! grep -q "^set style line 21 .* dt " "$T/cont.gp"; then
  ok "continue: cut at the PD (81.5 kHz) and where |mu| crosses 1 (83.5 kHz), both segments sharing the point"
else bad "continue segments: exit $rc, '$segs' $(cat "$T/cont.err")"; fi
# 4b. zoom (issue: fig 4.2's period-2 branches squeezed into 1 nm of 6 kHz): --xrange 81:83
# draws that window in both panels, each y fitted to the branch points inside it (min(xr)
# -33..-31 nm, amplitude 31..33 nm, plus 4 % below and 2 % above: [-33.08:-30.96] and
# [30.92:33.04]); --yrange and --yrange2 fix a panel's y; --data is the same bytes with or
# without a zoom (the one label keeps row 0); bad ranges and a range for another kind refused
"$A" plot continue "$T/cont.json" -o "$T/cz.png" --script "$T/cz.gp" --data "$T/cz.dat" \
  --xrange 81:83 2>"$T/cz.err"; rc=$?
"$A" plot continue "$T/cont.json" -o "$T/cz2.png" --script "$T/cz2.gp" --data "$T/cz0.dat" \
  --yrange -32.5:-31.5 --yrange2 30:35 2>>"$T/cz.err"; rc2=$?
"$A" plot continue "$T/cont.json" -o "$T/cz3.png" --data "$T/cz3.dat" 2>>"$T/cz.err"
# (the legend's own empty plot sets [0:1])
yr=$(grep '^set [xy]range ' "$T/cz.gp" | grep -v '\[0:1\]' | tr '\n' ' ')
yr2=$(grep '^set yrange ' "$T/cz2.gp" | grep -v '\[0:1\]' | tr '\n' ' ')
if [ $rc -eq 0 ] && [ $rc2 -eq 0 ] \
  && [ "$yr" = "set xrange [81:83] set yrange [-33.08:-30.96] set xrange [81:83] set yrange [30.92:33.04] " ] \
  && [ "$yr2" = "set yrange [-32.5:-31.5] set yrange [30:35] " ] \
  && cmp -s "$T/cz.dat" "$T/cz3.dat" && cmp -s "$T/cz0.dat" "$T/cz3.dat"; then
  ok "continue --xrange 81:83: both panels zoomed, y fitted to the window; --yrange/--yrange2 fix y; --data unchanged"
else bad "continue zoom: exit $rc/$rc2, '$yr' '$yr2' $(cat "$T/cz.err")"; fi
# each refused with exit 2 and its own reason (not as an unknown option)
n2=0
for a in "--xrange 83:81" "--xrange 81" "--yrange 1:x" "--xrange 90:95"; do
  # shellcheck disable=SC2086
  "$A" plot continue "$T/cont.json" -o "$T/czb.png" $a 2>"$T/czb.err"
  [ $? -eq 2 ] && grep -q 'LO:HI, LO < HI\|no point of the branches in --xrange' "$T/czb.err" && n2=$((n2 + 1))
done
"$A" plot sweep "$T/sweep-fwd.json" -o "$T/czs.png" --xrange 81:83 2>"$T/czb.err"
[ $? -eq 2 ] && grep -q "continue's options" "$T/czb.err" && n2=$((n2 + 1))
[ $n2 -eq 5 ] && ok "continue zoom: LO >= HI, no colon, no number, a window with no point, and sweep --xrange refused (exit 2, said why)" \
  || bad "continue zoom: $n2 of 5 bad ranges refused with exit 2 and a reason"
# the legend: short, a PD branch named by the label of its PD (P1) (the old legend's
# 'b1 (period 2): PD of b0 at 81.5 kHz' and 'stable (any branch)' were longer)
{ cat "$T/cont.json"
  echo '{"type":"branch","param_name":"fe","branch":1,"parent":0,"param":81500,"period":2,"via":"PD","via_param":81500}'
  printf '{"type":"point","param_name":"fe","branch":1,"parent":0,"param":%s,"period":2,"stable":true,"min_deflection_m":%s,"amplitude_m":3.2e-8}\n' \
    81500 -3.15e-8 82000 -3.3e-8 83000 -3.4e-8
} >"$T/cl.json"
"$A" plot continue "$T/cl.json" -o "$T/cl.png" --script "$T/cl.gp" 2>"$T/cl.err"; rc=$?
if [ $rc -eq 0 ] && grep -q "keyentry with lines ls 23 title 'b1 (period 2): P1 of b0'" "$T/cl.gp" \
  && grep -q "keyentry with lines ls 21 title 'b0 (period 1)'" "$T/cl.gp" \
  && grep -q "keyentry .* title 'stable'" "$T/cl.gp" && grep -q 'maxrows 3 ' "$T/cl.gp"; then
  ok "continue legend: 'b1 (period 2): P1 of b0' (the PD's own label), 5 entries in 2 columns of 3 rows"
else bad "continue legend: exit $rc, $(grep -o "maxrows [0-9]*\|title '[^']*'" "$T/cl.gp" | tr '\n' ' ') $(cat "$T/cl.err")"; fi
# --zoom-pd: the window of the period-2 branch alone (b1: 81.5..83 kHz, min(xr) -34..-31.5
# nm): x [81.5 - 0.045 : 83 + 0.045] (3 %), y [-34 - 0.1 : -31.5 + 2.2 * 0.09 * 2.5 + 0.05]
# (its P1 label's row 0 over it); the period-1 points from 80 to 84 kHz clipped
"$A" plot continue "$T/cl.json" -o "$T/cpd.png" --script "$T/cpd.gp" --zoom-pd 2>"$T/cpd.err"; rc=$?
zr=$(grep '^set [xy]range ' "$T/cpd.gp" | grep -v '\[0:1\]' | head -2 | tr '\n' ' ')
if [ $rc -eq 0 ] && [ "$zr" = "set xrange [81.455:83.045] set yrange [-34.1:-30.955] " ]; then
  ok "continue --zoom-pd: x and y of the period-2 branch ($zr)"
else bad "continue --zoom-pd: exit $rc, '$zr' $(cat "$T/cpd.err")"; fi
# 5. bifurcation labels that do not overlap (issue 30: fig 4.2's "P2P6" ran together, and
# L3/L5/L7 stood in a column over a cluster): two PDs 130 Hz apart and four events within
# 100 Hz, as in fig 4.2 (6 kHz wide, ~2.7 characters of a label per 130 Hz). Each label is
# drawn one character right of its point on row label_row ($E's column 6); two labels of
# points closer than a label's width (3 characters: 200 Hz) at about the same height must
# take different rows, and a label above the first row has a leader down to its point.
{ pt point 80000 true -3.1e-8 3.1e-8 0.5; pt point 82000 true -3.12e-8 3.2e-8 0.6
  pt PD 83100 true -3.13e-8 3.27e-8 -1.0; pt PD 83230 true -3.13e-8 3.22e-8 -1.0
  pt point 84000 true -3.14e-8 3.3e-8 0.8; pt LPC 84400 true -3.16e-8 3.3e-8 1.0
  pt PD 84410 true -3.14e-8 3.3e-8 -1.0; pt LPC 84420 true -3.17e-8 3.31e-8 1.0
  pt LPC 84450 true -3.18e-8 3.32e-8 1.0; pt point 86000 true -0.85e-8 0.85e-8 0.5
  echo '{"type":"end","param_name":"fe","branch":0,"parent":-1,"param":86000,"period":1,"points":5,"reason":"end"}'
} >"$T/lab.json"
"$A" plot continue "$T/lab.json" -o "$T/lab.png" --script "$T/lab.gp" 2>"$T/lab.err"; rc=$?
lab=$(awk 'BEGIN { n = 0 } /^\$E << EOD/ { f = 1; next } f && /^EOD/ { f = 0 } f && NF >= 6 { x[n] = $1; r[n] = $6; n++ }
  END { for (i = 0; i < n; i++) for (j = 0; j < i; j++) { d = x[i] - x[j]; if (d < 0) d = -d
          if (d < 0.2 && r[i] == r[j]) { printf "clash:%s/%s ", x[j], x[i]; bad = 1 } }
        for (i = 0; i < n; i++) printf "%s:%s ", x[i], r[i]; exit bad }' "$T/lab.gp"); lrc=$?
if [ $rc -eq 0 ] && [ $lrc -eq 0 ] && grep -q 'with vectors nohead' "$T/lab.gp"; then
  ok "continue: labels of near points on rows of their own, with leaders (fe kHz:row $lab)"
else bad "continue labels: exit $rc, $lab $(cat "$T/lab.err")"; fi
# ---- issue 30: traces that say what the stream can show ----
# the trace of tools/doc-plots.sh (stream 0 of default.conf: 878.75 kHz, 2.6 samples per
# drive period): the rate and the low-pass on the picture and in the data, points only
t=$(title_of "$T/trace.gp")
case "$t" in
  *"stream 0: 878.75 kHz (decimation 16), 2.6 samples per drive period: points"*"low-pass 351.5 kHz, -80 dB from 527.25 kHz"*)
    ok "trace title: the stream's rate, samples per period and low-pass" ;;
  *) bad "trace title: $t" ;;
esac
if grep -q '^plot \$T.* with \(lines\|linespoints\)' "$T/trace.gp"; then
  bad "trace: samples 2.6 per period joined by lines: $(grep -m1 '^plot \$T' "$T/trace.gp")"
elif grep -q '^plot \$T using 1:4 with points' "$T/trace.gp" \
  && grep -q "keyentry with points ls 4 title 'tip-sample force, low-pass 351.5 kHz'" "$T/trace.gp"; then
  ok "trace: 2.6 samples per period drawn as points, the force's legend names its low-pass"
else bad "trace plot commands: $(grep '^plot \$T' "$T/trace.gp" | head -1)"; fi
if grep -q '^# stream 0: 878.75 kHz' "$T/trace.dat" \
  && grep -q '^# every channel (force too) low-pass 351.5 kHz' "$T/trace.dat" \
  && head -1 "$T/trace.csv" | grep -q ',rate (Hz),passband (Hz)$' \
  && [ "$(sed -n 2p "$T/trace.csv" | awk -F, '{print $(NF-1), $NF}')" = "878750 351500" ]; then
  ok "trace --data and --csv: the stream's rate and passband (878750 Hz, 351500 Hz)"
else bad "trace data: $(head -3 "$T/trace.dat" | tr '\n' '|') csv $(head -2 "$T/trace.csv" | tr '\n' '|')"; fi
"$A" listen --log "$T/out.log" --count 200 2>/dev/null | grep -m1 '^samples .* stream 0 ' >"$T/ls.txt"
grep -q 'rate 878750 Hz, low-pass 351500 Hz, -80 dB from 527250 Hz' "$T/ls.txt" \
  && ok "listen: a samples message states its low-pass" || bad "listen samples line: $(cat "$T/ls.txt")"
# lost messages: the log without its samples messages 60..99 (perl: Debian's perl-base)
perl -e '($f, $t) = @ARGV; binmode STDIN; binmode STDOUT; $k = 0;
  while (read(STDIN, $h, 28) == 28) { ($cl, $dl) = unpack("x20 N N", $h);
    read(STDIN, $c, $cl); read(STDIN, $d, $dl);
    if ($c =~ /SAMPLES$/) { $i = $k++; next if $i >= $f && $i < $t } print $h, $c, $d }' \
  60 100 <"$T/out.log" >"$T/gap.log"
"$A" plot trace "$T/gap.log" --from 0.003 --to 0.00302 -o "$T/g1.png" 2>"$T/g1.err"; rc=$?
if [ $rc -eq 2 ] && grep -q 'the window 3.000000..3.020000 ms falls in a gap of lost messages: 40 samples messages (msg_seq 60 to 99)' "$T/g1.err"; then
  ok "trace: a window in lost messages is named a gap, with its msg_seq"
else bad "trace in a gap: exit $rc, $(cat "$T/g1.err")"; fi
"$A" plot trace "$T/gap.log" --from 0.002 --to 0.0038 -o "$T/g2.png" --script "$T/g2.gp" \
  --data "$T/g2.dat" 2>"$T/g2.err"; rc=$?
runs=$(awk '/^# T:/ { f = 1; next } f && NF { r[$7] = 1 } END { print length(r) }' "$T/g2.dat" 2>/dev/null)
if [ $rc -eq 0 ] && grep -q '^set object .* rect from 2.166' "$T/g2.gp" \
  && grep -q "title 'lost messages (msg_seq 60 to 99)'" "$T/g2.gp" && [ "$runs" = 2 ]; then
  ok "trace across lost messages: the gap shaded and named, the samples in 2 runs"
else bad "trace across a gap: exit $rc, runs $runs, $(grep -c '^set object' "$T/g2.gp" 2>/dev/null) objects, $(cat "$T/g2.err")"; fi
# the filter's delay is taken off the sample times, which puts its first (start-up) samples
# before the run's start: not drawn, and the time axis says so; the first row within one
# stream sample (1.138 us) after 0, where the run starts
"$A" plot trace "$T/out.log" -o "$T/t0.png" --script "$T/t0.gp" --data "$T/t0.dat" 2>"$T/t0.err"; rc=$?
t_first=$(awk '/^# T:/ { f = 1; next } f && NF { print $1; exit }' "$T/t0.dat" 2>/dev/null)
if [ $rc -eq 0 ] && awk -v t="${t_first:--1}" 'BEGIN { exit !(t >= 0 && t < 1.138e-3) }' \
  && grep -q "xlabel 'model time (ms), less the 1[0-9.]* us delay of the filter (its [0-9]* samples before 0 not drawn)'" "$T/t0.gp"; then
  ok "trace: no samples before the start (first at $t_first ms), the axis names the filter's delay"
else bad "trace start: exit $rc, first row $t_first ms, $(grep -m1 xlabel "$T/t0.gp") $(cat "$T/t0.err")"; fi
check_done
