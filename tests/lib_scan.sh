# lib_scan.sh -- sourced by the tests where an outside controller (tests/scan_client.c) images
# a step over LCM (test_scan_daemon.sh, test_scan_rt.sh): judge reads its image against the
# analytic step (H, POS, EDGE of the caller), rt_judge the daemon's statuses under the scan;
# scan_client_build builds the controller.

# scan_client_build BUILD OUT: tests/scan_client.c against BUILD's message library into OUT
# (ok, or bad with the compiler's first lines, the counts printed and 1 returned).
scan_client_build() {
  if cc -std=c11 -O2 -Wall -Wextra -Werror -D_POSIX_C_SOURCE=200809L -I"$1/gen" -Imsgtypes \
       -o "$2" tests/scan_client.c "$1/lib/libafmtwin_msg.a" -llcm -lm 2> "$2.err"; then
    ok "tests/scan_client.c builds"
  else
    bad "scan_client build: $(head -3 "$2.err")"; echo "$pass passed, $fail failed"; return 1
  fi
}

# judge IMG: the controller's image (scan_client's records) against the truth; one line
judge() {
python3 - "$1" $POS $EDGE $H <<'EOF'
import sys
pos, edge, H = map(float, sys.argv[2:5])
R = [list(map(float, l.split())) for l in open(sys.argv[1]) if l.strip()]
# plateaus away from the edge and its settling: lower 110..170 nm, upper 240..300 nm
lo = [r for r in R if 1.1e-7 <= r[1] <= 1.7e-7]
hi = [r for r in R if 2.4e-7 <= r[1] <= 3.0e-7]
if len(lo) < 10 or len(hi) < 10:
    print("FAIL too few records on the plateaus (%d, %d of %d)" % (len(lo), len(hi), len(R))); sys.exit()
zlo = sum(r[4] for r in lo) / len(lo); zhi = sum(r[4] for r in hi) / len(hi)
step = zhi - zlo
# the controller's image against the truth point by point on the plateaus: Z - z_s constant
glo = [r[4] - r[3] for r in lo]; ghi = [r[4] - r[3] for r in hi]
spread = max(glo + ghi) - min(glo + ghi)
rel = (step - H) / H
good = abs(rel) <= 0.02
print("%s step %.4f nm (true %.4f nm, %+.3f %%) from %d + %d records; Z - z_s on the plateaus spread %.4f nm" %
      ("ok" if good else "FAIL", step * 1e9, H * 1e9, 100 * rel, len(lo), len(hi), spread * 1e9))
EOF
}

# rt_judge STATUS_JSONL STRICT(0/1) SPEED: one line "ok|info|FAIL ...": the statuses from 1 s
# in (realtime_factor_1s covers a whole second) as a share of the speed asked for, >= 0.99
# in every one and no resync; STRICT 1 makes a miss FAIL, 0 info.
rt_judge() {
python3 - "$1" "$2" "$3" <<'EOF'
import json, sys
L = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
speed = float(sys.argv[3])
L = L[10:] # from 1 s in: realtime_factor_1s covers a whole second
if len(L) < 5:
    print("FAIL %d statuses under the scan" % len(L)); sys.exit()
rtf = [d['realtime_factor_1s'] / speed for d in L] # of the speed asked for
res = L[-1]['resyncs'] - L[0]['resyncs']
good = min(rtf) >= 0.99 and res == 0
tag = "ok" if good else ("FAIL" if sys.argv[2] == "1" else "info")
print("%s under the scan (%d statuses, %.2f s of model time): realtime_factor_1s / speed min %.4f, resyncs %d" %
      (tag, len(L), L[-1]['model_time_s'] - L[0]['model_time_s'], min(rtf), res))
EOF
}
