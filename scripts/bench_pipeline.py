#!/usr/bin/env python3
"""Whole-pipeline benchmark (issue 11): forest-slam map on forest-sim
scenarios with the shipped configs (odometry, tree layer and every default
output on), then forest-eval. Prints and optionally writes as JSON:
throughput (scans/s over wall and CPU time, real-time factor for a 10 Hz
VLP-16), per-stage milliseconds (median, p95, max), peak RSS and the memory
curve (RSS every [pipeline] memory_report_period_s of data), the map's
memory, and the accuracy figures (ATE, RPE, return to start, tree recall /
precision / DBH RMSE) so that speed is never bought with accuracy unseen.

Scenarios (BUILD/bench-sim/<name>[-seed<N>], generated once, reused after):
  handheld  ini/sim-handheld.ini (421 s, 4214 scans)
  robot     ini/sim-robot.ini    (952 s, 9518 scans)
  long      ini/sim-robot.ini with [motion] loops = LONG_LOOPS (default 11:
            about 58 min, 35,000 scans): the memory-growth run; on demand
            only (`--scenarios long`), never in `make test`.
With --live the tree layer detects the stems during the run, as for live
input ([trees] layer_detect_during_run = true; run folders <name>-live):
the tree layer's updates then include those detections.
Environment: MAX_SCANS=N maps only the first N scans of each scenario (the
trees are then scored within 15 m of the mapped path only);
MEMORY_PERIOD_S=S sets [pipeline] memory_report_period_s (the RSS curve,
default 300 s of data); LONG_LOOPS=N laps of the long scenario.

One run is one draw: a neutral change (another world, the order in which
points enter a map) moves ATE by +-0.01 m and the robot's DBH RMSE by
+-0.5 cm (doc/performance.md). With several --seeds (worlds generated with
each seed) the bench ends with each figure's band over them, min / median /
max, and how many runs meet each target.

Usage: scripts/bench_pipeline.py [--build DIR] [--scenarios handheld robot]
           [--seeds N [N ...]] [--live] [--json FILE] [--out DIR]
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time

SIM_INI = {"handheld": "ini/sim-handheld.ini", "robot": "ini/sim-robot.ini",
           "long": "ini/sim-robot.ini"}
MAP_INI = {"handheld": "ini/vlp16-handheld.ini",
           "robot": "ini/vlp16-robot.ini", "long": "ini/vlp16-robot.ini"}


def die(msg):
    print("bench-pipeline: " + msg, file=sys.stderr)
    sys.exit(1)


def run(cmd, log, env=None):
    """Runs cmd with stdout+stderr into log; dies naming the log on
    failure."""
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, env=env)
    if r.returncode != 0:
        die(f"{' '.join(cmd)} failed (exit {r.returncode}), see {log}")


def set_ini_key(text, section, key, value):
    """Sets `key = value` in [section] of an INI text (added if missing)."""
    out, in_sec, done = [], False, False
    for line in text.splitlines():
        m = re.match(r"\s*\[(\w+)\]", line)
        if m:
            if in_sec and not done:
                out.append(f"{key} = {value}")
                done = True
            in_sec = m.group(1) == section
        elif in_sec and re.match(rf"\s*{key}\s*=", line):
            line, done = f"{key} = {value}", True
        out.append(line)
    if not done:
        if not in_sec:
            out.append(f"[{section}]")
        out.append(f"{key} = {value}")
    return "\n".join(out) + "\n"


def scenario_dir(build, name, seed, long_loops):
    """Generates the forest-sim scenario unless its folder already holds a
    complete run of the same configuration (cache by name, seed, laps)."""
    tag = name if name != "long" else f"long{long_loops}"
    d = os.path.join(build, "bench-sim", tag + ("" if seed == 1 else f"-seed{seed}"))
    if os.path.isfile(os.path.join(d, "scenario.ini")) and os.path.isfile(
            os.path.join(d, "run.rawlog")):
        return d
    os.makedirs(os.path.dirname(d), exist_ok=True)
    ini = SIM_INI[name]
    if name == "long":
        text = set_ini_key(open(ini).read(), "motion", "loops", long_loops)
        ini = d + ".ini"
        with open(ini, "w") as f:
            f.write(text)
    print(f"generating forest-sim {name} (seed {seed}) into {d}", flush=True)
    run([os.path.join(build, "bin", "forest-sim"), "--config", ini, "--out", d,
         "--seed", str(seed), "--threads", "2", "--progress", "log"],
        d + ".log")
    return d


def time_v(path):
    """Peak RSS [MB] and CPU seconds from a /usr/bin/time -v report."""
    text = open(path).read()

    def num(label):
        m = re.search(re.escape(label) + r":\s*([0-9.]+)", text)
        return float(m.group(1)) if m else 0.0
    return {"peak_rss_mb": num("Maximum resident set size (kbytes)") / 1024,
            "cpu_s": num("User time (seconds)") + num("System time (seconds)")}


def bench(build, name, seed, out_root, max_scans, long_loops, mem_period,
          live=False):
    sim = scenario_dir(build, name, seed, long_loops)
    out = os.path.join(out_root, name + ("" if seed == 1 else f"-seed{seed}")
                       + ("-live" if live else ""))
    os.makedirs(out, exist_ok=True)
    cfg = open(MAP_INI[name]).read()
    if live:
        cfg = set_ini_key(cfg, "trees", "layer_detect_during_run", "true")
    if max_scans:
        cfg = set_ini_key(cfg, "pipeline", "max_scans", max_scans)
    if mem_period:
        cfg = set_ini_key(cfg, "pipeline", "memory_report_period_s", mem_period)
    ini = os.path.join(out, "config.ini")
    with open(ini, "w") as f:
        f.write(cfg)
    bin_dir = os.path.join(build, "bin")
    t0 = time.time()
    run(["/usr/bin/time", "-v", "-o", os.path.join(out, "time.txt"),
         os.path.join(bin_dir, "forest-slam"), "map", "--config", ini,
         "--rawlog", os.path.join(sim, "run.rawlog"), "--out", out,
         "--progress", "log"], os.path.join(out, "map.log"))
    wall = time.time() - t0
    tv = time_v(os.path.join(out, "time.txt"))
    summ = json.load(open(os.path.join(out, "run_summary.json")))
    run([os.path.join(bin_dir, "forest-eval"), "traj", "--gt",
         os.path.join(sim, "gt_trajectory.tum"), "--est",
         os.path.join(out, "trajectory.tum"), "--json",
         os.path.join(out, "traj.json")], os.path.join(out, "traj.txt"))
    traj = json.load(open(os.path.join(out, "traj.json")))
    trees = None
    if os.path.isfile(os.path.join(out, "trees.csv")):
        run([os.path.join(bin_dir, "forest-eval"), "trees", "--gt",
             os.path.join(sim, "gt_trees.csv"), "--est",
             os.path.join(out, "trees.csv"), "--max-range-m", "15", "--traj",
             # A shortened run is scored on the ground it covered.
             os.path.join(out, "trajectory.tum") if max_scans else
             os.path.join(sim, "gt_trajectory.tum"), "--json",
             os.path.join(out, "trees.json")], os.path.join(out, "trees.txt"))
        tj = json.load(open(os.path.join(out, "trees.json")))
        trees = {"recall": tj["detection"]["recall"],
                 "precision": tj["detection"]["precision"],
                 "dbh_rmse_m": tj["dbh"]["rmse_m"],
                 "dbh_bias_m": tj["dbh"]["bias_m"],
                 "position_rmse_m": tj["position_err_m"]["rmse"],
                 # What the RMSE is made of: the map's scale (a 2D
                 # similarity fit) and the stems' own scatter left after it.
                 "position_map_scale":
                     tj["position_err_m"].get("structure", {}).get("scale"),
                 "position_rmse_after_similarity_m":
                     tj["position_err_m"].get("structure", {}).get(
                         "rmse_after_similarity_m"),
                 "trees": summ.get("trees", 0)}
    scans = summ["scans_mapped"]
    data_s = summ["data_seconds"]
    tl = summ.get("tree_layer", {})
    # Issue 7's speed target: the tree layer's updates (store, spilling,
    # corrections, detections during the run) against the process CPU.
    tree_layer = {
        "update_share_of_cpu": tl.get("update_share_of_cpu"),
        "update_cpu_s": tl.get("update_cpu_ms", 0) / 1e3,
        "store_cpu_s": tl.get("store_cpu_ms", 0) / 1e3,
        "correct_cpu_s": tl.get("correct_cpu_ms", 0) / 1e3,
        "spill_cpu_s": tl.get("spill_cpu_ms", 0) / 1e3,
        "end_of_run_detection_s": tl.get("finish_ms", 0) / 1e3,
        "detections": tl.get("detections", 0),
        "detections_in_run": tl.get("detections_in_run", 0),
        "redetections_in_run": tl.get("redetections_in_run", 0),
    } if tl else None
    mem = summ.get("memory", {})
    rts = traj.get("return_to_start", {}).get("estimate_vs_gt", {})
    return {
        "scenario": name, "seed": seed, "live": live, "sim_dir": sim,
        "out_dir": out,
        "scans": scans, "data_s": data_s,
        "path_m": traj.get("vertical_drift", {}).get("distance_m"),
        "wall_s": wall, "cpu_s": tv["cpu_s"],
        "mapping_wall_s": summ["wall_seconds"],
        "output_write_s": summ.get("output_write_seconds"),
        "scans_per_s": summ["scans_per_second"],
        "scans_per_cpu_s": scans / tv["cpu_s"] if tv["cpu_s"] else 0,
        # A VLP-16 at 10 Hz: data seconds per wall second of mapping.
        "real_time_factor": summ["real_time_factor"],
        "real_time_factor_cpu": data_s / tv["cpu_s"] if tv["cpu_s"] else 0,
        "stage_ms": summ["stage_ms"],
        # Each thread's CPU per scan while the scans were processed.
        "scan_thread_cpu_ms_per_scan": {
            k: 1e3 * v / scans if scans else 0 for k, v in
            summ.get("scan_thread_cpu_seconds", {}).items()},
        "peak_rss_mb": tv["peak_rss_mb"],
        "peak_rss_mapping_mb": max([c["rss_mb"] for c in mem.get("curve", [])]
                                   + [mem.get("end_of_mapping", {}).get("rss_mb", 0)]),
        "memory_end_of_mapping": mem.get("end_of_mapping"),
        "memory_curve": [{"data_s": c["data_s"], "scans": c["scans"],
                          "rss_mb": c["rss_mb"]} for c in mem.get("curve", [])],
        "map_memory_mb": mem.get("end_of_mapping", {}).get("forest_map_mb"),
        "ate_m": traj["ate"]["aligned_se3"]["trans_m"]["rmse"],
        "rpe_trans_pct": traj["rpe"]["trans_err_pct"],
        "rpe_rot_deg_per_m": traj["rpe"]["rot_err_deg_per_m"],
        "return_to_start_m": rts.get("total_trans_m"),
        "return_to_start_deg": rts.get("angle_deg"),
        "trees": trees,
        "tree_layer": tree_layer,
    }


def fmt(v, spec):
    """Number or n/a (RPE needs segments longer than the path, etc.)."""
    return "n/a" if v is None else format(v, spec)


def show(r):
    print(f"== {r['scenario']} (seed {r['seed']}"
          f"{', trees during the run' if r.get('live') else ''}): {r['scans']} scans, "
          f"{r['data_s']:.0f} s of data, {r['path_m'] or 0:.0f} m")
    print(f"  throughput  {r['scans_per_s']:.1f} scans/s over the mapping wall "
          f"({r['mapping_wall_s']:.1f} s), {r['scans'] / r['wall_s']:.1f} scans/s "
          f"end to end ({r['wall_s']:.1f} s with the outputs), "
          f"{r['real_time_factor']:.2f}x real time; CPU {r['cpu_s']:.0f} s: "
          f"{r['scans_per_cpu_s']:.1f} scans per CPU s, "
          f"{r['real_time_factor_cpu']:.2f}x real time per core "
          f"(targets >= 100 scans/s, 10x); outputs written in "
          f"{r['output_write_s'] or 0:.1f} s")
    print("  stage ms    " + ", ".join(
        f"{k} {v['median']:.1f}/{v['p95']:.1f}/{v['max']:.0f}"
        for k, v in r["stage_ms"].items()) + "  (median/p95/max)")
    th = r["scan_thread_cpu_ms_per_scan"]
    if th:
        print(f"  CPU/scan    {sum(th.values()):.1f} ms during the scans: " +
              ", ".join(f"{k} {v:.1f}" for k, v in
                        sorted(th.items(), key=lambda kv: -kv[1])))
    m = r["memory_end_of_mapping"] or {}
    print(f"  memory      peak RSS {r['peak_rss_mb']:.0f} MB (mapping "
          f"{r['peak_rss_mapping_mb']:.0f} MB; target <= 2048); at the end "
          f"of mapping: dense map {m.get('dense_map_mb', 0):.0f}, keyframes "
          f"{m.get('keyframes_mb', 0):.0f}, submaps "
          f"{m.get('forest_map_mb', 0):.0f}, tree layer "
          f"{m.get('tree_layer_mb', 0):.0f}, local map "
          f"{m.get('local_map_mb', 0):.0f} MB; spilled "
          f"{m.get('spilled_mb', 0):.0f} MB")
    if r["memory_curve"]:
        print("  RSS curve   " + "  ".join(
            f"{c['data_s']:.0f}s:{c['rss_mb']:.0f}MB"
            for c in r["memory_curve"]))
    print(f"  trajectory  ATE {fmt(r['ate_m'], '.3f')} m, RPE "
          f"{fmt(r['rpe_trans_pct'], '.3f')} % / "
          f"{fmt(r['rpe_rot_deg_per_m'], '.4f')} deg/m, return to start "
          f"{fmt(r['return_to_start_m'], '.3f')} m "
          f"{fmt(r['return_to_start_deg'], '.2f')} deg")
    t = r["trees"]
    if t:
        cm = {k: None if t[k] is None else 100 * t[k]
              for k in ("dbh_rmse_m", "dbh_bias_m", "position_rmse_m")}
        print(f"  trees       recall {fmt(t['recall'], '.3f')}, precision "
              f"{fmt(t['precision'], '.3f')}, DBH RMSE "
              f"{fmt(cm['dbh_rmse_m'], '.2f')} cm (bias "
              f"{fmt(cm['dbh_bias_m'], '+.2f')} cm), position RMSE "
              f"{fmt(cm['position_rmse_m'], '.1f')} cm, {t['trees']} stems")
        sc = t.get("position_map_scale")
        left = t.get("position_rmse_after_similarity_m")
        if sc is not None and left is not None:
            print(f"              position error's structure: map scale "
                  f"{(sc - 1) * 100:+.3f} %; {100 * left:.1f} cm left after "
                  "a 2D similarity (the stems' own scatter)")
    tl = r.get("tree_layer")
    if tl and tl["update_share_of_cpu"] is not None:
        print(f"  tree layer  updates {tl['update_cpu_s']:.1f} s of CPU, "
              f"{tl['update_share_of_cpu']:.3f} of the process (target <= "
              f"0.10): store {tl['store_cpu_s']:.1f}, corrections "
              f"{tl['correct_cpu_s']:.1f}, spilling {tl['spill_cpu_s']:.1f} s, "
              f"{tl['detections_in_run']} detections during the run "
              f"({tl['redetections_in_run']} again); end-of-run detection "
              f"{tl['end_of_run_detection_s']:.1f} s, "
              f"{tl['detections'] - tl['detections_in_run']} columns")
    sys.stdout.flush()


def tree_figure(key):
    """Getter of a tree figure of a run (None without a tree list)."""
    return lambda r: (r["trees"] or {}).get(key)


def scale_error(r):
    """The map's scale minus 1 (None without a tree list or a fit)."""
    s = tree_figure("position_map_scale")(r)
    return None if s is None else s - 1


