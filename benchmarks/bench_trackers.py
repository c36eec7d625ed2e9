"""Benchmark: time per frame of each tracker, one run at a time, on 8 views (MPI08-like).

    .venv/bin/python benchmarks/bench_trackers.py [--frames 6] [--trackers local,apf_prior,apf,hybrid]
        [--images]

Generates a synthetic walking sequence (8 views, 1004 x 1004; --images adds textured RGB
so that the local tracker also uses SIFT), tracks it with each tracker from ground truth +
noise, and prints the mean and median step time (frame 0 is the initialisation and not
timed) and the energy evaluations per frame. Targets: local <= 0.5 s, apf_prior (25x10)
<= 1 s, apf (100x15) <= 6 s per frame.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.trackers.run import frame_of, noisy_initial_pose
from mocap_cli.hydra_edge import build, compose

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=6)
    p.add_argument("--trackers", default="local,apf_prior,apf_25x10,apf,hybrid")
    p.add_argument("--images", action="store_true")
    p.add_argument("--cameras", default="mpi08")
    args = p.parse_args()
    base = compose("track")
    body = build(base.body)
    rig = rig_from_config(args.cameras)
    seq = make_synthetic(body, rig, motion="walk", frames=args.frames, fps=25, seed=0, images=args.images)
    print(f"{len(rig)} views {rig.sizes[0][0]}x{rig.sizes[0][1]}, {args.frames - 1} tracked frames, "
          f"images: {args.images}")
    print(f"{'tracker':12s} {'mean s':>8s} {'median s':>9s} {'evals':>7s}")
    for name in args.trackers.split(","):
        cfg = compose("track", [f"tracker={name}"])
        tracker = build(cfg.tracker, body=body, rig=rig, rng=np.random.default_rng(0))
        tracker.initialize(noisy_initial_pose(body, seq.gt.chi[0], np.random.default_rng(0), 3.0, 0.02),
                           seq.gt.alpha)
        times, evals = [], []
        for f in range(1, args.frames):
            t = time.perf_counter()
            est = tracker.step(frame_of(seq, f))
            times.append(time.perf_counter() - t)
            evals.append(est.diagnostics.get("energy_evaluations", 0))
        print(f"{name:12s} {np.mean(times):8.3f} {np.median(times):9.3f} {np.mean(evals):7.0f}")


if __name__ == "__main__":
    main()
