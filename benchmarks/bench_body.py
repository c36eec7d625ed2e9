"""Benchmark: posing P particles of the body model (shape fixed, pose varying).

    .venv/bin/python benchmarks/bench_body.py [--particles 250] [--repeats 50]

Prints the median and best time per call of ``ShapedBody.pose`` (twist chain + LBS) and of
its parts, for float32 and float64. The issue's target: P = 250 in <= 40 ms on 2 cores.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from mocap import presets
from mocap.body import load_body_model
from mocap.body.kinematics import chain_transforms
from mocap.body.lbs import lbs_apply

REPO = Path(__file__).resolve().parents[1]


def timeit(fn, repeats: int) -> tuple[float, float]:
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * float(np.median(times)), 1e3 * float(np.min(times))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--particles", type=int, default=250)
    p.add_argument("--repeats", type=int, default=50)
    p.add_argument("--body", default="paper22")
    args = p.parse_args()
    cfg = presets.read("body", args.body)
    print(f"posing {args.particles} particles, body {args.body}")
    print(f"{'dtype':8s} {'part':14s} {'median ms':>10s} {'best ms':>8s}")
    for dtype in ("float32", "float64"):
        model = load_body_model(cfg["dofs"], dtype=dtype)
        sb = model.shaped()
        chi = np.random.default_rng(0).normal(0, 0.3, (args.particles, model.num_dofs)).astype(dtype)
        G = chain_transforms(model.parents, model.dof_joint, sb.axes, sb.rest_joints, chi[:, :6], chi[:, 6:])
        parts = {
            "pose (total)": lambda: sb.pose(chi),
            "twist chain": lambda: chain_transforms(model.parents, model.dof_joint, sb.axes,
                                                    sb.rest_joints, chi[:, :6], chi[:, 6:]),
            "LBS": lambda: lbs_apply(sb._basis_t, G),
            "joints only": lambda: sb.joints(chi),
        }
        for name, fn in parts.items():
            med, best = timeit(fn, args.repeats)
            print(f"{dtype:8s} {name:14s} {med:10.2f} {best:8.2f}")


if __name__ == "__main__":
    main()
