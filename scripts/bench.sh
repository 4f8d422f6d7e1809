#!/usr/bin/env bash
# `make bench`: benchmarks that print figures (never timed unit tests).
# Each module adds its own scripts/bench-*.sh; this runs them all.
set -euo pipefail
BUILD=${1:-build}
found=0
for b in scripts/bench-*.sh; do
  [ -e "$b" ] || continue
  found=1
  echo "== $b"
  bash "$b" "$BUILD"
done
[ $found -eq 1 ] || echo "no benchmarks yet (scripts/bench-*.sh)"
