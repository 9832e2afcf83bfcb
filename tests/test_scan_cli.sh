#!/usr/bin/env bash
# test_scan_cli.sh BUILD -- `afmtwin scan` as a user meets it (issue 18): --help, the text
# table's phase convention, the JSON keys of a pixel, and clear errors (exit 2) for bad
# options, bad values and a config without a sample group (a warning, then a flat scan).
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
check_done
