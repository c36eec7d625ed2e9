"""Benchmark: frames per second of ``marker_apf`` (conf/tracker/marker_apf.yaml) with 4 views.

    .venv/bin/python benchmarks/bench_marker.py [--frames 60] [--particles P --layers L]

Tracks a synthetic walk seen by the HumanEva-like rig (4 views, 640x480; detection rate 0.9,
false positives 0.1, 2 px noise, labelled markers) at the tracker's default particles x
layers and prints the median and mean wall time per frame (step only), frames per second,
the process CPU time per frame (what an idle core would take: on a shared machine the wall
time also counts waiting for a core), the split between observation (arranging detections)
and annealed search, and the cost of one likelihood evaluation of P particles and its parts.
The paper's claim: real time (>= 30 fps). Report the machine load with the numbers.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import yaml

from mocap import presets
from mocap.body import load_body_model
from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.energy.markers import pinhole_project, view_costs
from mocap.trackers.factory import make_marker_tracker
from mocap.trackers.run import frame_of, track_sequence

REPO = Path(__file__).resolve().parents[1]


def timeit(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * float(np.median(times))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--motion", default="walk")
    p.add_argument("--particles", type=int, default=None)
    p.add_argument("--layers", type=int, default=None)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    dofs = presets.read("body", "paper22")["dofs"]
    body = load_body_model(dofs, name="paper22")
    rig = rig_from_config("humaneva")
    detections = {"enabled": True, "detection_rate": 0.9, "false_positive_rate": 0.1, "noise_px": 2.0,
                  "occlusion": False}
    seq = make_synthetic(body, rig, motion=args.motion, frames=args.frames, fps=25, seed=args.seed,
                         masks=False, detections=detections)
    cfg = yaml.safe_load((REPO / "conf/tracker/marker_apf.yaml").read_text())
    cfg.pop("_target_")
    for k in ("particles", "layers"):
        if getattr(args, k) is not None:
            cfg[k] = getattr(args, k)
    trk = make_marker_tracker(body=body, rig=rig, rng=np.random.default_rng(args.seed), **cfg)
    cpu0 = time.process_time()
    res = track_sequence(trk, seq, seq.gt.chi[0], seq.gt.alpha)
    cpu = (time.process_time() - cpu0) / (len(res.estimates) - 1)
    step = np.array(res.seconds[2:])                   # frame 1 builds the landmark set and groups
    obs = np.array([e.diagnostics["timings"]["observation"] for e in res.estimates[2:]])
    search = np.array([e.diagnostics["timings"]["search"] for e in res.estimates[2:]])
    P, L = cfg["particles"], cfg["layers"]
    print(f"marker_apf {P} particles x {L} layers, 4 views, {len(trk.landmarks)} landmarks, "
          f"{len(step)} frames; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"  per frame: median {1e3 * np.median(step):.1f} ms, mean {1e3 * step.mean():.1f} ms "
          f"-> {1 / np.median(step):.1f} fps (median), {1 / step.mean():.1f} fps (mean)")
    print(f"  CPU time per frame {1e3 * cpu:.1f} ms -> {1 / cpu:.1f} fps on an otherwise idle core")
    print(f"  observation {1e3 * obs.mean():.2f} ms, search {1e3 * search.mean():.1f} ms, "
          f"other {1e3 * (step.mean() - obs.mean() - search.mean()):.2f} ms")
    predicted = trk.predict()
    energy, _ = trk.frame_energy(frame_of(seq, len(res.estimates) - 1), predicted)
    x = predicted + np.random.default_rng(0).normal(0, 0.02, (P, body.num_dofs))
    X = energy.points(x)
    u, depth = pinhole_project(energy.rig, X)
    front = depth > 0.05
    gate = energy.settings.gate_px
    total = timeit(lambda: energy.landmark_costs(x), 50)
    fk = timeit(lambda: energy.points(x), 50)
    proj = timeit(lambda: pinhole_project(energy.rig, X), 50)
    costs = timeit(lambda: view_costs(u, front, energy.obs_cast, energy.tables, gate), 50)
    print(f"  one likelihood evaluation of {P} particles: {total:.2f} ms (forward kinematics {fk:.2f}, "
          f"projection {proj:.2f}, gating + epipolar {costs:.2f})")


if __name__ == "__main__":
    main()
