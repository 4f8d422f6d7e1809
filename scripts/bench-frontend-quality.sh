#!/usr/bin/env bash
# Front-end quality against forest-sim ground truth on the handheld and
# robot scenarios, with the shipped INIs' [ground] [cluster] [features]:
# ground precision/recall, clusters mixing two GT trees, edges on
# stems/branches, and per-stage ms per scan (single thread, wall time).
# Reuses BUILD/bench-sim/<scenario> (scripts/bench-sim.sh) and generates a
# scenario that is missing (about 2 and 4 minutes on 2 cores).
# Targets (issue 5): precision >= 98 %, recall >= 97 %, mixing <= 5 %,
# edges on stems/branches >= 85 %. Definitions: doc/frontend.md.
set -euo pipefail
BUILD=${1:-build}
OUT="$BUILD/bench-sim"
for scenario in handheld robot; do
  dir="$OUT/$scenario"
  if [ ! -f "$dir/run.rawlog" ] || [ ! -f "$dir/gt_trajectory.tum" ]; then
    echo "generating $dir (forest-sim, ini/sim-$scenario.ini)"
    mkdir -p "$OUT"
    "$BUILD/bin/forest-sim" --config "ini/sim-$scenario.ini" --out "$dir" \
      --threads 2 --progress log >"$OUT/$scenario.log" 2>&1 ||
      { echo "forest-sim failed, see $OUT/$scenario.log" >&2; exit 1; }
  fi
  ini=ini/vlp16-handheld.ini
  [ "$scenario" = robot ] && ini=ini/vlp16-robot.ini
  echo "== $scenario ($ini)"
  "$BUILD/bin/bench_frontend_quality" "$dir" --ini "$ini"
done
