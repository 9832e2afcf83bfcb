# SPDX-License-Identifier: MIT
# san_build.sh -- sourced by the test scripts that need the sanitizer build: `san_build
# BUILD` makes BUILD/san (`make sanitize-build`: clang, ASan + LSan + UBSan, the fuzzers),
# quietly; on failure it prints why and the closing "0 passed, 1 failed" and exits.
san_build() {
  if ! command -v clang >/dev/null; then
    echo "FAIL clang is not installed (Debian packages clang libclang-rt-dev: make deps)"
    echo "0 passed, 1 failed"; exit 1
  fi
  local out
  # -j2: the build machine has two cores (this runs outside the caller's make jobserver)
  if ! out=$(make --no-print-directory -s -j2 sanitize-build BUILD="$1" 2>&1); then
    echo "$out" | tail -20
    echo "FAIL make sanitize-build"; echo "0 passed, 1 failed"; exit 1
  fi
}
