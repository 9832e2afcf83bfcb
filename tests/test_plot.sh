#!/usr/bin/env bash
# test_plot.sh BUILD -- every `afmtwin plot` kind drawn from the example runs of
# tools/doc-plots.sh (the runs behind docs/img/): gnuplot succeeded, each output is a PNG of
# the requested size (signature and IHDR), its columns file has data, and bad input is
# refused with exit 2. Needs no network. Prints "N passed, N failed".
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
for k in sweep approach spectrum thermal trace scan continue; do
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
"$A" plot continue "$T/continue.json" 2>"$T/e6.txt"; rc=$?
[ $rc -eq 2 ] && grep -q "\-o FILE.png is required" "$T/e6.txt" && ok "no -o: exit 2, '-o FILE.png is required'" \
  || bad "no -o: exit $rc, $(cat "$T/e6.txt")"
check_done
