#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_fuzz.sh BUILD -- the short fuzz run of `make test`: builds the harnesses
# (`make sanitize-build` into BUILD/san) and runs each for 3 s (tests/fuzz.sh). `make fuzz`
# runs each for 1e7 inputs.
set -u
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/san_build.sh
san_build "$BUILD" fuzzers
exec bash tests/fuzz.sh "$BUILD/san" 0 "${AFMTWIN_FUZZ_SECONDS:-3}"
