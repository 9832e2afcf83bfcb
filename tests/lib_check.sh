# lib_check.sh -- sourced by the shell tests that need no daemon: check_init NAME BUILD
# goes to the repository root and sets A (the afmtwin binary), T (a scratch directory,
# removed at exit) and the pass / fail counters that ok, bad and check_done keep and print
# ("N passed, N failed", the line tests/run.sh adds up).
check_init() {
  cd "$(dirname "$0")/.." || exit 1
  A="${2:-build}/bin/afmtwin"
  pass=0; fail=0
  T=$(mktemp -d "/tmp/afmtwin-$1.XXXXXX")
  trap 'rm -rf "$T"' EXIT
}
ok()  { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
# gsf_thumbnails FILE...: Gwyddion's own reader (gwyddion-thumbnailer, asked for by the
# caller) makes a PNG thumbnail of every FILE; 0 when all came out, else 1 with each
# refused file and the reader's complaint printed. The thumbnails lie beside the files.
gsf_thumbnails() {
  local f all=0
  for f in "$@"; do
    gwyddion-thumbnailer gnome2 64 "$f" "${f%.gsf}.png" 2> "$T/th.err" \
      && [ "$(head -c 4 "${f%.gsf}.png" | tail -c 3)" = PNG ] \
      || { all=1; echo "     $f: $(head -c 200 "$T/th.err")"; }
  done
  return $all
}
check_done() {
  echo "$pass passed, $fail failed"
  [ "$fail" -eq 0 ]
}
