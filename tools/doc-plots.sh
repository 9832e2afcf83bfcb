#!/bin/sh
# doc-plots.sh BUILD OUTDIR -- the example runs behind every `afmtwin plot` kind, and their
# pictures (OUTDIR/KIND.png, the columns beside them as OUTDIR/KIND.dat). make doc-plots
# writes docs/img/; tests/test_plot.sh runs it into a scratch directory and checks the
# images. Each command below is the one that made the picture of the same name.
set -eu
B=$1
O=$2
A="$B/bin/afmtwin"
mkdir -p "$O"
# sweep: the thesis's 1-DOF probe, forward and backward through its resonance
"$A" sweep --config config/thesis-1dof.conf --from 295e3 --to 305e3 --step 1e3 --json \
  --max-periods 3000 >"$O/sweep-fwd.json"
"$A" sweep --config config/thesis-1dof.conf --from 305e3 --to 295e3 --step 1e3 --json \
  --max-periods 3000 >"$O/sweep-bwd.json"
"$A" plot sweep "$O/sweep-fwd.json" "$O/sweep-bwd.json" -o "$O/sweep.png" --data "$O/sweep.dat" \
  --title "thesis-1dof.conf, forward and backward"
# approach: the lumped Q 300 probe at A0 20 nm, approach and retract through the jump
"$A" approach --config config/probe-q300.conf --ae 6.6667e-11 --from 22e-9 --to 4e-9 \
  --step 1e-9 --retract --periods 3000 --json >"$O/approach.json"
"$A" plot approach "$O/approach.json" -o "$O/approach.png" --data "$O/approach.dat" \
  --title "probe-q300.conf, A0 20 nm, approach and retract"
# spectrum: the harmonics of the approach's step at Z 10 nm
"$A" plot spectrum "$O/approach.json" --index 12 -o "$O/spectrum.png" --data "$O/spectrum.dat" \
  --title "probe-q300.conf, A0 20 nm"
# thermal: a thermal tune of the 1-DOF probe and its eq. 5.1 fit
"$A" thermal --config config/thesis-1dof.conf --seconds 0.5 --modes 1 --psd "$O/thermal.psd" \
  --json >"$O/thermal.json"
"$A" plot thermal "$O/thermal.psd" --fit "$O/thermal.json" -o "$O/thermal.png" \
  --data "$O/thermal.dat" --title "thesis-1dof.conf, 0.5 s"
# trace: the daemon's outputs (afmtwin replay of a dither command) on default.conf
"$A" send dither --config config/default.conf --freq 338112 --amp 0.087e-9 --seq 1 \
  --log "$O/cmd.log" --log-time 0 --quiet
"$A" replay --config config/default.conf --in "$O/cmd.log" --out "$O/out.log" --tail 0.004 \
  --quiet
"$A" plot trace "$O/out.log" --from 0.003 --to 0.00302 --z 40e-9 -o "$O/trace.png" \
  --data "$O/trace.dat" --title "default.conf, replay, Z 40 nm"
# scan: a grating imaged with the reference controller, 6 lines at 20 lines/s (issue 18)
"$A" scan --config config/scan-grating.conf --pixels 48 --lines 6 --size-y 2e-7 \
  --line-rate 20 --json >"$O/scan.json"
"$A" plot scan "$O/scan.json" -o "$O/scan.png" --data "$O/scan.dat" \
  --title "scan-grating.conf, 5 nm lines, 20 lines/s"
# continue: the folded peak of a soft lever with vdW only, and its fold curve in (fe, Ae)
# through the cusp (two-parameter continuation, issue 17)
"$A" continue --config config/lumped-vdw-fold.conf --param fe --from 297500 --to 298700 \
  --no-switch --param2 ae --from2 3e-13 --to2 6e-13 --curves 1 --json >"$O/continue.json"
"$A" plot continue "$O/continue.json" -o "$O/continue.png" --data "$O/continue.dat" \
  --title "lumped-vdw-fold.conf: the folded peak and its fold curve in (fe, Ae)"
