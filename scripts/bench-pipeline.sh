#!/usr/bin/env bash
# Whole-pipeline benchmark (issue 11): scripts/bench_pipeline.py on the
# forest-sim handheld and robot scenarios (odometry, tree layer, every
# default output), throughput, per-stage ms, peak RSS and the memory curve,
# accuracy. Writes BUILD/bench-pipeline.json. MAX_SCANS=N shortens each
# run. The 60-minute memory run is on demand only:
#   scripts/bench_pipeline.py --build build --scenarios long --json long.json
# Usage: scripts/bench-pipeline.sh [BUILD_DIR] [scenario...]
set -euo pipefail
BUILD=${1:-build}
shift || true
SCENARIOS=${*:-handheld robot}
# shellcheck disable=SC2086
exec python3 scripts/bench_pipeline.py --build "$BUILD" --scenarios $SCENARIOS \
  --json "$BUILD/bench-pipeline.json"
