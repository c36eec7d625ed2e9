"""Does per-person scoring (a gt.npz with a person axis in a Pose2Sim folder) pick the person a
tracker follows on the real Pose2Sim demo, and leave the other one untracked?

The demo has no ground truth. This writes a copy of it (links to its keypoints) with a
*pseudo* ground truth: per frame, the people associated across views by whole-skeleton
epipolar consistency (:mod:`mocap.trackers.markers.associate`) triangulated by DLT, linked over
frames by the nearest centroid, in the ``coco17`` skeleton, people ``p0`` (most views in the
first frame) and ``p1``. It is model-free triangulation, not an accuracy reference: the MPJPE
against it is agreement with triangulation (COCO hips are not anatomical hip joints).

    python -m experiments.pose2sim_pseudo_gt --out outputs/demo_pseudo_gt
    mocap track tracker=marker_apf data=pose2sim_demo data.path=outputs/demo_pseudo_gt \\
        init.mode=tracker recording.enabled=false hydra.run.dir=outputs/demo_pseudo_gt_run
    # metrics.json: people.p0 / people.p1 (track, coverage, mpjpe_mm, pcp, identity_switches)
"""

from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from mocap.body.skeletons import SKELETONS
from mocap.cameras import fundamental_matrices, triangulate
from mocap.data.openpose import load_openpose_sequence
from mocap.trackers.markers.associate import associate_people, skeletons_of

DEMO = Path(os.environ.get("MOCAP_SHARED_DATA", "../shared/data")) / "pose2sim-demo"


def pseudo_ground_truth(demo: Path, out: Path, people: int = 2) -> np.ndarray:
    """Write out/ (Calib.toml, a link to demo/pose, gt.npz); returns joints (F, P, 17, 3)."""
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    shutil.copy(demo / "Calib.toml", out)
    (out / "pose").symlink_to((demo / "pose").resolve())
    seq = load_openpose_sequence(out, layout="auto", person="all", fps=60)
    if seq.meta["layout"] not in ("BODY_25B", "HALPE_26", "COCO_17"):
        raise ValueError(f"{demo}: layout {seq.meta['layout']} does not start with the COCO-17 keypoints")
    names, K = list(seq.detections.labels), 17
    fm = fundamental_matrices(seq.rig)
    threshold = 0.04 * float(np.hypot(*seq.rig.sizes[0]))        # the marker tracker's gate
    joints = np.full((seq.num_frames, people, K, 3), np.nan)
    last: list[np.ndarray | None] = [None] * people
    for f in range(seq.num_frames):
        det = seq.detections.select(f)
        sk = skeletons_of(det, names, seq.rig)
        found = []
        for combo, _ in associate_people(sk, fm, threshold)[:people]:
            xy = np.zeros((len(seq.rig), K, 2))
            ok = np.zeros((len(seq.rig), K), bool)
            for c, i in enumerate(combo):
                if i is not None:
                    sel = (det.view == c) & (det.person == sk.ids[c][i]) & (det.label < K)
                    xy[c, det.label[sel]], ok[c, det.label[sel]] = det.xy[sel], True
            found.append(triangulate(seq.rig, xy, valid=ok))
        if f == 0:
            order = list(range(len(found)))
        else:
            centre = [np.nanmedian(p, 0) if p is not None else None for p in last]
            cost = np.array([[np.linalg.norm(np.nanmedian(x, 0) - c) if c is not None else 1e9
                              for c in centre] for x in found]).reshape(len(found), people)
            order = [None] * len(found)
            for a, b in zip(*linear_sum_assignment(cost), strict=True):
                order[a] = int(b)
        for x, p in zip(found, order, strict=True):
            if p is not None:
                joints[f, p] = last[p] = x
    np.savez(out / "gt.npz", joints=joints, joint_valid=np.isfinite(joints).all(-1),
             joint_names=np.array(list(SKELETONS["coco17"])), skeleton=np.array("coco17"),
             person_names=np.array([f"p{p}" for p in range(people)]))
    return joints


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--demo", type=Path, default=DEMO)
    p.add_argument("--out", type=Path, default=Path("outputs/demo_pseudo_gt"))
    args = p.parse_args(argv)
    joints = pseudo_ground_truth(args.demo, args.out)
    seen = np.isfinite(joints).all(-1).any(-1).sum(0)
    print(f"wrote {args.out / 'gt.npz'}: {len(joints)} frames, people seen in "
          + ", ".join(f"p{p} {n}" for p, n in enumerate(seen)) + " frames")


if __name__ == "__main__":
    main()
