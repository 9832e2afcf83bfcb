#!/usr/bin/env bash
# deb.sh OUT -- `make deb`: dpkg-buildpackage -us -uc -b on a copy of this tree (so that its
# build/ stays), the packages into OUT; then each unpacked into a scratch root (dpkg -x) and
# used from there: `afmtwin modes` on a thesis config, the daemon's --version, the conffile,
# the unit, and the -dev part building examples/hil_pi through pkg-config. The binaries are
# the portable build (AFMTWIN_MARCH=portable): no AVX outside the run-time-chosen copies.
# Prints "N passed, N failed".
set -u
OUT=${1:-build/deb}
cd "$(dirname "$0")/.." || exit 1
pass=0; fail=0
ok()  { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
S=$(mktemp -d /tmp/afmtwin-deb.XXXXXX)
trap 'rm -rf "$S"' EXIT
mkdir -p "$S/src" "$OUT"
# the tracked and the new files of the working tree, not build/ or .git
git ls-files -co --exclude-standard -z | grep -zv '^build/' | xargs -0 cp --parents -t "$S/src"
( cd "$S/src" && dpkg-buildpackage -us -uc -b ) > "$S/build.log" 2>&1; rc=$?
if [ $rc -ne 0 ]; then
  bad "dpkg-buildpackage -us -uc -b: exit $rc: $(tail -15 "$S/build.log")"
  echo "$pass passed, $fail failed"; exit 1
fi
cp "$S"/*.deb "$OUT"/
debs=$(cd "$OUT" && ls afmtwind_*.deb afmtwin-tools_*.deb libafmtwin-msg1_*.deb libafmtwin-msg-dev_*.deb 2>/dev/null | wc -l)
[ "$debs" -eq 4 ] && ok "dpkg-buildpackage built 4 packages: $(cd "$OUT" && ls *.deb | tr '\n' ' ')" ||
  bad "packages: $(ls "$OUT")"
R="$S/root"
for d in "$OUT"/*.deb; do dpkg -x "$d" "$R"; done
out=$("$R/usr/bin/afmtwin" modes --config "$R/usr/share/afmtwin/config/thesis-table-3-1.conf" 2>&1); rc=$?
[ $rc -eq 0 ] && echo "$out" | grep -qi "hz" && ok "afmtwin modes from the unpacked package: $(echo "$out" | head -3 | tr '\n' '|' | cut -c1-160)" ||
  bad "afmtwin modes: exit $rc: $out"
v=$("$R/usr/bin/afmtwind" --version 2>&1)
[ "$v" = "afmtwind $(dpkg-parsechangelog -S Version)" ] && ok "afmtwind --version: $v" || bad "afmtwind --version: $v"
dpkg-deb --ctrl-tarfile "$OUT"/afmtwind_*.deb | tar -xO ./conffiles 2>/dev/null | grep -qx /etc/afmtwin/afmtwind.conf &&
  ok "afmtwind: /etc/afmtwin/afmtwind.conf is a conffile" || bad "afmtwind conffiles"
grep -q 'ExecStart=/usr/bin/afmtwind --config /etc/afmtwin/afmtwind.conf' "$R/lib/systemd/system/afmtwind.service" &&
  ok "the unit runs /usr/bin/afmtwind on the conffile" || bad "unit: $(grep ExecStart "$R"/lib/systemd/system/afmtwind.service)"
dep=$(dpkg-deb -f "$OUT"/afmtwind_*.deb Depends)
echo "$dep" | grep -q liblcm && ok "afmtwind Depends (shlibs): $dep" || bad "afmtwind Depends: $dep"
# -march of the package: the default copy must not need AVX. Per object of the same build
# (debian/build/obj; the packaged binary is stripped): any ymm register use must be inside
# the x86-64-v3 clones (named *.arch_x86_64_v3*) or in the integrator's x86-64-v3 copy
# (afm_rt_v3.o, chosen at run time by afm_sim.c), which must exist.
O="$S/src/debian/build/obj"
fns=$(find "$O" -name '*.o' ! -name afm_rt_v3.o -exec objdump -d --no-show-raw-insn {} + |
  awk '/^[0-9a-f]+ <.*>:$/ {fn=$2} /%ymm/ {print fn}' | sort -u)
bad_fn=$(echo "$fns" | grep -v 'arch_x86_64_v3' | grep . | head -5)
v3=$(find "$O" -name afm_rt_v3.o -exec objdump -d --no-show-raw-insn {} + | grep -c '%ymm')
[ -n "$fns" ] && [ -z "$bad_fn" ] && [ "$v3" -gt 0 ] &&
  ok "afmtwind (portable): AVX registers only in the x86-64-v3 clones ($(echo "$fns" | tr -d '<>:' | tr '\n' ' ')) and the integrator's v3 copy ($v3 instructions)" ||
  bad "AVX outside the clones in: $bad_fn (clones: $fns; v3 copy: $v3 ymm instructions)"
L=$(ls -d "$R"/usr/lib/*-linux-gnu | head -1)
export PKG_CONFIG_PATH="$L/pkgconfig" PKG_CONFIG_SYSROOT_DIR="$R"
make -s -C "$R/usr/share/doc/afmtwin/examples" OUT="$S" > "$S/ex.log" 2>&1 &&
  LD_LIBRARY_PATH="$L" "$S/hil_pi" --help > /dev/null && ok "libafmtwin-msg-dev: examples/hil_pi builds with pkg-config and runs" ||
  bad "hil_pi from the package: $(tail -5 "$S/ex.log")"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
