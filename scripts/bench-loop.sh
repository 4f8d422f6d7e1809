#!/usr/bin/env bash
# Back-end benchmark (issue 8, doc/backend.md): forest-sim scenarios mapped
# by `forest-slam map` with the odometry alone and with [loop] enabled, the
# odometry drift optionally forced by injection. Prints, per run: return to
# start, ATE (unaligned, the map frame is the GT's), closures accepted and
# how many are false (measured pose > 0.5 m or 3 deg from the GT relative
# pose of the two keyframes), back-end worker ms, throughput.
# Scenarios: tiny loop (ini/sim-tiny.ini), plantation out and back
# (ini/sim-plantation.ini), generated into BUILD/bench-loop/; then issue
# 8's targets on the full handheld and robot scenarios (BUILD/bench-sim/,
# shared with scripts/bench_pipeline.py; generated if missing; trees and
# outputs other than the trajectory off): handheld return to start and ATE,
# robot ATE, robot with GNSS (mean drift against the GT). LOOP_FULL=0 skips
# the full scenarios (about 12 minutes on 2 cores).
# Usage: scripts/bench-loop.sh [BUILD]
set -euo pipefail
BUILD=${1:-build}
BIN=$BUILD/bin
OUT=$BUILD/bench-loop
mkdir -p "$OUT"

# ini_with_loop BASE_INI "key = value\n..." > FILE: the shipped INI with its
# [loop] enabled (whatever the shipped value) and the given keys.
ini_with_loop() {
  python3 - "$1" "$2" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
m = re.search(r"\n\[loop\]\n(?:.*\n)*?enabled = \w+\n", t)
assert m, "no [loop] enabled line in " + sys.argv[1]
keys = "enabled = true\n" + sys.argv[2].replace("\\n", "\n") + "\n"
print(t[:m.end()].rsplit("enabled = ", 1)[0] + keys + t[m.end():])
PY
}

figures() {  # DIR SIMDIR LABEL
  "$BIN/forest-eval" traj --gt "$2/gt_trajectory.tum" --est "$1/trajectory.tum" \
    --json "$1/traj.json" > /dev/null
  python3 - "$1" "$2" "$3" <<'PY'
import json, math, sys, bisect, csv, os
d, sim, label = sys.argv[1:4]
t = json.load(open(d + "/traj.json")); r = json.load(open(d + "/run_summary.json"))
rs = t["return_to_start"]["estimate_vs_gt"]
line = (f"  {label:28s} return {rs['total_trans_m']:.3f} m {rs['total_rot_deg']:.2f} deg, "
        f"ATE {t['ate']['unaligned']['trans_m']['rmse']:.3f} m (aligned "
        f"{t['ate']['aligned_se3']['trans_m']['rmse']:.3f}, unaligned mean "
        f"{t['ate']['unaligned']['trans_m']['mean']:.3f}), {r['scans_per_second']:.1f} scans/s")
lp = r.get("loop")
if lp and lp.get("gnss_fixes"):
    e = lp.get("map_to_enu", {})
    line += (f"\n  {'':28s} GNSS {lp['gnss_fixes']} fixes, {lp['gnss_outliers']} outliers, "
             f"map->ENU yaw {e.get('yaw_deg', float('nan')):.3f} deg")
if lp:
    # Closures against the GT (quaternion maths without numpy).
    def qmul(a, b):
        x1, y1, z1, w1 = a; x2, y2, z2, w2 = b
        return (w1*x2+x1*w2+y1*z2-z1*y2, w1*y2-x1*z2+y1*w2+z1*x2,
                w1*z2+x1*y2-y1*x2+z1*w2, w1*w2-x1*x2-y1*y2-z1*z2)
    def conj(q): return (-q[0], -q[1], -q[2], q[3])
    def rot(q, v): return qmul(qmul(q, (v[0], v[1], v[2], 0)), conj(q))[:3]
    gt = [list(map(float, l.split())) for l in open(sim + "/gt_trajectory.tum")
          if l.strip() and not l.startswith("#")]
    ts = [g[0] for g in gt]
    def at(tt):
        i = min(max(bisect.bisect_left(ts, tt), 0), len(ts) - 1)
        g = gt[i]; return g[1:4], g[4:8]
    def rel(a, b):
        qi = conj(a[1]); return rot(qi, [b[0][k] - a[0][k] for k in range(3)]), qmul(qi, b[1])
    acc = bad = 0; worst = (0.0, 0.0); yaws = []
    for c in csv.DictReader(open(d + "/loop_closures.csv")):
        if c["accepted"] != "1": continue
        acc += 1
        g = rel(at(float(c["from_t_s"])), at(float(c["to_t_s"])))
        m = ([float(c[k]) for k in ("x", "y", "z")], [float(c[k]) for k in ("qx", "qy", "qz", "qw")])
        e = rel(g, m)
        dm = math.sqrt(sum(x * x for x in e[0])); dd = 2 * math.degrees(math.acos(min(1, abs(e[1][3]))))
        worst = (max(worst[0], dm), max(worst[1], dd))
        # Signed yaw error: a bias turns every later pass the same way.
        x, y, z, w = e[1]
        yaws.append(math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))))
        bad += dm > 0.5 or dd > 3
    line += (f"\n  {'':28s} {lp['keyframes']} keyframes, {lp['candidates']} candidates, {acc} closures "
             f"({bad} false; worst {worst[0]:.3f} m {worst[1]:.2f} deg vs GT; yaw error mean "
             f"{1e3 * sum(yaws) / max(1, len(yaws)):+.1f} mdeg, RMS "
             f"{1e3 * math.sqrt(sum(v * v for v in yaws) / max(1, len(yaws))):.1f}), worker "
             f"{lp['verify_ms']/1e3:.1f} s verify + {lp['optimise_ms']/1e3:.2f} s optimise")
