"""What a recording costs: recording overhead as a fraction of tracking time, and MB per frame,
for every tracker family, before (the sink at ``--before``) and after (this checkout's sink at
each ``recording.level``), measured in the same process with the runs alternating.

    .venv/bin/python benchmarks/bench_recording.py [--trackers local,apf,apf_prior,hybrid,marker_apf]
        [--frames 10] [--marker-frames 60] [--rounds 3] [--before aa44648] [--json FILE]

Each tracker runs through :func:`mocap.run_folder.run_tracking` (the real path: the frame
loop, the sink, the files) on small data: ``walk_small`` (4 views at 320 x 240, silhouettes,
ground truth + noise at frame 0) for the silhouette trackers, ``walk_markers_small`` with
``--marker-frames`` frames for ``marker_apf``; one thread (``threads=1``). Per round, in turn:
recording off, the old sink (``--before``: its rerun_sink.py and motion_log.py read from git,
with its defaults every=1, particles=true, images=true, scale=0.25), and this checkout's sink at
each level. Medians over the rounds. Columns:

    track s    tracking time (wall, the steps of frames 1..F-1) with recording off
    CPU s      the main thread's CPU time of the run without recording (tracking, scoring, files)
    overhead   what the recording costs in CPU time, over ``CPU s``: the sink's own CPU time in the
               main thread (start, every frame, finish) plus the CPU time of the process's other
               threads (Rerun's batcher, encoder and file writer), less the same with recording
               off. CPU time rather than wall time: on a shared machine the wall time of a run
               varies by more than the recording costs
    of which bg  the other threads' share of it
    start s    the sink's start (main thread CPU: the file, cameras, mesh topology, config), once
    ms/frame   the rest of the cost per frame (CPU ms; the finish, which sends the last batch,
               included): what a long run pays per frame
    wall       (run time with recording - run time without) / tracking time without: the same
               cost in wall time (noisy on a loaded machine; keeping particles in the tracker
               shows here only)
    MB/frame   recording.rrd size / frames

On a shared machine absolute times drift with the load (printed); the ratios of one run are
the figures to compare.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mocap.recording.factory import make_sink
from mocap.recording.settings import LEVELS
from mocap.run_folder import run_tracking
from mocap.run_folder import tracking as tracking_module
from mocap_cli.hydra_edge import build, compose, plain

REPO = Path(__file__).resolve().parents[1]
BEFORE = "aa44648"      # the last commit before issue 28's recording work
OLD_SETTINGS = {"enabled": True, "every": 1, "particles": True, "images": True, "scale": 0.25}

# name -> (tracker config, data config and overrides)
TRACKERS = {
    "local": ("local", ["data=walk_small", "tracker.sift.enabled=false"]),
    "apf": ("apf", ["data=walk_small"]),
    "apf_prior": ("apf_prior", ["data=walk_small"]),
    "hybrid": ("hybrid", ["data=walk_small"]),
    "marker_apf": ("marker_apf", ["data=walk_markers_small"]),
}


def legacy_sink_class(rev: str):
    """RerunSink of commit ``rev`` (its rerun_sink.py and motion_log.py, loaded from git)."""
    folder = Path(tempfile.mkdtemp(prefix="legacy_recording_"))
    for name in ("rerun_sink", "motion_log"):
        text = subprocess.run(["git", "show", f"{rev}:mocap/recording/{name}.py"], cwd=REPO, check=True,
                              capture_output=True, text=True).stdout
        text = text.replace("from mocap.recording.motion_log import",
                            "from legacy_recording_motion_log import")
        (folder / f"{name}.py").write_text(text)
    modules = {}
    for name in ("motion_log", "rerun_sink"):
        spec = importlib.util.spec_from_file_location(f"legacy_recording_{name}", folder / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
        modules[name] = module
    return modules["rerun_sink"].RerunSink


class Timed:
    """A sink wrapper adding up the CPU time (this thread's) spent in start(), frame() and
    finish()."""

    def __init__(self, sink):
        self.sink, self.seconds, self.fixed = sink, 0.0, 0.0
        self.path = getattr(sink, "path", None)

    def start(self, *a):
        t = time.thread_time()
        self.sink.start(*a)
        self.seconds += time.thread_time() - t
        self.fixed += time.thread_time() - t

    def frame(self, *a):
        t = time.thread_time()
        self.sink.frame(*a)
        self.seconds += time.thread_time() - t

    def finish(self, *a, **k):
        t = time.thread_time()
        self.sink.finish(*a, **k)
        self.seconds += time.thread_time() - t


def one_run(out: Path, config: dict, body, seq, tracker_node, variant: str, legacy) -> dict:
    timed = {}

    def sink_for(out_dir, settings):
        sink = legacy(Path(out_dir) / "recording.rrd", **{k: v for k, v in OLD_SETTINGS.items()
                                                          if k != "enabled"}) \
            if variant == "before" else make_sink(out_dir, settings)
        timed["sink"] = Timed(sink)
        return timed["sink"]

    cfg = dict(config)
    cfg["recording"] = ({"enabled": False} if variant == "off" else dict(OLD_SETTINGS) if variant == "before"
                        else {"enabled": True, "level": variant})
    original = tracking_module.make_sink
    tracking_module.make_sink = sink_for
    try:
        t, c, main = time.perf_counter(), time.process_time(), time.thread_time()
        m = run_tracking(out, cfg, make_body=lambda: body, make_sequence=lambda b: seq,
                         make_tracker=lambda **o: build(tracker_node, **o))
        total, main = time.perf_counter() - t, time.thread_time() - main
        background = time.process_time() - c - main       # other threads, Rerun's writers among them
    finally:
        tracking_module.make_sink = original
    rrd = out / "recording.rrd"
    return {"total": total, "main": main, "background": background, "track": m["tracking_seconds"],
            "sink": timed["sink"].seconds, "fixed": timed["sink"].fixed, "frames": m["frames"],
            "bytes": rrd.stat().st_size if rrd.is_file() else 0}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trackers", default=",".join(TRACKERS))
    p.add_argument("--frames", type=int, default=10)
    p.add_argument("--marker-frames", type=int, default=60)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--before", default=BEFORE, help="the commit whose sink is 'before'")
    p.add_argument("--levels", default=",".join(LEVELS))
    p.add_argument("--json", type=Path, help="append the results as one JSON line")
    args = p.parse_args(argv)
    legacy = legacy_sink_class(args.before)
    variants = ["off", "before", *args.levels.split(",")]
    load0 = os.getloadavg()
    print(f"rerun recording cost, {args.rounds} rounds, before = {args.before}, load {load0[0]:.1f} "
          f"(1 min) on {os.cpu_count()} cores, OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE')}")
    rows = []
    for name in args.trackers.split(","):
        tracker, overrides = TRACKERS[name]
        frames = args.marker_frames if name == "marker_apf" else args.frames
        data_frames = [f"data.frames={frames}"] if frames > 20 else []
        cfg = compose("track", [f"tracker={tracker}", *overrides, *data_frames, f"frames={frames}",
                                "threads=1"])
        body = build(cfg.body)
        seq = build(cfg.data, body=body)
        config = plain(cfg)
        runs = {v: [] for v in variants}
        with tempfile.TemporaryDirectory(prefix="bench_recording_") as tmp:
            one_run(Path(tmp) / "warm", config, body, seq, cfg.tracker, "standard", legacy)   # JIT, caches
            for r in range(args.rounds):
                order = variants if r % 2 == 0 else variants[::-1]
                for v in order:
                    runs[v].append(one_run(Path(tmp) / f"{v}_{r}", config, body, seq, cfg.tracker, v, legacy))
        keys = ("total", "main", "background", "track", "sink", "fixed", "bytes")
        med = {v: {k: statistics.median(x[k] for x in rs) for k in keys} for v, rs in runs.items()}
        track_off, off = med["off"]["track"], med["off"]
        cpu_off = off["main"] - off["sink"]          # the run without recording, main thread
        for v in variants:
            cost = med[v]["sink"] + med[v]["background"] - off["sink"] - off["background"]
            rows.append({
                "tracker": name, "variant": v, "frames": frames, "track_off_s": track_off,
                "track_s": med[v]["track"],
                "cpu_s": cpu_off, "cost_cpu_s": cost,
                "overhead": cost / cpu_off,
                "background": (med[v]["background"] - off["background"]) / cpu_off,
                "fixed_s": med[v]["fixed"] - off["fixed"],
                "per_frame_ms": 1e3 * (cost - med[v]["fixed"] + off["fixed"]) / frames,
                "wall_overhead": (med[v]["total"] - off["total"]) / track_off,
                "mb_per_frame": med[v]["bytes"] / frames / 1e6,
            })
        print_table([r for r in rows if r["tracker"] == name], header=name == args.trackers.split(",")[0])
    load1 = os.getloadavg()
    print(f"load {load1[0]:.1f} at the end")
    if args.json:
        with args.json.open("a") as fh:
            fh.write(json.dumps({"before": args.before, "load": [load0[0], load1[0]], "rounds": args.rounds,
                                 "rows": rows}) + "\n")
    return 0


def print_table(rows, header=True) -> None:
    if header:
        print(f"{'tracker':<11} {'frames':>6} {'track s':>8} {'CPU s':>6}  {'recording':<9} {'overhead':>9} "
              f"{'of which bg':>11} {'start s':>8} {'ms/frame':>9} {'wall':>7} {'MB/frame':>9}")
    for r in rows:
        if r["variant"] == "off":
            continue
        print(f"{r['tracker']:<11} {r['frames']:>6} {r['track_off_s']:>8.2f} {r['cpu_s']:>6.2f}  "
              f"{r['variant']:<9} {100 * r['overhead']:>8.1f}% {100 * r['background']:>10.1f}% "
              f"{r['fixed_s']:>8.3f} {r['per_frame_ms']:>9.2f} {100 * r['wall_overhead']:>6.1f}% "
              f"{r['mb_per_frame']:>9.3f}")
    sys.stdout.flush()


if __name__ == "__main__":
    raise SystemExit(main())
