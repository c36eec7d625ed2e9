"""Benchmark: frames per second of ``marker_people`` (several people) on the synthetic crowd.

    OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_people.py
    ... benchmarks/bench_people.py --frames 80 --seed 0 [--profile 30]

The crowd of ``data=crowd`` (:func:`mocap.data.crowd.crowd_sequence`: five people, at most four
at once, 5 views 640x480, 1 px noise) tracked by the ``marker_people`` preset (default settings)
in one thread: the start-up on frame 0, then one :meth:`PeopleTracker.step` per frame, timed.
Prints frames/s over the frames with 4 people live and no newcomer's start-up (the issue's
figure: 4 people in view, 5 views, one thread) from the wall time and from the thread's CPU
time (what an idle core would take: the machine is shared), over every frame, and the load
average. ``--profile N`` prints the N costliest functions (cProfile, cumulative) of the
tracking loop instead of timing it. Uses only the public API, so the same
file times another checkout (``PYTHONPATH=/work/main``): run old and new alternately in one
session and compare ratios.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from mocap import presets
from mocap.body import load_body_model
from mocap.data.crowd import crowd_sequence
from mocap.threads import thread_budget
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of


def track(seq, body, seed: int) -> tuple[list[float], list[float], list[int], list[bool]]:
    """(wall seconds per step, thread CPU seconds per step, tracks live after the step, whether a
    track was born) for frames 1.."""
    people = make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(seed))
    people.check_sequence(seq)
    people.start(frame_of(seq, 0))
    seconds, cpu, live, born = [], [], [], []
    for f in range(1, seq.num_frames):
        frame = frame_of(seq, f)
        t, c = time.perf_counter(), time.thread_time()
        people.step(frame)
        seconds.append(time.perf_counter() - t)
        cpu.append(time.thread_time() - c)
        live.append(sum(not t_.ended for t_ in people.tracks))
        born.append(f in people.births)
    return seconds, cpu, live, born


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=80)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--profile", type=int, default=0, help="print the N costliest functions instead")
    args = p.parse_args()
    body = load_body_model(presets.read("body", "paper22")["dofs"], name="paper22")
    seq = crowd_sequence(body=body, frames=args.frames, seed=args.seed)
    with thread_budget(1):
        track(crowd_sequence(body=body, frames=20, seed=args.seed), body, args.seed)     # warm-up (numba)
        if args.profile:
            import cProfile
            import pstats

            prof = cProfile.Profile()
            prof.enable()
            track(seq, body, args.seed)
            prof.disable()
            pstats.Stats(prof).sort_stats(os.environ.get("SORT", "cumulative")).print_stats(args.profile)
            return
        seconds, cpu, live, born = track(seq, body, args.seed)
    s, c, n, b = np.array(seconds), np.array(cpu), np.array(live), np.array(born)
    four = (n == 4) & ~b
    print(f"marker_people, crowd seed {args.seed}, {args.frames} frames, 5 views, one thread; "
          f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"  4 people live ({four.sum()} frames): {1 / s[four].mean():.1f} frames/s (mean), "
          f"{1 / np.median(s[four]):.1f} (median); on an idle core (thread CPU time): "
          f"{1 / c[four].mean():.1f} (mean); all frames: {len(s) / s.sum():.1f} frames/s (wall), "
          f"{len(c) / c.sum():.1f} (CPU, start-ups included)")


if __name__ == "__main__":
    main()
