#!/usr/bin/env bash
# `make demo`: the main job on a built-in demo. Today: simulate a small forest
# (forest-sim, ini/sim-tiny.ini), map it with forest-slam (lidar odometry,
# ini/vlp16-handheld.ini), then score the trajectory against the simulator's
# ground truth with forest-eval; ends by listing the output files (LAS,
# OctoMap, trees, DTM, report, ...) with one line each. Grows with the
# pipeline.
set -euo pipefail
BUILD=${1:-build}
OUT=${2:-$BUILD/demo}
BIN=$BUILD/bin
mkdir -p "$OUT"

if [ -x "$BIN/forest-sim" ]; then
  echo "== 1/3 forest-sim: simulating a small forest (ini/sim-tiny.ini, seed 1)"
  "$BIN/forest-sim" --config ini/sim-tiny.ini --seed 1 --out "$OUT/sim"
  echo "== 2/3 forest-slam map (lidar odometry, ini/vlp16-handheld.ini)"
  "$BIN/forest-slam" map --config ini/vlp16-handheld.ini --rawlog "$OUT/sim/run.rawlog" \
      --out "$OUT/map" --progress log | tee "$OUT/map.log"
  if [ -x "$BIN/forest-eval" ]; then
    echo "== 3/3 forest-eval traj (estimate vs ground truth)"
    "$BIN/forest-eval" traj --gt "$OUT/sim/gt_trajectory.tum" --est "$OUT/map/trajectory.tum" \
        --json "$OUT/traj_metrics.json"
  fi
  echo "== trees in the scene (ground truth): $(($(wc -l < "$OUT/sim/gt_trees.csv") - 1))"
else
  echo "== forest-sim is not built: mapping the real MRPT VLP-16 sample instead"
  sed 's/^lidar_label = lidar/lidar_label = Velodyne1_SCAN/' ini/vlp16-handheld.ini > "$OUT/demo-map.ini"
  "$BIN/forest-slam" map --config "$OUT/demo-map.ini" \
      --rawlog ../shared/data/mrpt/rot_scan_velodyne.rawlog --out "$OUT/map" --progress log \
      | tee "$OUT/map.log"
fi
echo "== outputs (doc/outputs.md describes every format and column):"
grep '^wrote ' "$OUT/map.log" | sed 's/^wrote /  /'
echo "== open the report: xdg-open $OUT/map/report.html"
