#!/bin/sh
# bench-fm.sh BUILD -- `make bench`'s FM row (issue 32): the internal PLL and amplitude control
# (and the self-excited drive) against AM on one config, in ns per sample (afmtwin bench-fm,
# one run, the states alternated) and in instructions per sample (callgrind on one state's
# window at a time, --toggle-collect=bench_fm_window: the window alone, not the settling).
# Without valgrind the instruction row is skipped, said.
B="${1:-build}"
A="$B/bin/afmtwin"
"$A" bench-fm || exit 1
if ! command -v valgrind > /dev/null 2>&1; then
  echo "# bench-fm: no valgrind here: instructions per sample not counted"
  exit 0
fi
T=$(mktemp -d) || exit 1
trap 'rm -rf "$T"' EXIT
U=50 # updates in the counted window (51200 samples at fm.update_samples 1024)
printf '# %-6s %12s %12s   (callgrind, the window alone: %s updates)\n' state Ir/sample "minus am" $U
am=
for s in am pll self; do
  valgrind --tool=callgrind --collect-atstart=no --toggle-collect=bench_fm_window \
    --callgrind-out-file="$T/cg.$s" "$A" bench-fm --only $s --updates $U > "$T/out.$s" 2> "$T/err.$s" ||
    { echo "# bench-fm: callgrind $s failed: $(tail -3 "$T/err.$s")"; exit 1; }
  n=$(sed -n 's/.*: \([0-9]*\) samples in the window/\1/p' "$T/out.$s")
  ir=$(sed -n 's/^summary: *\([0-9]*\).*/\1/p' "$T/cg.$s")
  per=$(awk -v i="$ir" -v n="$n" 'BEGIN { printf "%.1f", i / n }')
  if [ -z "$am" ]; then am=$per; d=-; else d=$(awk -v a="$per" -v b="$am" 'BEGIN { printf "%.1f", a - b }'); fi
  printf '  %-6s %12s %12s\n' $s "$per" "$d"
done
