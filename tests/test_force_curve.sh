#!/usr/bin/env bash
# test_force_curve.sh BUILD -- `afmtwin force-curve` (issue 30) against the quasi-static
# analytic force-distance curve of the lumped probes' van der Waals + DMT law. Prints
# "N passed, N failed".
#
# Sign conventions of the code: the deflection x is negative towards the sample, the gap is
# d = x cos(alpha) + Z (alpha 0 here), the tip force F(d) = -C / d^2 out of contact
# (C = H R / 6) and -F_ad + Hc (a0 - d)^1.5 in contact (F_ad = C / a0^2, Hc = 4/3 Er sqrt(R)).
# The lever holds k x = F(x + Z) (force_n = k x); the branch is stable while dF/dd < k.
#  - snap-in: dF/dd = 2 C / d^3 = k at d* = (2 C / k)^(1/3) = (H R / (3 k))^(1/3); there
#    k x* = -C / d*^2 = -k d* / 2, so x* = -d*/2 and Z* = d* - x* = 1.5 d*. It exists only
#    when d* > a0, i.e. k below the largest attractive gradient 2 C / a0^3 at contact.
#    thesis-1dof.conf (k 40 N/m, H 1.29e-19 J, R 10 nm, a0 0.24 nm) has 2 C / a0^3 = 31.1 N/m
#    < 40: no snap-in (d* = 0.221 nm < a0), the tip reaches contact smoothly at the same Z as
#    it leaves it. lumped-vdw-fold.conf (the same probe, k 2 N/m) snaps in: d* = 0.599 nm,
#    Z* = 0.899 nm, x* = -0.300 nm, F* = -0.599 nN.
#  - adhesion: in contact dF/dd = -1.5 Hc sqrt(a0 - d) <= 0 and F >= -F_ad, out of contact
#    F > -F_ad: the most negative force of the retract is -F_ad = -H R / (6 a0^2)
#    (-3.7326 nN for both), at d = a0, x = -F_ad / k: pull-off at Z = a0 + F_ad / k
#    (0.3333 nm for k 40, 2.1063 nm for k 2, where the tip jumps off: 2 C / a0^3 > 2).
#  - contact slope: the deflection up per Z down over the approach records the tool fits,
#    from the same equilibrium solved in contact (bisection), least squares.
# Tolerances, from the ramp speed s and the lever's w1 = 2 pi f0:
#  - adhesion: quasi-statically exact; the tip in contact decelerates to the pull-off and
#    overshoots by at most its speed (<= s: the contact slope is below 1) over w1, so
#    |dF| <= 2 k s / w1, plus 1e-5 relative for the integrator.
#  - pull-off Z: the minimum lags the quasi-static one by less than two lever periods of
#    ramp, 2 s / f0.
#  - snap-in: the departure from a saddle-node fold under a ramp takes T = (2 d* / (3 w1^4
#    s))^(1/5) and runs L = 2 d* / (3 w1^2 T^2) in x before the curve's slope passes 100
#    (the tool's jump start, which sits 0.7 % short of x* and 2e-5 Z* before the fold on
#    the quasi-static curve): Z within 5 s T + 2e-5 Z*, x within 2 L + 0.7 % of x*
#    (3e-8 m/s: T = 4 us, 5 s T = 0.6 pm; L = 7 pm, 2.3 % of x*).
#  - contact slope: 1e-4 (the ramp shifts every contact record by about the same lag,
#    c v / (k + k_c) ~ 1e-18 m, which leaves the slope alone).
. "$(dirname "$0")/lib_check.sh"
check_init force-curve "${1:-build}"

# A number from the config's text (the first "key = value").
cfg() { sed -n "s/.*\\b$2 *= *\\([-0-9.eE+]*\\).*/\\1/p" "$1" | head -1; }
# A number (or null / true / false) of a JSON line's key (flat keys are unique here).
jnum() { sed -n "s/.*\"$2\":\\([^,}]*\\).*/\\1/p" <<< "$1"; }
# ok when |a - b| <= tol (awk doubles); name, a, b, tol
near() {
  if awk -v a="$2" -v b="$3" -v t="$4" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= t) }'
  then ok "$1: $2 vs analytic $3 (tol $4)"; else bad "$1: $2 vs analytic $3 (tol $4)"; fi
}

