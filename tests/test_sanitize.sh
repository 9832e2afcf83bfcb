#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_sanitize.sh BUILD -- the short sanitizer run of `make test`: builds BUILD/san
# (`make sanitize-build`, clang with ASan + LSan + UBSan) and runs the decoder and engine
# subset of the unit tests there (tests/sanitize.sh short). `make sanitize` runs them all.
set -u
BUILD=${1:-build}
cd "$(dirname "$0")/.." || exit 1
. tests/san_build.sh
san_build "$BUILD" $(for t in $SAN_SHORT; do echo tests/$t; done)
exec bash tests/sanitize.sh "$BUILD/san" short
