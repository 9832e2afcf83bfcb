#!/usr/bin/env bash
# bench-march.sh BUILD -- `make bench`'s figures for each target-CPU choice (README
# "Portable builds"), side by side in one run: the default build (BUILD,
# AFMTWIN_MARCH=portable: baseline x86-64, the integrator's x86-64-v3 copy and the chain's
# x86-64-v3 clones chosen at run time), the x86-64-v3 one and the plain baseline (x86-64, no
# run-time choice), the last two built into BUILD/march/. Each runs `afmtwin bench-states` ROUNDS times,
# interleaved; the median of the rounds per state, and the ratio to the default build.
set -eu
BUILD=${1:-build}
ROUNDS=${ROUNDS:-3}
cd "$(dirname "$0")/.."
names=(portable v3 baseline); marches=(portable x86-64-v3 x86-64)
bins=("$BUILD/bin/afmtwin" "$BUILD/march/x86-64-v3/bin/afmtwin" "$BUILD/march/x86-64/bin/afmtwin")
[ "$(uname -m)" = x86_64 ] || { names=(portable native); marches=(portable native)
  bins=("$BUILD/bin/afmtwin" "$BUILD/march/native/bin/afmtwin"); }
for i in "${!names[@]}"; do
  [ "$i" -eq 0 ] && continue
  make -s --no-print-directory BUILD="$BUILD/march/${marches[$i]}" AFMTWIN_MARCH="${marches[$i]}" \
    "$BUILD/march/${marches[$i]}/bin/afmtwin" >/dev/null
done
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
states='tapping, Z 40 nm|free, far from|hard contact|multi-tone \(4 tones\)'
for r in $(seq 1 "$ROUNDS"); do
  for i in "${!names[@]}"; do
    "${bins[$i]}" bench-states --runs 1 2>/dev/null | grep -E "^  ($states)" |
      awk -v b="${names[$i]}" '{n=$0; sub(/ +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9.]+ +[0-9.inf]+ +[0-9]+$/, "", n);
        sub(/^ +/, "", n); print b "\t" n "\t" $(NF-5) "\t" $(NF-3)}' >> "$T/all"
  done
done
echo "target CPU choices (README 'Portable builds'), bench-states on config/default.conf, median of $ROUNDS interleaved rounds:"
printf '  %-44s %-9s %12s %12s %10s\n' state build "integ ns/s" "chain ns/s" "integ/port"
awk -F'\t' '{k=$2 SUBSEP $1; n[k]++; ig[k, n[k]]=$3; ch[k, n[k]]=$4
    if (!($2 in so)) {so[$2]=++ns; sn[ns]=$2}; if (!($1 in bo)) {bo[$1]=++nb; bn[nb]=$1}}
  function med(a, k, m,   i, j, t, v) { for (i=1;i<=m;i++) v[i]=a[k,i]
    for (i=1;i<=m;i++) for (j=i+1;j<=m;j++) if (v[j]<v[i]) {t=v[i];v[i]=v[j];v[j]=t}; return v[int((m+1)/2)] }
  END { for (i=1;i<=ns;i++) for (b=1;b<=nb;b++) { s=sn[i]; k=s SUBSEP bn[b]; d=med(ig, s SUBSEP bn[1], n[s SUBSEP bn[1]])
          printf "  %-44s %-9s %12.1f %12.1f %10.2f\n", (b==1 ? s : ""), bn[b], med(ig,k,n[k]), med(ch,k,n[k]), med(ig,k,n[k])/d } }' "$T/all"
