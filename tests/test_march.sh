#!/usr/bin/env bash
# test_march.sh BUILD -- the same bits from every target-CPU choice (README "Portable
# builds"): `afmtwin replay` of one command log (tapping, a Z step into hard contact, four
# tones, back to one, a Z ramp) on default.conf and nchv.conf, every output channel and every
# period's harmonics, by the BUILD's afmtwin and by an x86-64-v3 and a plain x86-64 build of
# it (built into BUILD/march/, as `make bench` does): the output logs must be byte-identical.
# They are when every copy of the integrator and of the chain rounds each operation once
# per lane (rt_fma4, AFM_V4_FMA); an unfused multiply-add or a contracted expression in
# one copy changes the last bits within a few samples. Only on x86-64 (elsewhere there is one
# copy). Prints "N passed, N failed".
# make test builds and compares the plain x86-64 copy only (the baseline code path: every
# rt_fma4 and AFM_V4_FMA a libm fma per lane, against the x86-64-v3 copies that this BUILD's
# portable afmtwin runs here), with make -j2; AFMTWIN_VALIDATE=full (make validate) also the
# x86-64-v3 build (every file compiled for AVX2 + FMA), ~1 min more on 2 cores.
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
pass=0; fail=0
ok() { pass=$((pass + 1)); echo "ok   $*"; }
bad() { fail=$((fail + 1)); echo "FAIL $*"; }
if [ "$(uname -m)" != x86_64 ]; then
  echo "     not x86-64: one copy of everything, nothing to compare"
  echo "0 passed, 0 failed"
  exit 0
fi
T=$(mktemp -d /tmp/afmtwin-march.XXXXXX)
trap 'rm -rf "$T"' EXIT
A="$BUILD/bin/afmtwin"
declare -A bin=([default]="$A")
marches="x86-64"
[ "${AFMTWIN_VALIDATE:-}" = full ] && marches="x86-64-v3 x86-64"
for m in $marches; do
  # -j2: the build machine has two cores (this runs outside the caller's make jobserver)
  if make -s -j2 --no-print-directory BUILD="$BUILD/march/$m" AFMTWIN_MARCH=$m \
      "$BUILD/march/$m/bin/afmtwin" > "$T/make.$m" 2>&1; then
    bin[$m]="$BUILD/march/$m/bin/afmtwin"
    ok "built afmtwin for AFMTWIN_MARCH=$m"
  else
    bad "AFMTWIN_MARCH=$m does not build: $(tail -3 "$T/make.$m")"
  fi
done
for conf in config/default.conf config/nchv.conf; do
  name=$(basename "$conf")
  L="$T/$name.log"; rm -f "$L"
  send() { "$A" send "$@" --config "$conf" --log "$L" --quiet; }
  send setpoint --z 30e-9 --seq 1 --log-time 0 &&
    send setpoint --z 15e-9 --seq 2 --log-time 0.004 &&
    send dither --freq 337900,403300,227600,756700 --amp 0.076e-9,0.0126e-9,0.0143e-9,0.004e-9 \
      --phase 0,0.4,1.9,3.1 --seq 3 --log-time 0.008 &&
    send dither --freq 342500 --amp 0.076e-9 --seq 4 --log-time 0.012 &&
    send setpoint --z 40e-9 --ramp 2e-3 --seq 5 --log-time 0.014 ||
    { bad "$name: send --log"; continue; }
  ref=""
  for b in default x86-64-v3 x86-64; do
    [ -n "${bin[$b]:-}" ] || continue
    if ! "${bin[$b]}" replay --config "$conf" --in "$L" --out "$T/$name.$b.out" --tail 0.004 \
        --harmonics-every 1 --quiet 2> "$T/err"; then
      bad "$name: replay by the $b build: $(head -2 "$T/err")"
      continue
    fi
    if [ -z "$ref" ]; then
      ref="$T/$name.$b.out"
      continue
    fi
    cmp -s "$ref" "$T/$name.$b.out" &&
      ok "$name: the $b build's replay is byte-identical to the default build's ($(stat -c %s "$ref") bytes: samples, harmonics of every period, status)" ||
      bad "$name: the $b build's replay differs from the default build's ($(cmp "$ref" "$T/$name.$b.out" | head -1))"
  done
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
