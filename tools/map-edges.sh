#!/bin/sh
# map-edges.sh -- the bistable band's edges of an `afmtwin map` (fe on x, both directions)
# against the LPC curves of `afmtwin continue --param2 --json` (issue 31, docs/map.md): per
# map row (y), the map's edge and the curve's fe at that y, and their difference in Hz. It is
# how docs/map.md's tables were made, kept so that they can be made again.
#
#   lower: the midpoint between the last point of the row that is not bistable and the first
#          that is (the map's B records), the down pass leaving the low branch;
#   upper: the midpoint of the two points across which the up pass's amplitude drops most
#          (the J record of direction u with the largest relative drop): it leaves the high
#          branch at the fold of the branch it is on;
#   pd:    the midpoint of the up pass's first step from a period-1 to a period-2 point, the
#          period doubling, against the PD curves instead of the LPC curves.
#
# The curve's fe at the row: every crossing of the row's y by a curve's segments (the sides
# joined at the curve's start, interpolated linearly), of the LPC curves in all the files;
# the one nearest the map's edge is reported, with its curve's period (p1: the period-1
# LPC, p2: the fold of a period-2 branch). "-" where the map has no edge or no curve
# crosses the row.
#
# Usage: sh tools/map-edges.sh MAP lower|upper|pd CURVES.jsonl...   (needs jq)
set -e
[ $# -ge 3 ] || {
  echo "usage: sh tools/map-edges.sh MAP lower|upper|pd CURVES.jsonl..." >&2
  exit 2
}
map=$1
edge=$2
shift 2
case $edge in lower | upper | pd) ;; *)
  echo "map-edges.sh: the edge is lower, upper or pd, not $edge" >&2
  exit 2
  ;;
esac
T=$(mktemp /tmp/afmtwin-map-edges.XXXXXX)
trap 'rm -f "$T"' EXIT
kind=LPC
[ "$edge" = pd ] && kind=PD
# one line per curve point of that kind: run (file index and the summary records before it in the
# file: the outputs of several runs concatenated, as plot map --curves reads them), curve,
# side, period, fe (Hz), y (SI)
i=0
for f in "$@"; do
  jq -r -s --argjson i $i --arg kind $kind 'foreach .[] as $r (0; if $r.type == "summary" then . + 1 else . end;
      . as $n | $r | select(.type == "curve_point" and .kind == $kind) |
      ["\($i).\($n)", .curve, .side, .period,
       (if .param_name == "fe" then .param else .param2 end),
       (if .param_name == "fe" then .param2 else .param end)]) | @tsv' "$f" >> "$T"
  i=$((i + 1))
done
awk -v edge="$edge" -v curves="$T" '
  BEGIN {
    n = 0
    while ((getline line < curves) > 0) {
      split(line, a, "\t")
      key = a[1] ":" a[2]
      if (!(key in start)) { start[key] = n; sfe[key] = a[5]; sy[key] = a[6] }
      else if (a[3] != pside[key]) { # side 1 begins again at the start point
        k[n] = key; per[n] = a[4]; fe[n] = sfe[key]; yy[n] = sy[key]; n++
      }
      pside[key] = a[3]
      k[n] = key; per[n] = a[4]; fe[n] = a[5]; yy[n] = a[6]; n++
    }
  }
  $1 == "x" && $2 != "fe" { print "map-edges.sh: the map x axis is " $2 ", not fe" > "/dev/stderr"; exit 2 }
  $1 == "y" { yname = $2 }
  $1 == "P" && $3 == "u" {
    x[$4] = $5; yv[$2] = $6; amp[$2, $4] = $7
    if ($4 > 0 && $15 == 2 && prevper == 1 && !(($2) in firstpd)) firstpd[$2] = $4
    prevper = $15
  }
  $1 == "B" { if (!(($2) in firstb) || $3 < firstb[$2]) firstb[$2] = $3 }
  $1 == "J" && $3 == "u" && $7 < $6 {
    d = 1 - $7 / $6
    if (!(($2) in drop) || d > drop[$2]) { drop[$2] = d; jb[$2] = $4; ja[$2] = $5 }
  }
  $1 == "E" { rows = $2 + 1 }
  END {
    scale = yname == "z" || yname == "ae" ? 1e9 : 1
    printf "%-10s %-12s %-12s %-4s %s\n", yname (scale == 1e9 ? "(nm)" : ""), "map(kHz)", \
           "curve(kHz)", "p", "map-curve(Hz)"
    for (r = 0; r < rows; r++) {
      m = "-"
      if (edge == "lower" && (r in firstb) && firstb[r] > 0)
        m = (x[firstb[r] - 1] + x[firstb[r]]) / 2
      if (edge == "upper" && (r in drop))
        m = (x[jb[r]] + x[ja[r]]) / 2
      if (edge == "pd" && (r in firstpd))
        m = (x[firstpd[r] - 1] + x[firstpd[r]]) / 2
      best = ""; bp = ""
      for (j = 1; j < n; j++) {
        if (k[j] != k[j - 1]) continue
        y0 = yy[j - 1]; y1 = yy[j]
        if (y0 == y1 || (yv[r] - y0) * (yv[r] - y1) > 0) continue
        f = fe[j - 1] + (fe[j] - fe[j - 1]) * (yv[r] - y0) / (y1 - y0)
        if (best == "" || (m != "-" && (f - m) ^ 2 < (best - m) ^ 2)) { best = f; bp = per[j] }
      }
      printf "%-10.4g %-12s %-12s %-4s %s\n", yv[r] * scale,
             m == "-" ? "-" : sprintf("%.2f", m / 1e3),
             best == "" ? "-" : sprintf("%.3f", best / 1e3), bp == "" ? "-" : "p" bp,
             m == "-" || best == "" ? "-" : sprintf("%+.0f", m - best)
    }
  }' "$map"
