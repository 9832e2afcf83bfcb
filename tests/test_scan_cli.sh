#!/usr/bin/env bash
# test_scan_cli.sh BUILD -- `afmtwin scan` as a user meets it (issue 18): --help, the text
# table's phase convention, the JSON keys of a pixel, and clear errors (exit 2) for bad
# options, bad values and a config without a sample group (a warning, then a flat scan);
# --gsf (issue 30): the Gwyddion Simple Field files, their headers, a pixel of each read back
# with od against the JSON of the same scan, and Gwyddion's own reader (gwyddion-thumbnailer,
# package gwyddion: make deps) taking every file and refusing a truncated one.
# Prints "N passed, N failed".
. "$(dirname "$0")/lib_check.sh"
check_init scan-cli "${1:-build}"
"$A" scan --help > "$T/help.txt"; rc=$?
[ $rc -eq 0 ] && grep -q "lag of the deflection behind the drive" "$T/help.txt" \
  && ok "scan --help: exit 0, states the phase convention" || bad "scan --help (exit $rc)"
"$A" scan --config config/scan-grating.conf --pixels 8 --line-rate 100 --engage 0.002 \
  > "$T/t.txt" 2> "$T/t.err"; rc=$?
n=$(grep -vc '^#' "$T/t.txt")
[ $rc -eq 0 ] && [ "$n" -eq 16 ] && grep -q "^#.*90 deg free at resonance" "$T/t.txt" \
  && ok "scan: 8 trace + 8 retrace rows, header with the phase convention" \
  || bad "scan text: exit $rc, $n rows: $(head -c 300 "$T/t.err")"
"$A" scan --config config/scan-grating.conf --pixels 4 --line-rate 200 --engage 0.002 --json \
  > "$T/j.txt"; rc=$?
keys_ok=1
for k in line pixel retrace x_m y_m true_height_m material height_m z_m amplitude_m error_m \
         phase_lag_deg peak_force_n dissipated_energy_j periods free_amplitude_m; do
  grep -q "\"$k\":" "$T/j.txt" || { keys_ok=0; echo "     missing $k"; }
done
[ $rc -eq 0 ] && [ $keys_ok -eq 1 ] && [ "$(wc -l < "$T/j.txt")" -eq 8 ] \
  && ok "scan --json: one object per pixel with every key" || bad "scan --json (exit $rc)"
for args in "--pixels 1" "--line-rate 0" "--setpoint 1.2" "--ki -1" "--size-x nan" \
            "--frobnicate 3" "--pixels 2.5"; do
  "$A" scan --config config/scan-grating.conf $args > /dev/null 2> "$T/e.txt"; rc=$?
  [ $rc -eq 2 ] && [ -s "$T/e.txt" ] && ok "scan $args: exit 2: $(head -1 "$T/e.txt")" \
    || bad "scan $args: exit $rc"
done
"$A" scan > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "config is required" "$T/e.txt" && ok "scan without --config: exit 2" \
  || bad "scan without --config: exit $rc"
"$A" scan --config config/probe-q300.conf --pixels 4 --line-rate 200 --engage 0.002 \
  > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 0 ] && grep -q "no sample group" "$T/e.txt" \
  && ok "scan of a config without a sample group: warns, scans a flat sample" \
  || bad "scan probe-q300.conf: exit $rc"

# ---- --gsf: 4 x 2 pixels, 1e-7 m line pitch, the origin moved to (1e-8, 2e-8) m
"$A" scan --config config/scan-grating.conf --pixels 4 --lines 2 --size-y 1e-7 --x0 1e-8 \
  --y0 2e-8 --line-rate 200 --engage 0.002 --json --gsf "$T/img" > "$T/g.txt" 2> "$T/g.err"
rc=$?
chans="height true-height z amplitude error phase peak-force dissipation squeeze-dissipation
  material"
nf=0
for c in $chans; do for d in trace retrace; do [ -s "$T/img-$c-$d.gsf" ] && nf=$((nf+1)); done; done
[ $rc -eq 0 ] && [ $nf -eq 20 ] && [ "$(wc -l < "$T/g.txt")" -eq 16 ] \
  && ok "scan --gsf: 20 files (10 images, trace and retrace) beside the 16 JSON pixels" \
  || bad "scan --gsf: exit $rc, $nf of 20 files: $(head -c 300 "$T/g.err")"
