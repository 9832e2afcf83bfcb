#!/bin/sh
# doc-plots.sh BUILD OUTDIR -- the example runs behind every `afmtwin plot` kind, and their
# pictures (OUTDIR/KIND.png; beside them the columns as OUTDIR/KIND.dat, the curve as
# OUTDIR/KIND.csv and the gnuplot script as OUTDIR/KIND.gp). Every plot names the run's
# config (--config, and the drive the run overrode) for the title. make doc-plots writes
# docs/img/; tests/test_plot.sh runs it into a scratch directory and checks the images and
# scripts. Each command below is the one that made the picture of the same name.
set -eu
B=$1
O=$2
A="$B/bin/afmtwin"
mkdir -p "$O"
# plot KIND ...: afmtwin plot with the picture, columns, CSV and script of KIND in OUTDIR
plot() {
  k=$1
  shift
  "$A" plot "$k" "$@" -o "$O/$k.png" --data "$O/$k.dat" --csv "$O/$k.csv" --script "$O/$k.gp"
}
# sweep: the thesis's 1-DOF probe, forward and backward through its resonance
"$A" sweep --config config/thesis-1dof.conf --from 295e3 --to 305e3 --step 1e3 --json \
  --max-periods 3000 >"$O/sweep-fwd.json"
"$A" sweep --config config/thesis-1dof.conf --from 305e3 --to 295e3 --step 1e3 --json \
  --max-periods 3000 >"$O/sweep-bwd.json"
plot sweep "$O/sweep-fwd.json" "$O/sweep-bwd.json" --config config/thesis-1dof.conf \
  --title "a 1-DOF probe through its resonance, forward and backward"
# approach: the lumped Q 300 probe at A0 20 nm, approach and retract through the jump, in
# 0.25 nm steps (its bistable window is ~0.3 nm wide: 1 nm steps jump between the same two
# steps both ways and show no hysteresis)
"$A" approach --config config/probe-q300.conf --ae 6.6667e-11 --from 22e-9 --to 4e-9 \
  --step 0.25e-9 --retract --periods 3000 --json >"$O/approach.json"
plot approach "$O/approach.json" --config config/probe-q300.conf --ae 6.6667e-11 \
  --title "approach and retract at A0 20 nm"
# spectrum: the harmonics of the approach's step at Z 10 nm (step record 48 from 0)
plot spectrum "$O/approach.json" --index 48 --config config/probe-q300.conf --ae 6.6667e-11 \
  --title "the harmonics of one approach step"
# thermal: a thermal tune of the 1-DOF probe and its eq. 5.1 fit
"$A" thermal --config config/thesis-1dof.conf --seconds 0.5 --modes 1 --psd "$O/thermal.psd" \
  --json >"$O/thermal.json"
plot thermal "$O/thermal.psd" --fit "$O/thermal.json" --config config/thesis-1dof.conf \
  --title "thermal tune and its eq. 5.1 fit"
# trace: the daemon's outputs (afmtwin replay of a dither command) on default.conf
"$A" send dither --config config/default.conf --freq 338112 --amp 0.087e-9 --seq 1 \
  --log "$O/cmd.log" --log-time 0 --quiet
"$A" replay --config config/default.conf --in "$O/cmd.log" --out "$O/out.log" --tail 0.004 \
  --quiet
plot trace "$O/out.log" --from 0.003 --to 0.00302 --z 40e-9 --config config/default.conf \
  --fe 338112 --ae 0.087e-9 --title "the daemon outputs (afmtwin replay of a dither command)"
# scan: a grating imaged with the reference controller, 400 x 400 nm (48 pixels, 16 lines
# 25 nm apart) at 20 lines/s (issue 18)
"$A" scan --config config/scan-grating.conf --pixels 48 --lines 16 --size-y 3.75e-7 \
  --line-rate 20 --json >"$O/scan.json"
plot scan "$O/scan.json" --config config/scan-grating.conf \
  --title "a grating of 5 nm lines, 20 lines/s"
# continue: the folded peak of a soft lever with vdW only, and its fold curve in (fe, Ae)
# through the cusp (two-parameter continuation, issue 17)
"$A" continue --config config/lumped-vdw-fold.conf --param fe --from 297500 --to 298700 \
  --no-switch --param2 ae --from2 3e-13 --to2 6e-13 --curves 1 --json >"$O/continue.json"
plot continue "$O/continue.json" --config config/lumped-vdw-fold.conf \
  --title "the folded peak and its fold curve in (fe, Ae)"
# force-curve: the quasi-static force-distance curve of the soft vdW lever (drive off):
# snap-in on approach, adhesion and pull-off on retract, the ringing after the jump
"$A" force-curve --config config/lumped-vdw-fold.conf --from 2.5e-9 --to 0.85e-9 --speed 3e-8 \
  --json >"$O/force-curve.json"
plot force-curve "$O/force-curve.json" --config config/lumped-vdw-fold.conf \
  --title "a force-distance curve: snap-in, adhesion and pull-off"
