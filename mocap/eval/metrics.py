"""Joint-error metrics.

``mpjpe``: the HumanEva mean 3D joint error over 15 evaluation joints (pelvis, thorax,
head, shoulders, elbows, wrists, hips, knees, ankles), per frame and per joint, in mm.
``mmta`` / ``mmtp``: Canton-Ferrer et al. 2010, Sec. 4.1 (after the CLEAR MOT metrics):
the share of landmarks within a threshold of ground truth (accuracy), and the mean error of
those matched landmarks (precision), in mm.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

EVAL_JOINTS = ("pelvis", "thorax", "head", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder",
               "r_elbow", "r_wrist", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")


def joint_errors(estimate: np.ndarray, truth: np.ndarray, joint_names: Sequence[str],
                 eval_joints: Sequence[str] = EVAL_JOINTS) -> np.ndarray:
    """(F, J, 3), (F, J, 3) metres -> (F, E) Euclidean errors in mm of the evaluation joints."""
    if estimate.shape != truth.shape:
        raise ValueError(f"estimate {estimate.shape} and ground truth {truth.shape} differ")
    missing = [j for j in eval_joints if j not in joint_names]
    if missing:
        raise ValueError(f"evaluation joints missing from the body: {', '.join(missing)}")
    idx = [list(joint_names).index(j) for j in eval_joints]
    return 1e3 * np.linalg.norm(estimate[:, idx] - truth[:, idx], axis=-1)


def mpjpe_summary(errors: np.ndarray, eval_joints: Sequence[str] = EVAL_JOINTS) -> dict:
    """Summary of (F, E) errors: mean over frames of the per-frame mean, its std, per joint."""
    per_frame = errors.mean(axis=1)
    return {"mpjpe_mm": float(per_frame.mean()), "mpjpe_std_mm": float(per_frame.std()),
            "per_joint_mm": {j: float(e) for j, e in zip(eval_joints, errors.mean(axis=0), strict=True)},
            "per_frame_mm": [float(e) for e in per_frame]}


def mmta_mmtp(estimate: np.ndarray, truth: np.ndarray, threshold_mm: float = 200.0) -> dict:
    """MMTA (share of landmarks within ``threshold_mm``) and MMTP (their mean error, mm).

    estimate, truth: (F, L, 3) metres.
    """
    err = 1e3 * np.linalg.norm(estimate - truth, axis=-1)
    matched = err <= threshold_mm
    return {"mmta": float(matched.mean()),
            "mmtp_mm": float(err[matched].mean()) if matched.any() else float("nan"),
            "mmt_threshold_mm": threshold_mm}