# The band's figures: label, getter, format, scale, target test.
BAND = [
    ("scans/s", lambda r: r["scans_per_s"], ".1f", 1, lambda v: v >= 100),
    ("ATE m", lambda r: r["ate_m"], ".3f", 1, None),
    ("RPE %", lambda r: r["rpe_trans_pct"], ".3f", 1, None),
    ("peak RSS MB", lambda r: r["peak_rss_mb"], ".0f", 1, lambda v: v <= 2048),
    ("tree recall %", tree_figure("recall"), ".1f", 100, lambda v: v >= 98),
    ("tree precision %", tree_figure("precision"), ".1f", 100,
     lambda v: v >= 98),
    ("DBH RMSE cm", tree_figure("dbh_rmse_m"), ".2f", 100, lambda v: v <= 1.0),
    ("DBH bias cm", tree_figure("dbh_bias_m"), "+.2f", 100,
     lambda v: abs(v) <= 0.3),
    ("position RMSE cm", tree_figure("position_rmse_m"), ".1f", 100,
     lambda v: v <= 5.0),
    ("tree updates share", lambda r: (r.get("tree_layer") or {}).get(
        "update_share_of_cpu"), ".3f", 1, lambda v: v <= 0.10),
    ("map scale %", scale_error, "+.3f", 100, None),
    ("after similarity cm", tree_figure("position_rmse_after_similarity_m"),
     ".1f", 100, None),
]