# --- help and bad input
"$A" force-curve --help > "$T/help.txt"; rc=$?
[ $rc -eq 0 ] && grep -q "snap-in" "$T/help.txt" && grep -q "pull-off" "$T/help.txt" \
  && grep -q -- "--speed M_S" "$T/help.txt" && ok "force-curve --help: exit 0, the events and options" \
  || bad "force-curve --help (exit $rc)"
"$A" help | grep -q "force-curve" && ok "afmtwin help lists force-curve" \
  || bad "afmtwin help does not list force-curve"
C1=config/thesis-1dof.conf
for args in "--from 1e-9 --to 0" "--config $C1 --to 0" "--config $C1 --from 1e-9" \
            "--config $C1 --from 1e-9 --to 1e-9" "--config $C1 --from 1e-9 --to 2e-9" \
            "--config $C1 --from 1e-9 --to 0 --speed 0" "--config $C1 --from 1e-9 --to 0 --speed -1e-6" \
            "--config $C1 --from 1e-9 --to 0 --speed nan" "--config $C1 --from 1e-9 --to -1e-9" \
            "--config $C1 --from 2e-3 --to 0" "--config $C1 --from 1e-9 --to 0 --points 1" \
            "--config $C1 --from 1e-9 --to 0 --points 2.5" "--config $C1 --from 1e-6 --to 0 --speed 1e-12" \
            "--config $C1 --from 1e-9 --to 0 --speed 1 --points 100" \
            "--config /nonexistent.conf --from 1e-9 --to 0" "--config $C1 --from 1e-9 --to 0 --frobnicate"; do
  "$A" force-curve $args > "$T/o.txt" 2> "$T/e.txt"; rc=$?
  [ $rc -eq 2 ] && [ -s "$T/e.txt" ] && [ ! -s "$T/o.txt" ] \
    && ok "force-curve $args: exit 2: $(head -1 "$T/e.txt")" || bad "force-curve $args: exit $rc"
done
"$A" force-curve --from 1e-9 --to 0 2>&1 | grep -q -- "--config is required" \
  && ok "without --config: says --config is required" || bad "without --config: no clear message"
"$A" force-curve --config $C1 --from 1e-9 --to 2e-9 2>&1 | grep -q "must be above --to" \
  && ok "from <= to: says --from must be above --to" || bad "from <= to: no clear message"

