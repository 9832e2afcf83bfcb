#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_fuzz.sh BUILD -- the short fuzz run of `make test`: builds the harnesses
# (`make sanitize-build` into BUILD/san) and runs each for 3 s (tests/fuzz.sh). `make fuzz`
# runs each for 1e7 inputs.
set -u
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
if ! command -v clang >/dev/null; then
  echo "FAIL clang is not installed (Debian packages clang libclang-rt-dev: make deps)"
  echo "0 passed, 1 failed"; exit 1
fi
if ! out=$(make --no-print-directory -s sanitize-build BUILD="$BUILD" 2>&1); then
  echo "$out" | tail -20
  echo "FAIL make sanitize-build"; echo "0 passed, 1 failed"; exit 1
fi
exec bash tests/fuzz.sh "$BUILD/san" 0 "${AFMTWIN_FUZZ_SECONDS:-3}"
