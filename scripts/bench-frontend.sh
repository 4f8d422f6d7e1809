#!/usr/bin/env bash
# Front-end per-scan timings (Google Benchmark): ground lattice, clustering,
# features, each on one core, on the real VLP-16 scan of
# ../shared/data/mrpt/rot_scan_velodyne.rawlog and, when the forest-sim
# handheld run of scripts/bench-sim.sh exists in BUILD/bench-sim, on one of
# its forest scans, with the [ground] [cluster] [features] options of
# ini/vlp16-handheld.ini. Targets (issue 5): ground <= 1 ms, cluster <= 3 ms,
# features <= 1 ms per scan. Quality figures: scripts/bench-frontend-quality.sh.
set -euo pipefail
BUILD=${1:-build}
if [ -f "$BUILD/bench-sim/handheld/run.rawlog" ]; then
  export FOREST_SLAM_BENCH_SIM="$BUILD/bench-sim/handheld"
fi
"$BUILD/bin/bench_frontend_stages" --benchmark_min_time=0.5
