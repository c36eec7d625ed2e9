"""Benchmark: frames per second of ``marker_apf`` (the preset of :mod:`mocap.trackers.presets`).

    .venv/bin/python benchmarks/bench_marker.py [--frames 60] [--particles P --layers L]
    .venv/bin/python benchmarks/bench_marker.py --keypoints --views 5     # 5 views x 25 keypoints
    .venv/bin/python benchmarks/bench_marker.py --numpy                   # the numpy likelihood

Tracks a synthetic walk seen by the HumanEva-like rig (4 views, 640x480; detection rate 0.9,
false positives 0.1, 2 px noise, labelled markers); with ``--keypoints`` the 25 BODY_25B
keypoints of one person (2 px noise, no misses, :mod:`mocap.data.crowd`) seen by a ring of
``--views`` cameras (1920x1080). Runs the tracker's default particles x layers and prints
the median and mean wall time per frame (step only), frames per second, the process CPU
time per frame (start-up included) and the median CPU time of one step (what an idle core
would take: on a shared machine the wall time also counts waiting for a core), the split
between observation (arranging detections) and annealed search, and the cost of one
likelihood evaluation of P particles and its parts.
The paper's claim: real time (>= 30 fps). Report the machine load with the numbers.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocap import presets
from mocap.body import load_body_model
from mocap.body.skeletons import LAYOUTS
from mocap.cameras import rig_from_config, ring_rig
from mocap.data.crowd import crowd_detections
from mocap.data.generate import make_synthetic
from mocap.energy.markers import MarkerEnergy, pinhole_project, view_costs
from mocap.trackers.presets import make_tracker
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
    p.add_argument("--views", type=int, default=4)
    p.add_argument("--keypoints", action="store_true", help="25 BODY_25B keypoints instead of 15+ markers")
    p.add_argument("--numpy", action="store_true", help="the numpy likelihood instead of the compiled one")
    args = p.parse_args()
    dofs = presets.read("body", "paper22")["dofs"]
    body = load_body_model(dofs, name="paper22")
    if args.keypoints or args.views != 4:
        rig = ring_rig(args.views, 4.0, 1.5, 1920, 1080, fov_deg=60, look_at=(0, 0, 1.0))
    else:
        rig = rig_from_config("humaneva")
    detections = {"enabled": True, "detection_rate": 0.9, "false_positive_rate": 0.1, "noise_px": 2.0,
                  "occlusion": False}
    seq = make_synthetic(body, rig, motion=args.motion, frames=args.frames, fps=25, seed=args.seed,
                         masks=False, detections=None if args.keypoints else detections)
    if args.keypoints:
        labels = [n for n in LAYOUTS["BODY_25B"] if n is not None]
        det, _ = crowd_detections(body, rig, seq.gt.chi[None], seq.gt.alpha[None], labels, noise_px=2.0,
                                  seed=args.seed)
        seq = replace(seq, detections=det)
    budget = {k: getattr(args, k) for k in ("particles", "layers") if getattr(args, k) is not None}
    trk = make_tracker("marker_apf", body=body, rig=rig, rng=np.random.default_rng(args.seed), **budget)
    trk.likelihood = replace(trk.likelihood, compiled=not args.numpy)
    step_cpu: list[float] = []
    inner_step = trk.step

    def timed_step(frame):                             # this thread's CPU time per step
        c0 = time.thread_time()
        out = inner_step(frame)
        step_cpu.append(time.thread_time() - c0)
        return out

    trk.step = timed_step
    cpu0 = time.process_time()
    res = track_sequence(trk, seq, seq.gt.chi[0], seq.gt.alpha)
    cpu = (time.process_time() - cpu0) / (len(res.estimates) - 1)
    step_cpu = np.array(step_cpu[1:])                  # as ``step``: from frame 2 on
    step = np.array(res.seconds[2:])                   # frame 1 builds the landmark set and groups
    obs = np.array([e.diagnostics["timings"]["observation"] for e in res.estimates[2:]])
    search = np.array([e.diagnostics["timings"]["search"] for e in res.estimates[2:]])
    P, L = trk.settings.particles, trk.settings.layers
    kind = "numpy" if args.numpy else "compiled"
    print(f"marker_apf {P} particles x {L} layers, {len(rig)} views, {len(trk.landmarks)} landmarks, "
          f"{kind} likelihood, "
          f"{len(step)} frames; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"  per frame: median {1e3 * np.median(step):.1f} ms, mean {1e3 * step.mean():.1f} ms "
          f"-> {1 / np.median(step):.1f} fps (median), {1 / step.mean():.1f} fps (mean)")
    c = np.median(step_cpu)
    print(f"  CPU time per frame {1e3 * cpu:.1f} ms (start-up included) -> {1 / cpu:.1f} fps; per step "
          f"(thread CPU time, median) {1e3 * c:.1f} ms -> {1 / c:.1f} fps on an otherwise idle core")
    print(f"  observation {1e3 * obs.mean():.2f} ms, search {1e3 * search.mean():.1f} ms, "
          f"other {1e3 * (step.mean() - obs.mean() - search.mean()):.2f} ms")
    predicted = trk.predict()
    energy, _ = trk.frame_energy(frame_of(seq, len(res.estimates) - 1), predicted)
    x = predicted + np.random.default_rng(0).normal(0, 0.02, (P, body.num_dofs))
    X = energy.points(x)
    u, depth = pinhole_project(energy.rig, X, compiled=False)
    front = depth > 0.05
    gate = energy.settings.gate_px
    total = timeit(lambda: energy.landmark_costs(x), 50)
    fk = timeit(lambda: energy.points(x), 50)
    proj = timeit(lambda: pinhole_project(energy.rig, X, compiled=False), 50)
    ref = MarkerEnergy(energy.landmarks, energy.shaped, energy.rig, energy.obs, energy.settings,
                       F=energy.F, compiled=False)
    costs = timeit(lambda: view_costs(u, front, ref.obs_cast, ref.tables, gate), 50)
    Xc = np.ascontiguousarray(X, np.float64)
    fused = timeit(lambda: energy.costs_of_points(Xc), 50) if energy.compiled else float("nan")
    print(f"  one likelihood evaluation of {P} particles: {total:.2f} ms (forward kinematics {fk:.2f}; "
          f"numpy: projection {proj:.2f}, gating + epipolar {costs:.2f}; compiled projection + gating "
          f"+ epipolar {fused:.2f})")


if __name__ == "__main__":
    main()
