"""Thread independence: the same seed tracked with 1 and with 2 numeric threads (BLAS / OpenMP,
numba, OpenCV: :func:`mocap.threads.thread_budget`), per tracker family, and the largest pose
difference between the two tracks (and between two 1-thread runs in the same process).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_threads.py [--frames 3]
        [--runs local,apf_25x10,hybrid,marker_apf] [--threads 2] [--cameras ring4_small|mpi08]
        [--self-init] [--folder data/mismatch/box] [--save FILE.npz] [--against FILE.npz]

Data: a synthetic walk (seed 0) seen by ``--cameras``: ``ring4_small`` (4 views at 320x240, the
default) or ``mpi08`` (8 views at 1004x1004, the speed benchmark's rig); silhouettes for
local / apf / hybrid, labelled 2D detections for marker_apf (self-initialised from frame 0, as
``mocap track`` would with ``init.mode=tracker``); the others start at ground truth + noise
(3 deg, 2 cm). Each tracker runs its preset's defaults. Prints, per tracker: max |dchi| over
every frame and DOF between the 1-thread and the N-thread track (rad / m), the first frame
where they differ, the largest relative difference of the per-frame energies (the energy terms
of the estimates' diagnostics: they show a difference that has not moved the pose yet), the same
for a second 1-thread run, and the seconds of each run; with ``--against`` also the 1-thread
tracks against those of another process (``--save``): a cold numba cache, say::

    bench_threads.py --save /tmp/warm.npz
    NUMBA_CACHE_DIR=$(mktemp -d) bench_threads.py --against /tmp/warm.npz
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import mocap
from mocap.threads import thread_budget

#: run name -> (tracker preset, settings, sequence kind, init)
RUNS = {
    "local": ("local", {}, "silhouettes", "gt_noise"),
    "apf_25x10": ("apf_25x10", {}, "silhouettes", "gt_noise"),
    "apf_prior": ("apf_prior", {}, "silhouettes", "gt_noise"),
    "hybrid": ("hybrid", {}, "silhouettes", "gt_noise"),
    "marker_apf": ("marker_apf", {}, "markers", "tracker"),
}


def sequences(body, frames: int, cameras: str = "ring4_small", folder: Path | None = None) -> dict:
    """kind -> sequence: the synthetic walk's, or a sequence folder's silhouettes."""
    if folder is not None:
        from mocap.data.sources import folder_sequence

        return {"silhouettes": folder_sequence(body=body, path=str(folder), images=False)}
    common = {"cameras": cameras, "motion": "walk", "frames": frames, "seed": 0}
    return {"silhouettes": mocap.synthetic_sequence(body, **common),
            "markers": mocap.synthetic_sequence(body, masks=False, detections={
                "enabled": True, "labelled": True, "occlusion": False}, **common)}


def track(body, seqs: dict, run: str, threads: int, init: str | None = None,
          frames: int | None = None) -> tuple[np.ndarray, dict, float]:
    """Poses (F, D) of ``run`` tracked with a budget of ``threads``, every frame's energies
    (``energy/<term>`` of its diagnostics: name -> (F,), NaN where a frame has none) and the
    run's seconds. init: the run's own (None) or "tracker" (self-initialised from frame 0)."""
    tracker, settings, kind, own = RUNS[run]
    init = init or own
    t = time.perf_counter()
    with thread_budget(threads):
        result = mocap.track(seqs[kind], tracker, body=body, seed=0, init=init, frames=frames, **settings)
    seconds = time.perf_counter() - t
    scalars = [e.diagnostics.scalars() if hasattr(e.diagnostics, "scalars") else {} for e in result.estimates]
    names = sorted({k for s in scalars for k in s if k.startswith("energy/")})
    energies = {k: np.array([s.get(k, np.nan) for s in scalars], float) for k in names}
    return np.stack([e.chi for e in result.estimates]), energies, seconds


def compare(a: np.ndarray, b: np.ndarray) -> tuple[float, str]:
    """max |a - b| and the first frame where a and b differ ('-' when they are equal)."""
    d = np.abs(a - b)
    differs = np.flatnonzero(d.max(axis=1) > 0)
    return float(d.max()), (str(differs[0]) if len(differs) else "-")


def energy_gap(a: dict, b: dict) -> float:
    """The largest relative difference of two runs' per-frame energies (inf: other terms)."""
    if a.keys() != b.keys():
        return float("inf")
    gaps = [np.nanmax(np.abs(a[k] - b[k]) / np.maximum(np.abs(a[k]), 1e-300), initial=0.0) for k in a]
    return float(max(gaps, default=0.0))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=3, help="frames per track (frame 0 is the start)")
    p.add_argument("--runs", default="local,apf_25x10,hybrid,marker_apf", help=f"of {', '.join(RUNS)}")
    p.add_argument("--threads", type=int, default=2, help="the budget compared with 1 thread")
    p.add_argument("--cameras", default="ring4_small", help="camera preset: ring4_small or mpi08")
    p.add_argument("--self-init", action="store_true",
                   help="every tracker initialises itself from frame 0 (init.mode=tracker)")
    p.add_argument("--save", type=Path, help="write the 1-thread tracks here (.npz, one array per tracker)")
    p.add_argument("--against", type=Path,
                   help="also compare the 1-thread tracks with those --save wrote (another process: "
                        "e.g. a cold numba cache, NUMBA_CACHE_DIR=<empty folder>, or another machine)")
    p.add_argument("--folder", type=Path,
                   help="a sequence folder's silhouettes instead of the synthetic walk (e.g. "
                        "data/mismatch/box; no ground-truth pose: the trackers initialise themselves)")
    args = p.parse_args()
    saved = dict(np.load(args.against)) if args.against else {}
    body = mocap.load_body("paper22")
    seqs = sequences(body, args.frames, args.cameras, args.folder)
    init = "tracker" if args.self_init or args.folder else None
    data = f"{args.folder}" if args.folder else f"walk {args.cameras}"
    print(f"{args.frames} frames of {data}, seed 0; 1 vs {args.threads} threads"
          + ("; self-initialised" if init else ""))
    print(f"{'tracker':11s} {'max|dchi| 1/' + str(args.threads):>16s} {'from':>5s} {'rel dE':>9s} "
          f"{'max|dchi| 1/1':>14s} {'from':>5s} {'rel dE':>9s} {'s (1)':>7s} {f's ({args.threads})':>7s}"
          + (f" {'max|dchi| file':>15s} {'from':>5s}" if saved else ""))
    tracks = {}
    for run in args.runs.split(","):
        if RUNS[run][2] not in seqs:
            print(f"{run:11s} (no {RUNS[run][2]} in this data)")
            continue
        one, e_one, t1 = track(body, seqs, run, 1, init, args.frames)
        many, e_many, tn = track(body, seqs, run, args.threads, init, args.frames)
        again, e_again, _ = track(body, seqs, run, 1, init, args.frames)
        d_many, f_many = compare(one, many)
        d_again, f_again = compare(one, again)
        tracks[run] = one
        line = (f"{run:11s} {d_many:16.3e} {f_many:>5s} {energy_gap(e_one, e_many):9.1e} {d_again:14.3e} "
                f"{f_again:>5s} {energy_gap(e_one, e_again):9.1e} {t1:7.1f} {tn:7.1f}")
        if run in saved:
            d_file, f_file = compare(one, saved[run])
            line += f" {d_file:15.3e} {f_file:>5s}"
        print(line, flush=True)
    if args.save:
        np.savez(args.save, **tracks)


if __name__ == "__main__":
    main()