def band(results):
    """Each figure's min / median / max over the runs of one scenario, and
    how many runs meet the issues' target (issues 7 and 11)."""
    rows = {}
    for label, get, spec, scale, target in BAND:
        vals = [get(r) for r in results]
        vals = [scale * v for v in vals if v is not None]
        if not vals:
            continue
        row = {"min": min(vals), "median": statistics.median(vals),
               "max": max(vals), "runs": len(vals)}
        if target:
            row["meeting_target"] = sum(1 for v in vals if target(v))
        rows[label] = row
    return rows


def show_band(name, seeds, rows):
    print(f"== {name}: band over seeds {' '.join(map(str, seeds))} "
          "(min / median / max; runs meeting the target)")
    for label, _, spec, _, target in BAND:
        if label not in rows:
            continue
        b = rows[label]
        meet = (f"   {b['meeting_target']}/{b['runs']} meet the target"
                if target else "")
        print(f"  {label:<19} {format(b['min'], spec):>8} "
              f"{format(b['median'], spec):>8} {format(b['max'], spec):>8}"
              + meet)
    sys.stdout.flush()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default="build")
    ap.add_argument("--scenarios", nargs="+", default=["handheld", "robot"],
                    choices=sorted(SIM_INI))
    ap.add_argument("--seeds", "--seed", type=int, nargs="+", default=[1],
                    help="forest-sim seeds (worlds); several: a band")
    ap.add_argument("--live", action="store_true",
                    help="trees detected during the run, as for live input")
    ap.add_argument("--json", help="write all figures to this file")
    ap.add_argument("--out", help="run folders (default BUILD/bench-pipeline)")
    a = ap.parse_args()
    for b in ("forest-sim", "forest-slam", "forest-eval"):
        if not os.access(os.path.join(a.build, "bin", b), os.X_OK):
            die(f"{a.build}/bin/{b} not found (build first)")
    max_scans = int(os.environ.get("MAX_SCANS", "0") or 0)
    long_loops = int(os.environ.get("LONG_LOOPS", "11") or 11)
    mem_period = os.environ.get("MEMORY_PERIOD_S", "")
    out_root = a.out or os.path.join(a.build, "bench-pipeline")
    print(f"whole-pipeline benchmark on {os.cpu_count()} cores, load "
          f"{os.getloadavg()[0]:.1f}" + (f", MAX_SCANS={max_scans}" if max_scans else ""))
    if len(set(a.seeds)) != len(a.seeds):
        die("--seeds: each seed once")
    results, bands = [], {}
    for s in a.scenarios:
        for seed in a.seeds:
            r = bench(a.build, s, seed, out_root, max_scans, long_loops,
                      mem_period, a.live)
            show(r)
            results.append(r)
    if len(a.seeds) > 1:
        for s in a.scenarios:
            bands[s] = band([r for r in results if r["scenario"] == s])
            show_band(s, a.seeds, bands[s])
    if a.json:
        tmp = a.json + ".tmp"
        with open(tmp, "w") as f:
            json.dump({"machine": {"cores": os.cpu_count(),
                                   "load_at_start": os.getloadavg()[0]},
                       "max_scans": max_scans, "seeds": a.seeds,
                       "live": a.live,
                       "results": results, "bands": bands}, f,
                      indent=1)
        os.replace(tmp, a.json)
        print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