# gsf_hdr FILE: the text header (up to the first NUL); gsf_key FILE KEY: a value in it
gsf_hdr() { tr '\0' '\n' < "$1" | sed '/^$/q'; }
gsf_key() { gsf_hdr "$1" | sed -n "s/^$2 = //p"; }
h="$T/img-height-trace.gsf"
hdr_ok=1
for kv in "XRes=4" "YRes=2" "XReal=4e-07" "YReal=2e-07" "XOffset=1e-08" "YOffset=2e-08" \
          "XYUnits=m" "ZUnits=m" "Title=Height (trace)"; do
  [ "$(gsf_key "$h" "${kv%%=*}")" = "${kv#*=}" ] \
    || { hdr_ok=0; echo "     $h: ${kv%%=*} = '$(gsf_key "$h" "${kv%%=*}")', not '${kv#*=}'"; }
done
[ "$(head -1 "$h")" = "Gwyddion Simple Field 1.0" ] && [ $hdr_ok -eq 1 ] \
  && [ "$(gsf_key "$T/img-phase-retrace.gsf" ZUnits)" = deg ] \
  && [ "$(gsf_key "$T/img-peak-force-trace.gsf" ZUnits)" = N ] \
  && [ "$(gsf_key "$T/img-dissipation-trace.gsf" ZUnits)" = J ] \
  && [ "$(gsf_key "$T/img-squeeze-dissipation-retrace.gsf" ZUnits)" = J ] \
  && [ -z "$(gsf_key "$T/img-material-trace.gsf" ZUnits)" ] \
  && ok "scan --gsf: magic line, XRes YRes XReal YReal XOffset YOffset in m, ZUnits m deg N J" \
  || bad "scan --gsf: header: $(gsf_hdr "$h" | tr '\n' '|')"
# The layout: the text, 1..4 NULs to a multiple of 4, then exactly XRes x YRes floats.
lay_ok=1
for f in "$T"/img-*.gsf; do
  n=$(gsf_hdr "$f" | head -n -1 | wc -c); size=$(stat -c %s "$f"); off=$((size - 4 * 4 * 2))
  pad=$(od -A n -t u1 -v -j "$n" -N $((off - n)) "$f" | tr -s ' \n' ' ')
  [ $((off % 4)) -eq 0 ] && [ $((off - n)) -ge 1 ] && [ $((off - n)) -le 4 ] \
    && [ -z "$(echo "$pad" | tr -d ' 0')" ] || { lay_ok=0; echo "     $f: text $n, data at $off"; }
done
[ $lay_ok -eq 1 ] && ok "scan --gsf: each header NUL-padded to a multiple of 4, then 8 floats" \
  || bad "scan --gsf: file layout"
# gsf_px FILE ROW COL: a value, little-endian binary32 after the header, row by row
gsf_px() {
  local xres off
  xres=$(gsf_key "$1" XRes); off=$(($(stat -c %s "$1") - 4 * xres * $(gsf_key "$1" YRes)))
  od -A n -t f4 --endian=little -j $((off + 4 * ($2 * xres + $3))) -N 4 "$1" | tr -d ' '
}
# js LINE PIXEL RETRACE KEY: that pixel's value in the JSON of the same scan
js() {
  grep "\"line\":$1,\"pixel\":$2,\"retrace\":$3," "$T/g.txt" | sed -n "s/.*\"$4\":\([^,}]*\).*/\1/p"
}
# close A B: equal to a float's precision
close() { awk -v a="$1" -v b="$2" 'BEGIN { d = a - b; s = b < 0 ? -b : b;
  exit !(a != "" && b != "" && (d < 0 ? -d : d) <= 1e-6 * s) }'; }
px_ok=1
for t in "height trace 1 2 false height_m" "phase retrace 0 1 true phase_lag_deg" \
         "amplitude trace 0 3 false amplitude_m" "true-height retrace 1 0 true true_height_m" \
         "material trace 1 3 false material" "dissipation retrace 1 2 true dissipated_energy_j"; do
  set -- $t
  g=$(gsf_px "$T/img-$1-$2.gsf" "$3" "$4"); j=$(js "$3" "$4" "$5" "$6")
  close "$g" "$j" || { px_ok=0; echo "     $1 $2 line $3 pixel $4: gsf '$g', JSON '$j'"; }
