#!/usr/bin/env bash
# Front-end per-scan timings (ground lattice, clustering) on a real VLP-16 scan.
set -euo pipefail
BUILD=${1:-build}
"$BUILD/bin/bench_frontend" ../shared/data/mrpt/rot_scan_velodyne.rawlog 300
