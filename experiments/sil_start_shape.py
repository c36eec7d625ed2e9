"""Does searching the start's shape together with its pose lower its energy and joint error (issue 34
item 4)? On frame 0 of each sequence folder: the silhouette-only hybrid's start (read from
``--init-cache``, the random state ``mocap track`` gives it at ``--seed``), then the initialiser's
shape-and-pose step (:func:`mocap.trackers.start_shape.shape_pose_step`) with the settings given
here, run on that start as the initialiser runs it last; printed: the initialiser's fine E_S and the
joint error (mean over the joints, mm) of the start and of the result, the shape before and after.
The surface oracle's frame-0 E_S (the floor the search aims at) is in ``experiments.sil_start_energy``.

    python -m experiments.sil_start_shape data/real_motion/dev/* --init-cache outputs/init_cache \\
        [--searches 2 --particles 100 --layers 10 --pose-scale 0 --shape-std 0.5 --mesh full] \\
        [--out outputs/start_shape.jsonl]
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import time
from pathlib import Path

import numpy as np

from experiments.sil_hybrid_diagnosis import joint_errors
from experiments.sil_start_energy import StartEnergies
from experiments.tools.jsonl import report
from mocap.body import load_body
from mocap.body.energy_mesh import energy_mesh_for
from mocap.data.sources import folder_sequence
from mocap.eval.by_name import NameScorer
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of
from mocap.trackers.start_shape import shape_pose_step

#: the initialiser's first-layer pose spread (m, rad): root translation, rotation, joint angles
POSE_STD = (0.05, 0.15, 0.3)


def measure(seq_path: Path, seed: int, cache: str | None, changes: dict, mesh: str) -> dict:
    body = load_body("paper22")
    seq = folder_sequence(body=body, path=str(seq_path), name=f"real_{seq_path.name}", seed=seed)
    rng = np.random.default_rng([seed, 1])
    tracker = make_tracker("hybrid", body=body, rig=seq.rig, rng=rng)
    frame = frame_of(seq, 0)
    est, _ = tracker.initializer(cache).start(frame)
    a0, c0 = np.asarray(est[0].alpha, np.float64), np.asarray(est[0].chi, np.float64)
    settings = dataclasses.replace(tracker.init_settings, **changes)
    E = StartEnergies(body, seq.rig, frame.masks, settings)
    std = np.r_[np.full(3, POSE_STD[0]), np.full(3, POSE_STD[1]), np.full(body.num_dofs - 6, POSE_STD[2])]
    t = time.perf_counter()
    coarse = energy_mesh_for(body, settings.energy_mesh) if mesh == "coarse" else None
    chi, alpha, report = shape_pose_step(body, seq.rig.scaled(E.scale), E.target, coarse,
                                         lambda a, c: float(E.fine(a, c)[0]), E.local, c0, a0, settings, std,
                                         copy.deepcopy(rng))
    seconds = time.perf_counter() - t
    scorer = NameScorer(body, seq.gt.person(0))
    out = {"data": seq.name, "seed": seed, "settings": changes, "mesh": mesh, "seconds": seconds,
           "searches": report}
    for name, (a, c) in {"start": (a0, c0), "after": (alpha, chi)}.items():
        names, err, _, _ = joint_errors(scorer, a[None], c[None])
        out[name] = {"E_S_fine": float(E.fine(a, c)[0]), "mpjpe_mm": float(err[0].mean()),
                     "per_joint_mm": {n: round(float(err[0, k]), 1) for k, n in enumerate(names)},
                     "alpha": [round(float(x), 3) for x in a[:8]]}
    return out


def summary(r: dict) -> str:
    s, a = r["start"], r["after"]
    return (f"{r['data']}: E_S {s['E_S_fine']:.4f} -> {a['E_S_fine']:.4f} "
            f"({(a['E_S_fine'] / s['E_S_fine'] - 1) * 100:+.1f}%), joints {s['mpjpe_mm']:.1f} -> "
            f"{a['mpjpe_mm']:.1f} mm, kept {[x['kept'] for x in r['searches']]}, shape {s['alpha']} -> "
            f"{a['alpha']}, {r['seconds']:.0f} s")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="+", type=Path)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--init-cache", default="outputs/init_cache")
    p.add_argument("--searches", type=int, default=2)
    p.add_argument("--particles", type=int, default=100)
    p.add_argument("--layers", type=int, default=10)
    p.add_argument("--pose-scale", type=float, default=0.0)
    p.add_argument("--shape-std", type=float, default=0.5)
    p.add_argument("--mesh", choices=["coarse", "full"], default="full")
    p.add_argument("--out", type=Path)
    a = p.parse_args(argv)
    changes = {"shape_pose_searches": a.searches, "shape_pose_particles": a.particles,
               "shape_pose_layers": a.layers, "shape_pose_pose_scale": a.pose_scale,
               "shape_pose_shape_std": a.shape_std}
    for s in a.sequences:
        r = measure(s, a.seed, a.init_cache, changes, a.mesh)
        report(r, summary(r), a.out)


if __name__ == "__main__":
    main()
