#!/usr/bin/env bash
# forest-sim benchmark: generates the handheld and robot scenarios and prints
# the generation speed (scans/s). Target: >= 20 VLP-16 scans/s on 2 cores.
# Usage: scripts/bench-sim.sh [BUILD_DIR]   (outputs kept in BUILD_DIR/bench-sim
# for other benchmarks to reuse: <scenario>/run.rawlog, gt_*.*, scenario.ini)
set -euo pipefail
BUILD=${1:-build}
SIM="$BUILD/bin/forest-sim"
OUT="$BUILD/bench-sim"
if [ ! -x "$SIM" ]; then
  echo "bench-sim: $SIM not found (build the forest-sim target first)" >&2
  exit 1
fi
mkdir -p "$OUT"
echo "forest-sim benchmark on $(nproc) cores ($(uname -m))"
printf '%-9s %8s %7s %8s %18s %16s %10s\n' scenario data_s scans route_m "ray-cast scans/s" "overall scans/s" wall_s
for scenario in handheld robot; do
  log="$OUT/$scenario.log"
  start=$(date +%s.%N)
  "$SIM" --config "ini/sim-$scenario.ini" --out "$OUT/$scenario" --threads 2 \
    --progress log >"$log" 2>&1 || { echo "bench-sim: $scenario failed, see $log" >&2; exit 1; }
  end=$(date +%s.%N)
  # "scenario: handheld, seed 1: 421.5 s of data, route 478 m, ..."
  data_s=$(sed -n 's/^scenario: .*: \([0-9.]*\) s of data, route \([0-9]*\) m.*/\1/p' "$log")
  route=$(sed -n 's/^scenario: .*, route \([0-9]*\) m.*/\1/p' "$log")
  scans=$(sed -n 's/^data: \([0-9]*\) scans.*/\1/p' "$log")
  cast=$(sed -n 's/^speed: \([0-9.]*\) scans\/s ray casting.*/\1/p' "$log")
  wall=$(echo "$end - $start" | bc -l)
  overall=$(echo "$scans / $wall" | bc -l)
  printf '%-9s %8.1f %7d %8d %18.1f %16.1f %10.1f\n' "$scenario" "$data_s" "$scans" "$route" "$cast" "$overall" "$wall"
done
echo "ray-cast scans/s: lidar simulation only (2 threads); overall: everything"
echo "including world generation, IMU/GNSS and writing the gzip rawlog."