# --- one curve against the analytic one: config, from, to, speed, points, want_slope
curve() {
  local conf=$1 from=$2 to=$3 s=$4 n=$5 want_slope=$6 name
  name=$(basename "$conf")
  "$A" force-curve --config "$conf" --from "$from" --to "$to" --speed "$s" --points "$n" --json \
    > "$T/c.json" 2> "$T/c.err"; rc=$?
  [ $rc -eq 0 ] && [ ! -s "$T/c.err" ] && ok "$name: exit 0, nothing on stderr (no terminal)" \
    || { bad "$name: exit $rc: $(head -c 300 "$T/c.err")"; return; }
  local k H R a0 Er f0 al
  k=$(cfg "$conf" stiffness_n_m); H=$(cfg "$conf" hamaker_j); R=$(cfg "$conf" radius_m)
  a0=$(cfg "$conf" a0_m); Er=$(cfg "$conf" reduced_modulus_pa); f0=$(cfg "$conf" resonance_hz)
  al=$(cfg "$conf" inclination_deg)
  [ "$al" = "0.0" ] || [ "$al" = "0" ] || { bad "$name: the analytic curve wants alpha 0"; return; }
  # analytic: C, F_ad, the largest gradient, d*, Z*, x*, pull-off, ramp delay scales
  read -r Fad kmax dst Zst xst Zpo xpo Ts L < <(awk -v k="$k" -v H="$H" -v R="$R" -v a0="$a0" \
    -v f0="$f0" -v s="$s" 'BEGIN { C = H * R / 6; Fad = C / a0^2; kmax = 2 * C / a0^3;
      d = (2 * C / k)^(1 / 3); w = 6.283185307179586 * f0; T = (2 * d / (3 * w^4 * s))^0.2;
      printf "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", Fad, kmax, d, 1.5 * d,
        -d / 2, a0 + Fad / k, -Fad / k, T, 2 * d / (3 * w^2 * T^2) }')
  local sum; sum=$(grep '"summary"' "$T/c.json")
  local np; np=$(grep -c '"direction"' "$T/c.json")
  [ "$np" -eq $((2 * n)) ] && ok "$name: $n records each way" || bad "$name: $np records"
  # every record: force_n = k deflection; Z from --from down to --to and back, exactly at the ends
  if awk -v k="$k" -v from="$from" -v to="$to" -F'[{:,}]' '/"direction"/ {
        for (i = 1; i < NF; i++) { if ($i == "\"z_m\"") z = $(i + 1) + 0; if ($i == "\"deflection_m\"") x = $(i + 1);
          if ($i == "\"force_n\"") f = $(i + 1); if ($i == "\"direction\"") dir = $(i + 1) }
        e = f - k * x; if (e < 0) e = -e; if (e > 1e-12 * (f < 0 ? -f : f) + 1e-30) no = no ? no : 1
        if (m == 0 && z != from + 0) no = no ? no : 2
        if (dir == "\"approach\"" && m > 0 && z > zp) no = no ? no : 3
        if (dir == "\"retract\"" && seen && z < zp) no = no ? no : 4
        if (dir == "\"approach\"") last = z; if (dir == "\"retract\"") seen = 1
        zp = z; m++ }
      END { if (!no && (last != to + 0 || zp != from + 0)) no = 5; exit no }' "$T/c.json"; then
    ok "$name: force_n = k deflection, Z $from -> $to -> $from in order"
  else bad "$name: records inconsistent (awk exit $?)"; fi
  near "$name: spring constant" "$(jnum "$sum" spring_constant_n_m)" "$k" 0
  local tol
  # snap-in, or none when k is above the largest attractive gradient
  if awk -v k="$k" -v m="$kmax" 'BEGIN { exit !(k > m) }'; then
    [ "$(jnum "$sum" snap_in_z_m)" = null ] && ! grep -q '"event":"snap_in"' "$T/c.json" \
      && ok "$name: k $k > max vdW gradient $(printf %.4g "$kmax") N/m: no snap-in" \
      || bad "$name: a snap-in reported though k > max gradient: $(grep snap_in "$T/c.json")"
    tol=$(awk -v s="$s" -v f0="$f0" 'BEGIN { print 2 * s / f0 }')
    near "$name: first contact Z = a0 + F_ad/k (no snap-in)" "$(jnum "$sum" contact_z_m)" "$Zpo" "$tol"
  else
    local ev; ev=$(grep '"event":"snap_in"' "$T/c.json")
    [ -n "$ev" ] && ok "$name: k $k < max vdW gradient $(printf %.4g "$kmax") N/m: snap-in reported" \
      || { bad "$name: no snap-in event"; }
    tol=$(awk -v s="$s" -v T="$Ts" -v Z="$Zst" 'BEGIN { print 5 * s * T + 2e-5 * Z }')
    near "$name: snap-in Z = 1.5 d*" "$(jnum "$sum" snap_in_z_m)" "$Zst" "$tol"
    tol=$(awk -v L="$L" -v x="$xst" 'BEGIN { print 2 * L + 0.007 * (x < 0 ? -x : x) }')
    near "$name: snap-in deflection = -d*/2" "$(jnum "$sum" snap_in_deflection_m)" "$xst" "$tol"
    near "$name: snap-in force = -k d*/2" "$(jnum "$sum" snap_in_force_n)" \
      "$(awk -v k="$k" -v x="$xst" 'BEGIN { printf "%.17g", k * x }')" \
      "$(awk -v k="$k" -v t="$tol" 'BEGIN { print k * t }')"
    near "$name: snap-in event = summary" "$(jnum "$ev" z_m)" "$(jnum "$sum" snap_in_z_m)" 0
  fi
  # adhesion and pull-off
  tol=$(awk -v k="$k" -v s="$s" -v f0="$f0" -v F="$Fad" \
    'BEGIN { print 2 * k * s / (6.283185307179586 * f0) + 1e-5 * F }')
  near "$name: adhesion = -H R / (6 a0^2)" "$(jnum "$sum" adhesion_force_n)" "-$Fad" "$tol"
  tol=$(awk -v s="$s" -v f0="$f0" 'BEGIN { print 2 * s / f0 }')
  near "$name: pull-off Z = a0 + F_ad / k" "$(jnum "$sum" pull_off_z_m)" "$Zpo" "$tol"
  local jump_want=false
  awk -v k="$k" -v m="$kmax" 'BEGIN { exit !(k < m) }' && jump_want=true
  [ "$(jnum "$sum" pull_off_jump)" = $jump_want ] \
    && grep -q "\"event\":\"pull_off\".*\"jump\":$jump_want" "$T/c.json" \
    && ok "$name: pull-off jump $jump_want (the vdW gradient beyond a0 against k)" \
    || bad "$name: pull-off jump: $(jnum "$sum" pull_off_jump), want $jump_want"
  [ "$want_slope" = 1 ] || return
  # contact slope: the tool's records (contact, force in the upper half) at the analytic
  # equilibrium k x = -F_ad + Hc (a0 - x - Z)^1.5, least squares, deflection up per Z down
  local want used
  read -r want used < <(awk -v k="$k" -v H="$H" -v R="$R" -v a0="$a0" -v Er="$Er" -F'[{:,}]' '
    /"direction":"approach"/ && /"contact":true/ {
      for (i = 1; i < NF; i++) { if ($i == "\"z_m\"") z = $(i + 1) + 0; if ($i == "\"force_n\"") f = $(i + 1) }
      n++; Z[n] = z; F[n] = f; if (n == 1 || f < lo) lo = f; if (n == 1 || f > hi) hi = f }
    END { C = H * R / 6; Fad = C / a0^2; Hc = 4 / 3 * Er * sqrt(R); mid = (lo + hi) / 2
      for (i = 1; i <= n; i++) if (F[i] >= mid) {
        u0 = 0; u1 = 1e-8  # u = a0 - d: k (a0 - Z - u) + F_ad - Hc u^1.5 = 0, decreasing in u
        for (it = 0; it < 200; it++) { u = (u0 + u1) / 2
          if (k * (a0 - Z[i] - u) + Fad - Hc * u^1.5 > 0) u0 = u; else u1 = u }
        m++; zz[m] = Z[i]; xx[m] = a0 - Z[i] - u; sz += zz[m]; sx += xx[m] }
      sz /= m; sx /= m
      for (i = 1; i <= m; i++) { szz += (zz[i] - sz)^2; szx += (zz[i] - sz) * (xx[i] - sx) }
      printf "%.17g %d\n", -szx / szz, m }' "$T/c.json")
  [ "$(jnum "$sum" contact_slope_points)" = "$used" ] && [ "$used" -ge 3 ] \
    && ok "$name: contact slope over the $used approach records in the upper half of contact forces" \
    || bad "$name: contact slope points $(jnum "$sum" contact_slope_points), want $used"
  near "$name: contact slope (deflection sensitivity, < 1: the sample yields)" \
    "$(jnum "$sum" contact_slope)" "$want" 1e-4
}
curve config/thesis-1dof.conf 1e-9 0 1e-7 101 1
curve config/lumped-vdw-fold.conf 2.5e-9 0.85e-9 3e-8 34 0

# --- the text table
"$A" force-curve --config config/lumped-vdw-fold.conf --from 2.5e-9 --to 0.85e-9 --speed 1e-6 \
  --points 14 > "$T/t.txt" 2> "$T/t.err"; rc=$?
[ $rc -eq 0 ] && [ "$(grep -c '^approach\|^retract' "$T/t.txt")" -eq 28 ] \
  && grep -q "^# snap_in: Z" "$T/t.txt" && grep -q "^# pull-off: " "$T/t.txt" \
  && grep -q "^# spring constant k 2 N/m" "$T/t.txt" \
  && ok "text: 14 + 14 rows, the events and the summary as # lines" \
  || bad "text table (exit $rc): $(head -c 300 "$T/t.err")"
check_done
