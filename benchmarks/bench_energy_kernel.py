"""Time per particle-view of the compiled silhouette energy kernel (``mocap/energy/fused.py``) on
the energy calls of a tracker run, and a checksum of its energies (not a timed test).

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_energy_kernel.py [--tracker apf_prior]
        [--frames 3] [--calls 8] [--repeat 10] [--label NAME] [--out FILE]

The tracker runs as in ``bench_speed.py`` (the MPI08-like rig, 8 views at 1004 x 1004, 256 px
internal silhouettes, the synthetic walk, frame 0 from ground truth + noise) for ``--frames``
frames on one thread; every ``_fused_energy`` call's arguments are kept (``--calls`` of them,
spread over the run), then those calls are run again ``--repeat`` times. Printed: CPU
microseconds per particle-view (``time.process_time``: on a shared machine the figure to
compare; minimum and median of the repeats), wall microseconds, and the SHA-1 of every energy
of the kept calls: two checkouts with the same checksum computed the same energies bit for
bit. The script times the ``mocap`` it imports, so an old checkout is timed with
``PYTHONPATH`` set to it::

    for r in 1 2 3; do for d in ../old $PWD; do PYTHONPATH=$d .venv/bin/python \\
        benchmarks/bench_energy_kernel.py --label $d --out /tmp/kernel.jsonl; done; done
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_speed import TRACKERS, without_images
from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.energy import fused
from mocap.threads import thread_budget
from mocap.trackers.run import frame_of, noisy_initial_pose
from mocap_cli.hydra_edge import build, compose


def record_calls(tracker_name: str, frames: int) -> list[tuple]:
    """The arguments of every kernel call of a ``frames``-frame run (arrays copied)."""
    calls = []
    kernel = fused._fused_energy

    def recording(*args):
        kernel(*args)
        calls.append(tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args))

    base = compose("track")
    body = build(base.body)
    rig = rig_from_config("mpi08")
    seq = make_synthetic(body, rig, motion="walk", frames=frames, fps=25, seed=0, images=False)
    cfg_name, overrides, _ = TRACKERS[tracker_name]
    cfg = compose("track", [f"tracker={cfg_name}", *overrides])
    tracker = build(cfg.tracker, body=body, rig=rig, rng=np.random.default_rng(0))
    tracker.initialize(noisy_initial_pose(body, seq.gt.chi[0], np.random.default_rng(0), 3.0, 0.02),
                       seq.gt.alpha)
    fused._fused_energy = recording
    try:
        with thread_budget(1):
            for f in range(1, frames):
                tracker.step(without_images(frame_of(seq, f)))
    finally:
        fused._fused_energy = kernel
    return calls


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tracker", default="apf_prior", choices=sorted(TRACKERS))
    p.add_argument("--frames", type=int, default=3, help="frames of the walk (frame 0 not run)")
    p.add_argument("--calls", type=int, default=8, help="kernel calls kept, spread over the run")
    p.add_argument("--repeat", type=int, default=10)
    p.add_argument("--label", default="", help="name of the code timed, for --out")
    p.add_argument("--out", type=Path, default=None, help="append a JSON line with the figures")
    args = p.parse_args()
    calls = record_calls(args.tracker, args.frames)
    if not calls:
        raise SystemExit(f"tracker {args.tracker} made no compiled energy call")
    calls = [calls[i] for i in np.linspace(0, len(calls) - 1, min(args.calls, len(calls))).astype(int)]
    energies = []
    with thread_budget(1):
        for a in calls:                  # energies (and the compile, or the cache's load)
            a = list(a)
            a[-2], a[-1] = np.empty_like(a[-2]), np.zeros_like(a[-1])    # out, bad
            fused._fused_energy(*a)
            energies.append(a[-2])
        cpu, wall = [], []
        for _ in range(args.repeat):
            t, c = time.perf_counter(), time.process_time()
            for a in calls:
                fused._fused_energy(*a)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
    views = sum(a[0].shape[0] * a[0].shape[1] for a in calls)
    digest = hashlib.sha1(np.concatenate(energies).tobytes()).hexdigest()[:16]
    row = {"label": args.label, "tracker": args.tracker, "calls": len(calls), "particle_views": views,
           "cpu_us_min": min(cpu) / views * 1e6, "cpu_us_median": float(np.median(cpu)) / views * 1e6,
           "wall_us_min": min(wall) / views * 1e6, "energies_sha1": digest,
           "load": os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")}
    print(f"{args.tracker}: {len(calls)} calls, {views} particle-views; CPU us per particle-view "
          f"min {row['cpu_us_min']:.1f} median {row['cpu_us_median']:.1f}; wall min "
          f"{row['wall_us_min']:.1f}; energies sha1 {digest}; load {row['load']:.1f}")
    if args.out:
        with args.out.open("a") as f:
            f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