print(line)
PY
}

for s in tiny plantation; do
  sim=$OUT/sim-$s
  if [ ! -f "$sim/run.rawlog" ]; then
    "$BIN/forest-sim" --config "ini/sim-$s.ini" --out "$sim" --progress log > "$OUT/sim-$s.log" 2>&1
  fi
  base=ini/vlp16-handheld.ini
  [ "$s" = plantation ] && base=ini/vlp16-robot.ini
  echo "== $s ($base, forest-sim ini/sim-$s.ini)"
  drift='inject_yaw_deg_per_m = 0.1\ninject_z_m_per_m = 0.005\n'
  fast='detect_every_keyframes = 1\nclosure_spacing_keyframes = 1\n'
  [ "$s" = plantation ] && fast='min_travel_m = 15\ndetect_every_keyframes = 1\nclosure_spacing_keyframes = 2\n'
  for run in odometry loop odometry+drift loop+drift; do
    case $run in
      odometry) keys='min_travel_m = 1e9' ;;
      loop) keys=$fast ;;
      odometry+drift) keys="${drift}min_travel_m = 1e9" ;;
      loop+drift) keys="$drift$fast" ;;
    esac
    ini_with_loop "$base" "$keys" > "$OUT/$s-$run.ini"
    "$BIN/forest-slam" map --config "$OUT/$s-$run.ini" --rawlog "$sim/run.rawlog" \
      --out "$OUT/$s-$run" --progress log > "$OUT/$s-$run.log" 2>&1
    figures "$OUT/$s-$run" "$sim" "$run"
  done
done

[ "${LOOP_FULL:-1}" = 0 ] && exit 0
# The full scenarios: the shipped INIs ([loop] on), outputs but the
# trajectory off, tree layer off (its time is the pipeline benchmark's).
full_ini() {  # BASE EXTRA_LOOP_KEYS > FILE
  python3 - "$1" "$2" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
m = re.search(r"\n\[loop\]\n(?:.*\n)*?enabled = \w+\n", t)
assert m, "no [loop] enabled line in " + sys.argv[1]
keys = "enabled = true\n" + sys.argv[2].replace("\\n", "\n") + "\n"
t = t[:m.end()].rsplit("enabled = ", 1)[0] + keys + t[m.end():]
print(t + "\n[outputs]\nkeyframes_simplemap = false\nforest_map = false\nlas = false\n"
      "octomap_bt = false\ntrees_csv = false\ntrees_geojson = false\ndtm_asc = false\n"
      "report_html = false\ntrajectory_kitti = false\ndetect_trees_if_empty = false\n"
      "\n[trees]\nlayer_enabled = false\n")
PY
}
for s in handheld robot; do
  sim=$BUILD/bench-sim/$s
  if [ ! -f "$sim/run.rawlog" ] || [ ! -f "$sim/scenario.ini" ]; then
    mkdir -p "$BUILD/bench-sim"
    "$BIN/forest-sim" --config "ini/sim-$s.ini" --out "$sim" --threads 2 \
      --progress log > "$sim.log" 2>&1
  fi
done
echo "== issue 8 targets on the full scenarios (forest-sim ini/sim-{handheld,robot}.ini)"
full_ini ini/vlp16-handheld.ini "" > "$OUT/full-handheld.ini"
full_ini ini/vlp16-robot.ini "" > "$OUT/full-robot.ini"
full_ini ini/vlp16-robot.ini "gnss_enabled = true" > "$OUT/full-robot-gnss.ini"
for run in handheld robot robot-gnss; do
  s=${run%-gnss}
  "$BIN/forest-slam" map --config "$OUT/full-$run.ini" --rawlog "$BUILD/bench-sim/$s/run.rawlog" \
    --out "$OUT/full-$run" --progress log > "$OUT/full-$run.log" 2>&1
  figures "$OUT/full-$run" "$BUILD/bench-sim/$s" "$run"
done
python3 - "$OUT" <<'PY'
import json, sys
o = sys.argv[1]
def t(run): return json.load(open(f"{o}/full-{run}/traj.json"))
def verdict(ok): return "met" if ok else "NOT MET"
h, r, g = t("handheld"), t("robot"), t("robot-gnss")
rs = h["return_to_start"]["estimate_vs_gt"]
ha = h["ate"]["aligned_se3"]["trans_m"]["rmse"]
ra = r["ate"]["aligned_se3"]["trans_m"]["rmse"]
gm = g["ate"]["unaligned"]["trans_m"]["mean"]
print("  targets (issue 8):")
print(f"    handheld return to start {rs['total_trans_m']:.3f} m (<= 0.05), "
      f"{rs['total_rot_deg']:.2f} deg (<= 0.3): "
      f"{verdict(rs['total_trans_m'] <= 0.05 and rs['total_rot_deg'] <= 0.3)}")
print(f"    handheld ATE (aligned) {ha:.3f} m (<= 0.10): {verdict(ha <= 0.10)}")
print(f"    robot ATE (aligned) {ra:.3f} m (<= 0.20): {verdict(ra <= 0.20)}")
print(f"    robot with GNSS, mean drift against the GT (unaligned, map frame) "
      f"{gm:.3f} m (<= 0.3): {verdict(gm <= 0.3)}")
PY
