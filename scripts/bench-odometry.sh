#!/usr/bin/env bash
# Odometry benchmark (issue 6): maps the forest-sim handheld and robot
# scenarios with `forest-slam map` (lidar-inertial odometry, no loop closure)
# and prints throughput (scans/s, real-time factor for a 10 Hz VLP-16),
# per-stage milliseconds (median, p95), peak RSS, and the accuracy figures of
# `forest-eval traj` (RPE, vertical drift, ATE, return to start).
# Each scenario runs twice: with the shipped INI (the whole pipeline: loop
# closure, tree layer, every output) and "odometry only", the target of
# issue 6 (front-end + odometry + mapping: the same INI with [loop], the
# tree layer and the file outputs other than trajectory.tum off: nothing is
# then collected for the outputs). ODOMETRY_ONLY=0 skips the second run.
# Scenarios are reused from scripts/bench-sim.sh (BUILD/bench-sim/<name>),
# generated if missing. Usage: scripts/bench-odometry.sh [BUILD] [scenario...]
set -euo pipefail
BUILD=${1:-build}
shift || true
SCENARIOS=${*:-handheld robot}
BIN=$BUILD/bin
OUT=$BUILD/bench-odometry
mkdir -p "$OUT"
for s in $SCENARIOS; do
  sim=$BUILD/bench-sim/$s
  if [ ! -f "$sim/run.rawlog" ]; then
    echo "generating forest-sim $s scenario into $sim"
    "$BIN/forest-sim" --config "ini/sim-$s.ini" --out "$sim" --threads 2 --progress log > "$OUT/sim-$s.log" 2>&1
  fi
  ini=ini/vlp16-handheld.ini
  [ "$s" = robot ] && ini=ini/vlp16-robot.ini
  runs="$s"
  if [ "${ODOMETRY_ONLY:-1}" = 1 ]; then
    # The shipped INI with the back-end, the tree layer and the outputs off.
    python3 - "$ini" "$OUT/$s-odometry.ini" <<'PY'
import sys
sys.path.insert(0, "scripts")
from bench_pipeline import set_ini_key
text = open(sys.argv[1]).read()
for sec, key, val in [("loop", "enabled", "false"), ("trees", "layer_enabled", "false")] + [
        ("outputs", k, "false") for k in ("trajectory_kitti", "keyframes_simplemap", "forest_map", "las",
                                          "octomap_bt", "trees_csv", "trees_geojson", "dtm_asc",
                                          "report_html", "detect_trees_if_empty")]:
    text = set_ini_key(text, sec, key, val)
open(sys.argv[2], "w").write(text)
PY
    runs="$s $s-odometry"
  fi
  for run in $runs; do
  run_ini=$ini
  [ "$run" != "$s" ] && run_ini=$OUT/$run.ini
  /usr/bin/time -f "%M" -o "$OUT/$run.rss" "$BIN/forest-slam" map --config "$run_ini" \
    --rawlog "$sim/run.rawlog" --out "$OUT/$run" --progress log > "$OUT/$run.log" 2>&1
  "$BIN/forest-eval" traj --gt "$sim/gt_trajectory.tum" --est "$OUT/$run/trajectory.tum" \
    --json "$OUT/$run/traj.json" > "$OUT/$run/traj.txt"
  python3 - "$OUT/$run" "$(cat "$OUT/$run.rss")" "$run" "$run_ini" <<'PY'
import json, sys
d, rss_kb, name, ini = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
r = json.load(open(d + "/run_summary.json"))
t = json.load(open(d + "/traj.json"))
what = ("front-end + odometry + mapping" if name.endswith("-odometry")
        else "whole pipeline, shipped INI")
print(f"== {name} ({ini}; {what}): {r['scans_mapped']} scans, {r['data_seconds']:.1f} s of data, "
      f"{t['vertical_drift']['distance_m']:.0f} m")
print(f"  throughput   {r['scans_per_second']:.1f} scans/s, {r['real_time_factor']:.2f}x real time, "
      f"peak RSS {rss_kb/1024:.0f} MB (targets: >= 100 scans/s, 10x); end to end with the outputs "
      f"{r.get('scans_per_second_end_to_end', 0):.1f} scans/s ({r.get('total_wall_seconds', 0):.1f} s)")
print("  stage ms     " + ", ".join(f"{k} {v['median']:.1f}/{v['p95']:.1f}" for k, v in r["stage_ms"].items())
      + "  (median/p95)")
rpe = t["rpe"]
print(f"  RPE          {rpe['trans_err_pct']:.3f} %, {rpe['rot_err_deg_per_m']:.4f} deg/m "
      "(targets handheld 0.5 %, 0.002 deg/m; robot 1.0 %, 0.004 deg/m)")
v = t["vertical_drift"]
print(f"  vertical     end {v['end_pct']:.3f} %, max {v['max_pct']:.3f} % of distance (target 0.3 %)")
a = t["ate"]["aligned_se3"]["trans_m"]["rmse"]
rs = t["return_to_start"]["estimate_vs_gt"]
print(f"  ATE aligned  {a:.3f} m; return to start {rs['total_trans_m']:.3f} m, {rs['angle_deg']:.2f} deg; "
      f"IMU scans {r.get('scans_imu', 0)}, degenerate {r['scans_degenerate']}, unregistered {r['scans_unregistered']}")
PY
  done
done
