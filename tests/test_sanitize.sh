#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_sanitize.sh BUILD -- the short sanitizer run of `make test`: builds BUILD/san
# (`make sanitize-build`, clang with ASan + LSan + UBSan) and runs the decoder and engine
# subset of the unit tests there (tests/sanitize.sh short). `make sanitize` runs them all.
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
exec bash tests/sanitize.sh "$BUILD/san" short