done
# the geometry: JSON pixel (line 1, pixel 2) lies in GSF pixel (row 1, column 2)
x=$(js 1 2 false x_m); y=$(js 1 2 false y_m)
awk -v x="$x" -v y="$y" -v xo="$(gsf_key "$h" XOffset)" -v yo="$(gsf_key "$h" YOffset)" \
    -v xr="$(gsf_key "$h" XReal)" -v yr="$(gsf_key "$h" YReal)" 'BEGIN {
  dx = xr / 4; dy = yr / 2; xc = xo + 2.5 * dx
  exit !(x != "" && (x - xc < 0 ? xc - x : x - xc) < 1e-6 * dx && y >= yo + dy && y < yo + 2 * dy) }' \
  || { px_ok=0; echo "     pixel (1, 2) at x $x, y $y: outside GSF row 1, column 2"; }
[ $px_ok -eq 1 ] && ok "scan --gsf: pixels read back with od equal the JSON's (float precision), in place" \
  || bad "scan --gsf: pixel values or geometry"
# Gwyddion's own reader: a PNG thumbnail of every file, none of a truncated one.
if command -v gwyddion-thumbnailer > /dev/null; then
  gsf_thumbnails "$T"/img-*.gsf && ok "gwyddion-thumbnailer reads all 20 .gsf files (a PNG of each)" \
    || bad "gwyddion-thumbnailer refused a .gsf file"
  head -c $(($(stat -c %s "$h") - 4)) "$h" > "$T/cut.gsf"
  gwyddion-thumbnailer gnome2 64 "$T/cut.gsf" "$T/cut.png" 2> "$T/th.err"; rc=$?
  [ $rc -ne 0 ] && [ ! -s "$T/cut.png" ] \
    && ok "gwyddion-thumbnailer refuses a .gsf with its last float cut: $(head -1 "$T/th.err")" \
    || bad "gwyddion-thumbnailer took a truncated .gsf (exit $rc)"
else
  bad "gwyddion-thumbnailer not found (package gwyddion: make deps)"
fi
# E_sq, the squeeze film's energy per period (issue 30), as an image of its own: on
# default.conf (squeeze film on, a flat sample) its pixels are the JSON's and ~500 eV
# (air damping of the beam at A ~ 40 nm), apart from the tip-sample dissipation (~22 eV).
"$A" scan --config config/default.conf --pixels 2 --line-rate 200 --engage 0.002 --json \
  --gsf "$T/sq" > "$T/sq.txt" 2> /dev/null; rc=$?
f="$T/sq-squeeze-dissipation-trace.gsf"
g=$(gsf_px "$f" 0 1)
j=$(grep '"line":0,"pixel":1,"retrace":false,' "$T/sq.txt" |
  sed -n 's/.*"squeeze_dissipated_energy_j":\([^,}]*\).*/\1/p')
e=$(grep '"line":0,"pixel":1,"retrace":false,' "$T/sq.txt" |
  sed -n 's/.*"dissipated_energy_j":\([^,}]*\).*/\1/p')
th=ok
command -v gwyddion-thumbnailer > /dev/null &&
  { gwyddion-thumbnailer gnome2 64 "$f" "$T/sq.png" 2> /dev/null || th=refused; }
[ $rc -eq 0 ] && close "$g" "$j" && [ "$th" = ok ] &&
  awk -v x="$j" -v e="$e" 'BEGIN { x /= 1.602176634e-19; e /= 1.602176634e-19
    exit !(x > 300 && x < 700 && e > 5 && e < 60) }' &&
  ok "scan --gsf on default.conf: E_sq image ($(gsf_key "$f" Title)), pixel $g J = JSON $j J, beside E_ts $e J; gwyddion-thumbnailer reads it" ||
  bad "scan --gsf E_sq: exit $rc, gsf '$g' J, JSON '$j' J, E_ts '$e' J, thumbnailer $th"
"$A" scan --config config/scan-grating.conf --pixels 4 --gsf "$T/no/such/dir/img" \
  > /dev/null 2> "$T/e.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "cannot write" "$T/e.txt" \
  && ok "scan --gsf into a missing directory: exit 2: $(head -1 "$T/e.txt")" \
  || bad "scan --gsf into a missing directory: exit $rc"
check_done
