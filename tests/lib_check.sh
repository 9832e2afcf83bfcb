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
check_done() {
  echo "$pass passed, $fail failed"
  [ "$fail" -eq 0 ]
}
