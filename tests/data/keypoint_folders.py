"""Small synthetic keypoint recordings for tests: a Pose2Sim-style folder (Calib.toml,
pose/<camera>_json/*.json in the BODY_25B layout) of one or two people with known 3D joints,
and its ground truth (gt.npz, mocap's own joint names; several people: a person axis)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from mocap.body.catalogue import make_landmark_set
from mocap.body.skeletons import LAYOUTS
from mocap.cameras import project, write_pose2sim_calibration
from mocap.data.sequence import GroundTruth
from mocap.data.sequence_io import write_ground_truth

#: the second person: the first one's motion moved by this much (m)
OFFSET = np.array([1.5, 0.0, 0.0])


def known_people(body, frames: int = 3, people: int = 2):
    """(rig, joints (F, P, J, 3), keypoints (F, P, K, 3) of BODY_25B, None where unknown)."""
    from mocap.data.sources import synthetic_sequence

    seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=frames, fps=25, seed=0,
                             name="two", shape_scale=0.8, masks=False, images=False)
    names = [n for n in LAYOUTS["BODY_25B"] if n is not None]
    lms = make_landmark_set(body, "auto", names)
    pts = lms.positions(body.shaped(seq.gt.alpha), seq.gt.chi).astype(np.float64)     # (F, L, 3)
    kp = np.full((frames, len(LAYOUTS["BODY_25B"]), 3), np.nan)
    for k, n in enumerate(LAYOUTS["BODY_25B"]):
        if n in lms.names:
            kp[:, k] = pts[:, lms.names.index(n)]
    shift = np.arange(people)[:, None, None] * OFFSET
    joints = seq.gt.joints[:, None] + shift[None]
    keypoints = kp[:, None] + shift[None]
    return seq.rig, joints, keypoints, seq.gt


def write_pose2sim(root: Path, rig, keypoints: np.ndarray, order=None) -> Path:
    """Calib.toml and pose/<camera>_json/<camera>.NNNN.json of 3D keypoints (F, P, K, 3)
    projected into every view (confidence 0.9, 0 where a keypoint is unknown); ``order``:
    a function (frame, view) -> the order of the people in that file."""
    root.mkdir(parents=True, exist_ok=True)
    write_pose2sim_calibration(rig, root / "Calib.toml")
    F, P, K, _ = keypoints.shape
    px = project(rig, np.nan_to_num(keypoints.reshape(F * P, K, 3)))                 # (F*P, C, K, 2)
    px = px.reshape(F, P, len(rig), K, 2)
    known = np.isfinite(keypoints).all(-1)
    for c, name in enumerate(rig.names):
        d = root / "pose" / f"{name}_json"
        d.mkdir(parents=True)
        for f in range(F):
            people = []
            for p in (order(f, c) if order else range(P)):
                arr = np.concatenate([px[f, p, c], np.where(known[f, p], 0.9, 0.0)[:, None]], axis=1)
                arr[~known[f, p]] = 0.0
                values = [round(float(v), 3) for v in arr.ravel()]
                people.append({"person_id": [-1], "pose_keypoints_2d": values})
            (d / f"{name}.{f:04d}.json").write_text(json.dumps({"version": 1.3, "people": people}))
    return root


def write_gt(path: Path, gt_single: GroundTruth, joints: np.ndarray, person_names=None) -> Path:
    """gt.npz of joints (F, P, J, 3) by mocap's joint names (P == 1 and no names: no person axis)."""
    multi = person_names is not None
    gt = GroundTruth(alpha=None, chi=None, joints=joints if multi else joints[:, 0], markers=None,
                     dof_names=(), joint_names=gt_single.joint_names, marker_names=(),
                     person_names=tuple(person_names or ()))
    write_ground_truth(gt, path)
    return path
