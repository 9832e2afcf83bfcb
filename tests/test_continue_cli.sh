#!/usr/bin/env bash
# test_continue_cli.sh BUILD -- `afmtwin continue` as a user meets it: --help, one JSON record
# per line with the fields the issue names (a short run on the linear model, the forces of
# thesis-fig-4-2.conf switched off by a config copy), and every bad input refused with exit 2
# and a message that says what is wrong. The numbers are tests/test_continue.c's job.
# Prints "N passed, N failed".
BUILD=${1:-build}
. "$(dirname "$0")/lib_check.sh"
check_init continue "$BUILD"

"$A" continue --help >"$T/help.txt" 2>&1 && grep -q "pseudo-arclength" "$T/help.txt" &&
  grep -q "Phase convention" "$T/help.txt" && ok "--help: exit 0, says the method and the phase convention" ||
  bad "--help: $(head -3 "$T/help.txt")"

miss=""
for k in --no-end-switch --join-points --beyond --max-branch-points --max-branches; do
  grep -q -- "$k" "$T/help.txt" || miss="$miss $k"
done
[ -z "$miss" ] && ok "--help: the options of the branches' ends and their bounds" || bad "--help lacks:$miss"

# a linear copy of the Fig. 4.2 beam (no tip forces): quick, no bifurcations
sed -e '/vdw_contact/d' -e '/viscoelastic/d' -e '/squeeze/d' config/thesis-fig-4-2.conf >"$T/lin.conf"
"$A" continue --config "$T/lin.conf" --param fe --from 80000 --to 80400 --max-points 6 --json \
  >"$T/lin.json" 2>"$T/lin.err"
rc=$?
[ $rc -eq 0 ] && ok "a linear run: exit 0" || bad "a linear run: exit $rc, $(cat "$T/lin.err")"
np=$(grep -c '"type":"point"' "$T/lin.json")
[ "$np" -ge 3 ] && ok "a linear run: $np point records" || bad "a linear run: $np point records"
# --curve-kinds pd: the same run has LPCs only, so no curve (and a line that says so)
"$A" continue --config config/lumped-vdw-fold.conf --param fe --from 298700 --to 298300 \
  --no-switch --param2 ae --from2 3e-13 --to2 6e-13 --curves 1 --curve-points 3 --json \
  --curve-kinds pd >"$T/cvpd.json" 2>"$T/cvpd.err"
rc=$?
[ $rc -eq 0 ] && ! grep -q '"type":"curve_point"' "$T/cvpd.json" &&
  tail -1 "$T/cvpd.json" | grep -q '"curves":0' && grep -q "no PD point in the range" "$T/cvpd.err" &&
  ok "--curve-kinds pd: no curve from a run with LPCs only, and it says so" ||
  bad "--curve-kinds pd: exit $rc, $(grep -c curve_point "$T/cvpd.json") curve points, $(cat "$T/cvpd.err")"
miss=""
for k in branch param period stable multipliers min_deflection_m max_deflection_m max_force_n \
  amplitude_m phase_lag_deg; do
  grep '"type":"point"' "$T/lin.json" | head -1 | grep -q "\"$k\":" || miss="$miss $k"
done
[ -z "$miss" ] && ok "point records carry every field the issue names" || bad "point records lack:$miss"
# each branch opens with a record of how it was reached, before its first point
head -1 "$T/lin.json" | grep '"type":"branch"' | grep '"via":"start"' | grep -q '"label":"the start orbit' &&
  grep '"type":"end"' "$T/lin.json" | grep -q '"via":"start".*"label":' &&
  tail -1 "$T/lin.json" | grep -q '"joins":0,"not_started":0' &&
  ok "a branch record (via, label) opens the branch; end and summary records carry them" ||
  bad "branch records: $(head -1 "$T/lin.json" | cut -c1-200)"
tail -1 "$T/lin.json" | grep -q '"type":"summary"' && grep -q '"type":"end"' "$T/lin.json" &&
  ok "an end record with its reason, and a closing summary" || bad "no end or summary record"

"$A" plot continue "$T/lin.json" -o "$T/lin.png" --data "$T/lin.dat" 2>"$T/plot.err" &&
  [ "$(od -An -tx1 -N8 "$T/lin.png" | tr -d ' \n')" = "89504e470d0a1a0a" ] &&
  [ "$(grep -cv '^#\|^$' "$T/lin.dat")" -ge 3 ] && ok "plot continue: a PNG and its columns" ||
  bad "plot continue: $(cat "$T/plot.err")"

# --param2: the fold curve of config/lumped-vdw-fold.conf from its lower LPC, 3 points a side
# (the numbers: tests/test_continue.c's lumped case)
"$A" continue --config config/lumped-vdw-fold.conf --param fe --from 298700 --to 298300 \
  --no-switch --param2 ae --from2 3e-13 --to2 6e-13 --curves 1 --curve-points 3 --json \
  >"$T/cv.json" 2>"$T/cv.err"
