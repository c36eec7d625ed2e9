"""Question: how close can silhouettes alone bring our body to the ground truth under model
mismatch (starting from the oracle), i.e. what error should no silhouette tracker beat?

How close silhouettes alone can bring our body to the ground truth: the silhouette floor.

The oracle (:func:`mocap.eval.mismatch.fit_oracle`) fits our body to the true joints: it is
the floor of a tracker that saw the joints. A silhouette tracker sees outlines, and under
model mismatch the state that best explains them need not be the one whose joints are
right. This starts from the oracle's shape and poses (the right basin, found with the ground
truth) and lowers the silhouette energy E_S from there, alternating
1. the shape on keyframes spread over the sequence, poses held
   (:func:`mocap.trackers.shape_search.refine_shape`), and
2. every frame's pose: an annealed search on E_S around it, then local optimisation on the
   contours, kept where E_S drops;
and scores each stage. Where E_S falls while the joint error rises, the silhouettes do not
determine the joints to the oracle's accuracy, and no silhouette tracker should be expected
to reach it.

    python experiments/silhouette_floor.py data=mismatch_walk      # one sequence
    python experiments/silhouette_floor.py --all                   # the three mismatch sequences
Writes outputs/silhouette_floor/<sequence>.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.eval.mismatch import fit_oracle
from mocap.eval.run_metrics import OracleSettings, accuracy_metrics
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.optimize import optimize_pose
from mocap.run_folder import write_json
from mocap.threads import thread_budget
from mocap.trackers.apf import run_apf
from mocap.trackers.shape_search import refine_shape, shifted
from mocap.trackers.tracker_settings import APFSettings, ShapeRefinement
from mocap_cli.hydra_edge import build, compose

SEQUENCES = ("mismatch_walk", "mismatch_box", "mismatch_gesture")


def mean_energy(body, rig, alpha, chis, masks, scale) -> float:
    sil = SilhouetteEnergy(body.shaped(alpha), rig, scale)
    names = tuple(rig.names)
    return float(np.mean([sil(c[None], silhouette_target(m, scale, view_names=names))[0]
                          for c, m in zip(chis, masks, strict=True)]))


def floor(data: str, rounds: int, keyframes: int, frames: int | None, seed: int) -> dict:
    cfg = compose("track", overrides=[f"data={data}"])
    body = build(cfg.body)
    seq = build(cfg.data, body=body)
    gt, rig = seq.gt, seq.rig
    if gt is None or seq.masks is None:
        raise ValueError(f"{data}: the silhouette floor needs masks and ground-truth joints")
    if gt.chi is not None:
        raise ValueError(f"{data}: rendered by our own body model, whose truth it can reach exactly; "
                         "the silhouette floor is for data another model rendered")
    F = seq.num_frames if frames is None else min(frames, seq.num_frames)
    masks = [seq.masks[f] for f in range(F)]
    rng = np.random.default_rng(seed)
    scale = rig.scale_for(256)
    oracle = fit_oracle(body, gt.joint_names, gt.joints[:F], None if gt.joint_valid is None
                        else gt.joint_valid[:F], gt.skeleton or None)
    alpha, chis = oracle.alpha.copy(), oracle.chi.copy()
    stages = []

    def score(stage: str, seconds: float) -> None:
        # the joint errors only: the oracles' fits (the joint and the surface oracle) are not read
        acc = accuracy_metrics(body, seq, chis, alpha, oracle=OracleSettings(enabled=False))
        row = {"stage": stage, "raw_mm": acc["mismatch"]["raw_mm"],
               "offset_removed_mm": acc["mismatch"]["offset_removed_mm"],
               "limbs_mm": acc["mismatch"]["limbs_mm"],
               "silhouette_energy": mean_energy(body, rig, alpha, chis, masks, scale), "seconds": seconds}
        stages.append(row)
        print(f"{data} {stage}: {row['raw_mm']:.1f} mm raw, {row['offset_removed_mm']:.1f} offset-removed, "
              f"E_S {row['silhouette_energy']:.4f}", flush=True)

    score("oracle (fitted to the true joints)", 0.0)
    keys = np.unique(np.linspace(0, F - 1, min(keyframes, F)).round().astype(int))
    search = ShapeRefinement(every=1, particles=40, layers=8, std=0.4, shift=0.03, min_gain=0.0)
    pose_search = APFSettings(particles=40, layers=8, diffusion=0.7, shrink=0.9)
    std = np.r_[np.full(3, 0.01), np.full(3, 0.03), np.full(body.num_dofs - 6, 0.08)]
    matcher = ContourMatcher(body, rig)
    for r in range(rounds):
        t = time.perf_counter()
        found = refine_shape(body, rig, alpha, chis[keys], [masks[k] for k in keys], tuple(keys),
                             search, rng)
        if found.accepted:
            alpha = found.alpha
            chis = np.stack([shifted(c, found.shift) for c in chis])
        score(f"round {r + 1}: shape", time.perf_counter() - t)
        t = time.perf_counter()
        shaped = body.shaped(alpha)
        sil = SilhouetteEnergy(shaped, rig, scale)
        for f in range(F):
            target = silhouette_target(masks[f], scale, view_names=tuple(rig.names))
            c, _ = run_apf(lambda x, t=target, e=sil: e(x, t), chis[f], std, body.limits, pose_search, rng,
                           root_point=shaped.rest_joints[0])
            obs = observed_contours(masks[f])
            c, _ = optimize_pose(shaped, c, lambda v, o=obs: matcher(v, o), 10)
            if sil(c[None], target)[0] < sil(chis[f][None], target)[0]:
                chis[f] = c
        score(f"round {r + 1}: poses", time.perf_counter() - t)
    return {"data": data, "frames": F, "keyframes": keys.tolist(), "seed": seed, "stages": stages,
            "alpha": alpha.tolist()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", nargs="*", help="data=<name> of conf/data (default with --all: "
                   "the three mismatch sequences)")
    p.add_argument("--all", action="store_true", help="the three model-mismatch sequences")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--keyframes", type=int, default=10)
    p.add_argument("--frames", type=int, default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--out", type=Path, default=Path("outputs") / "silhouette_floor")
    args = p.parse_args(argv)
    names = [d.split("=", 1)[-1] for d in args.data] or (list(SEQUENCES) if args.all else [])
    if not names:
        p.error("name a sequence (data=mismatch_walk) or pass --all")
    if args.rounds < 1 or args.keyframes < 1:
        p.error("--rounds and --keyframes must be >= 1")
    args.out.mkdir(parents=True, exist_ok=True)
    with thread_budget(args.threads):
        for name in names:
            result = floor(name, args.rounds, args.keyframes, args.frames, args.seed)
            write_json(args.out / f"{name}.json", result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
