"""Speed guard: time per frame of every silhouette tracker at fixed settings, with ratios
against a stored baseline (not a timed test: run it by hand on a quiet machine).

    .venv/bin/python benchmarks/bench_speed.py [--frames 4] [--threads 1]
        [--trackers local,local_sift,apf_prior,apf,hybrid] [--backend auto|numba|numpy]
        [--legacy-local] [--compare] [--baseline benchmarks/baseline_speed.json]
        [--save-baseline] [--frame-times FILE] [--label NAME]

Fixed settings: the MPI08-like rig (8 views, 1004 x 1004), 256 px internal silhouettes, a
synthetic walk (seed 0, textured images so that ``local_sift`` has SIFT features; the other
trackers get the frames without images), frame 0 from ground truth + noise (3 deg, 2 cm),
frames 1..F-1 timed (``step`` only). ``--threads`` is the thread budget of the numeric
kernels (BLAS / OpenMP via threadpoolctl, numba, OpenCV; 0 = the libraries' defaults, i.e.
no limit). ``--compare`` runs every tracker twice in the same process, first on the old
path (numpy silhouette energy, local tracker without the stopping rule and with per-view
contour loops) and then on the new one, and prints the same-run ratio: on a shared machine
that ratio is the figure to trust, absolute times drift with the load.

The baseline JSON stores seconds per frame per tracker (and the machine it came from);
every later run prints ``now / baseline`` next to its own times.

Comparing two commits on a noisy machine: run this script from two checkouts in turn, several
rounds, each with ``--frame-times FILE`` (one JSON line per run: the commit of the ``mocap``
timed, the load before and after, every frame's seconds and CPU seconds of this process per
tracker), then compare medians and the fastest frames per commit. This script can time an
older checkout's code (one without the option) through PYTHONPATH; CPU seconds are the
steadier figure where other work shares the cores::

    git worktree add ../old <commit> && ln -s $PWD/.venv ../old/.venv
    for r in 1 2 3; do for d in ../old .; do (cd $d && PYTHONPATH=$PWD .venv/bin/python \
        $OLDPWD/benchmarks/bench_speed.py --frames 7 --trackers local,hybrid \
        --frame-times /tmp/ab.jsonl); done; done
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.energy import silhouette as silhouette_module
from mocap.local import solver as solver_module
from mocap.threads import thread_budget
from mocap.trackers.base import Frame
from mocap.trackers.run import frame_of, noisy_initial_pose
from mocap_cli.hydra_edge import build, compose

REPO = Path(__file__).resolve().parents[1]
BASELINE = REPO / "benchmarks" / "baseline_speed.json"

# name -> (tracker config, Hydra overrides, uses images)
TRACKERS = {
    "local": ("local", ["++tracker.sift.enabled=false"], False),
    "local_sift": ("local", [], True),
    "apf_prior": ("apf_prior", [], False),
    "apf_25x10": ("apf_25x10", [], False),
    "apf": ("apf", [], False),
    "hybrid": ("hybrid", ["++tracker.local.sift.enabled=false"], False),
    # the full 10k-triangle mesh in the silhouette energy (the default before the energy mesh)
    "apf_prior_full": ("apf_prior", ["++tracker.energy_mesh=null"], False),
    "apf_full": ("apf", ["++tracker.energy_mesh=null"], False),
}


def without_images(frame: Frame) -> Frame:
    return Frame(index=frame.index, masks=frame.masks, images=None, detections=frame.detections)


def time_tracker(name: str, body, rig, seq, frames: int) -> tuple[float, float, float, list, list]:
    """Mean and median seconds per tracked frame, mean energy evaluations, every frame's
    seconds and every frame's CPU seconds of this process (steadier on a shared machine)."""
    cfg_name, overrides, images = TRACKERS[name]
    cfg = compose("track", [f"tracker={cfg_name}", *overrides])
    tracker = build(cfg.tracker, body=body, rig=rig, rng=np.random.default_rng(0))
    tracker.initialize(noisy_initial_pose(body, seq.gt.chi[0], np.random.default_rng(0), 3.0, 0.02),
                       seq.gt.alpha)
    times, cpu, evals = [], [], []
    for f in range(1, frames):
        frame = frame_of(seq, f)
        if not images:
            frame = without_images(frame)
        t, c = time.perf_counter(), time.process_time()
        est = tracker.step(frame)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        evals.append(est.diagnostics.get("energy_evaluations", 0))
    return float(np.mean(times)), float(np.median(times)), float(np.mean(evals)), times, cpu