rc=$?
[ $rc -eq 0 ] && ok "--param2 ae: exit 0" || bad "--param2 ae: exit $rc, $(cat "$T/cv.err")"
nc=$(grep -c '"type":"curve_point"' "$T/cv.json")
[ "$nc" -ge 3 ] && ok "--param2 ae: $nc curve_point records" || bad "--param2 ae: $nc curve_point records"
miss=""
for k in curve kind side param param_name param2 param2_name period stable multiplier g \
  multipliers min_deflection_m max_force_n amplitude_m phase_lag_deg state residual; do
  grep '"type":"curve_point"' "$T/cv.json" | head -1 | grep -q "\"$k\":" || miss="$miss $k"
done
[ -z "$miss" ] && ok "curve_point records carry the point's fields and the curve's" ||
  bad "curve_point records lack:$miss"
grep -q '"type":"curve_end".*"side":0.*the start is on the edge' "$T/cv.json" &&
  grep -q '"type":"curve_end".*"side":1.*the most points per side' "$T/cv.json" &&
  ok "each side ends with its reason (a start on the edge of Ae: side 0 has no points)" ||
  bad "curve_end records: $(grep curve_end "$T/cv.json" | cut -c1-160)"
tail -1 "$T/cv.json" | grep -q '"curves":1,"curve_points":4' &&
  ok "the summary counts the curves and their points" || bad "summary: $(tail -1 "$T/cv.json" | cut -c1-200)"
# every curve point: a multiplier at +1 (the fold), on the lower fold's side of the cusp
bad_pts=$(grep '"type":"curve_point"' "$T/cv.json" | grep -o '"multiplier":\[[^,]*' |
  awk -F'[' '{m=$2+0; if (m < 0.9999 || m > 1.0001) n++} END {print n+0}')
[ "$bad_pts" -eq 0 ] && ok "every curve point has its multiplier at +1 (1e-4)" ||
  bad "$bad_pts curve points with a multiplier away from +1"

refuse() { # refuse WHAT PATTERN ARGS...: exit 2 and PATTERN on stderr
  local what=$1 pat=$2
  shift 2
  "$A" continue "$@" >"$T/o.txt" 2>"$T/e.txt"
  local r=$?
  if [ $r -eq 2 ] && grep -qi -- "$pat" "$T/e.txt"; then ok "$what: exit 2, '$pat'"; else
    bad "$what: exit $r, $(head -2 "$T/e.txt")"
  fi
}
C=config/thesis-fig-4-2.conf
refuse "no --param" "are required" --config $C --from 80000 --to 81000
refuse "an unknown parameter" "unknown" --config $C --param bogus --from 1 --to 2
refuse "a geometry parameter" "changes the beam" --config $C --param model.beam.length_m --from 1e-4 --to 2e-4
refuse "--from = --to" "must differ" --config $C --param fe --from 80000 --to 80000
refuse "a frequency out of range" "out of its range" --config $C --param fe --from 80000 --to 9e6
refuse "a non-number" "wants a number" --config $C --param fe --from abc --to 81000
refuse "a bad --start" "comma-separated" --config $C --param fe --from 80000 --to 81000 --start 1,2,3
refuse "a bad --period" "integer" --config $C --param fe --from 80000 --to 81000 --period 0
refuse "a missing config" "cannot\|no such\|open" --config "$T/none.conf" --param fe --from 80000 --to 81000
refuse "an unknown option" "unknown or incomplete option" --config $C --param fe --from 80000 --to 81000 --bogus 1
refuse "--param2 without a range" "needs --from2 and --to2" --config $C --param fe --from 80000 --to 81000 --param2 z
refuse "--from2 without --param2" "needs --from2 and --to2" --config $C --param fe --from 80000 --to 81000 --from2 1e-9 --to2 2e-9
refuse "--param2 = --param" "must differ from --param" --config $C --param fe --from 80000 --to 81000 --param2 fe --from2 1 --to2 2
refuse "an unknown --param2" "unknown parameter" --config $C --param fe --from 80000 --to 81000 --param2 bogus --from2 1 --to2 2
refuse "--param2's config value outside its range" "outside \[--from2, --to2\]" --config $C --param fe --from 80000 --to 81000 --param2 z --from2 1e-9 --to2 2e-9
refuse "--curve-kinds bogus" "--curve-kinds wants one of lpc, pd, all, got 'bogus'" --config $C --param fe --from 80000 --to 81000 --param2 z --from2 29e-9 --to2 31e-9 --curve-kinds bogus
refuse "--curve-kinds without --param2" "is for --param2" --config $C --param fe --from 80000 --to 81000 --curve-kinds lpc
refuse "--curves 0" "--curves wants an integer in 1..32" --config $C --param fe --from 80000 --to 81000 --param2 z --from2 29e-9 --to2 31e-9 --curves 0
refuse "--beyond out of 0..1" "--beyond wants" --config $C --param fe --from 80000 --to 81000 --beyond 2
refuse "--join-points 0" "--join-points wants" --config $C --param fe --from 80000 --to 81000 --join-points 0
refuse "--max-branch-points 0" "--max-branch-points wants" --config $C --param fe --from 80000 --to 81000 --max-branch-points 0
check_done
