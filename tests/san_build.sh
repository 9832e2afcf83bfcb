# SPDX-License-Identifier: MIT
# san_build.sh -- sourced by the test scripts that need the sanitizer build: `san_build
# BUILD [GOAL...]` makes what the caller runs in BUILD/san (`make sanitize-build
# SAN_GOALS=...`: clang, ASan + LSan + UBSan; GOALs relative to BUILD/san, e.g. bin/afmtwind, or
# the phony fuzzers; everything when none), quietly; on failure it prints why and the closing
# "0 passed, 1 failed" and exits. make test's scripts build only what they run: the
# sanitized tools and the other unit tests are `make sanitize`'s (about half the build).
# SAN_SHORT: the decoder and engine unit tests that take seconds sanitized (make test's
# tests/test_sanitize.sh; tests/sanitize.sh short).
SAN_SHORT="test_cmd test_wire test_can_codec test_config test_runner test_spsc test_force test_model
           test_cycle test_orbit test_sundials test_obd"
san_build() {
  if ! command -v clang >/dev/null; then
    echo "FAIL clang is not installed (Debian packages clang libclang-rt-dev: make deps)"
    echo "0 passed, 1 failed"; exit 1
  fi
  local out b=$1 goals="" g
  shift
  # a file under BUILD/san (bin/afmtwind) or a phony goal of the Makefile (fuzzers)
  for g in "$@"; do case $g in */*) goals="$goals $b/san/$g" ;; *) goals="$goals $g" ;; esac; done
  [ -n "$goals" ] || goals="core fuzzers"
  # -j2: the build machine has two cores (this runs outside the caller's make jobserver);
  # SAN_JOBS=1 when run.sh makes it beside the unit tests
  if ! out=$(make --no-print-directory -s -j"${SAN_JOBS:-2}" sanitize-build BUILD="$b" SAN_GOALS="$goals" 2>&1); then
    echo "$out" | tail -20
    echo "FAIL make sanitize-build"; echo "0 passed, 1 failed"; exit 1
  fi
}