def _commit() -> str:
    """The commit of the checkout whose ``mocap`` is timed (for --frame-times lines; this
    script can time another checkout's code with PYTHONPATH), or '' outside git."""
    import subprocess

    import mocap
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"],
                              cwd=Path(mocap.__file__).resolve().parents[1], text=True,
                              capture_output=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def set_path(old: bool, backend: str) -> None:
    """Select the old (before issue 15) or the new code path, in this process."""
    silhouette_module.DEFAULT_BACKEND = "numpy" if old else backend
    solver_module.LEGACY = old


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--frames", type=int, default=4, help="frames of the walk (frame 0 not timed)")
    p.add_argument("--trackers", default="local,local_sift,apf_prior,apf,hybrid")
    p.add_argument("--threads", type=int, default=1, help="thread budget (0: library defaults)")
    p.add_argument("--backend", default="auto", choices=("auto", "numba", "numpy"),
                   help="silhouette energy backend of the new path")
    p.add_argument("--legacy", action="store_true", help="time the old path only")
    p.add_argument("--compare", action="store_true", help="old path, then new path, same process")
    p.add_argument("--baseline", type=Path, default=BASELINE)
    p.add_argument("--save-baseline", action="store_true", help="store this run's times as baseline")
    p.add_argument("--frame-times", type=Path, default=None,
                   help="append every frame's seconds to this JSON-lines file (one line per run)")
    p.add_argument("--label", default=None,
                   help="a name for this run in the --frame-times line (e.g. the checkout timed)")
    args = p.parse_args()

    base = compose("track")
    body = build(base.body)
    rig = rig_from_config("mpi08")
    names = args.trackers.split(",")
    images = any(TRACKERS[n][2] for n in names)
    seq = make_synthetic(body, rig, motion="walk", frames=args.frames, fps=25, seed=0, images=images)
    baseline = json.loads(args.baseline.read_text()) if args.baseline.is_file() else None
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{len(rig)} views {rig.sizes[0][0]}x{rig.sizes[0][1]}, 256 px internal, "
          f"{args.frames - 1} tracked frames; threads {args.threads or 'default'}; "
          f"{os.cpu_count()} cores, load {load:.1f}")
    paths = ["old", "new"] if args.compare else (["old"] if args.legacy else ["new"])
    header = (f"{'tracker':11s} {'path':4s} {'mean s':>8s} {'median s':>9s} {'cpu s':>6s} "
              f"{'evals':>6s}")
    print(header + (f" {'old/new':>8s}" if args.compare else "")
          + (f" {'/baseline':>9s}" if baseline else ""))
    results: dict[str, float] = {}
    frame_times: dict[str, list] = {}
    cpu_times: dict[str, list] = {}
    for name in names:
        row = {}
        for path in paths:
            set_path(path == "old", args.backend)
            with thread_budget(args.threads or None):
                mean, median, evals, times, cpu = time_tracker(name, body, rig, seq, args.frames)
            frame_times.setdefault(f"{name} {path}", []).append(times)
            cpu_times.setdefault(f"{name} {path}", []).append(cpu)
            row[path] = median
            line = f"{name:11s} {path:4s} {mean:8.3f} {median:9.3f} {np.median(cpu):6.3f} {evals:6.0f}"
            if args.compare and path == "new":
                line += f" {row['old'] / median:8.2f}"
            elif args.compare:
                line += f" {'':8s}"
            if baseline and name in baseline["seconds_per_frame"]:
                line += f" {median / baseline['seconds_per_frame'][name]:9.2f}"
            print(line, flush=True)
        results[name] = row[paths[-1]]
    set_path(False, "auto")
    if args.frame_times:
        with args.frame_times.open("a") as f:
            f.write(json.dumps({"commit": _commit(), "load": load, "times": frame_times,
                                "cpu": cpu_times, "load_after": os.getloadavg()[0],
                                "label": args.label}) + "\n")
    if args.save_baseline:
        args.baseline.write_text(json.dumps({
            "seconds_per_frame": results, "path": paths[-1], "threads": args.threads,
            "frames": args.frames, "machine": f"{platform.processor() or platform.machine()}, "
            f"{os.cpu_count()} cores, load {load:.1f}",
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, indent=2) + "\n")
        print(f"baseline written to {args.baseline}")


if __name__ == "__main__":
    main()
