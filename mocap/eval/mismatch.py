"""Evaluation that is fair under model mismatch (data our body model did not generate).

When the observed body is not one of our PCA bodies, or its skeleton is defined otherwise
(a thorax at the sternum instead of the spine, hips from another regression), part of every
tracker's raw joint error is a constant offset that no pose could remove. Three views of the
same estimate separate that from tracking error:

- ``raw``: the mean per-joint error (mm) over the scored joints, as :mod:`mocap.eval.by_name`;
- ``offset_removed``: each joint's constant offset over the sequence removed first. The offset
  is expressed in the subject's heading frame (x from the right to the left hip of the ground
  truth, z up), so that a definition offset that turns with the body (a thorax a few cm in
  front of the spine) is constant through a turn. It is the geometric median of the joint's
  per-frame offsets (Weiszfeld), the constant that minimises the joint's mean error, so the
  offset-removed error never exceeds the raw error;
- ``limbs``: only the 10 limb joints (:data:`LIMB_JOINTS`: hips, knees, ankles, elbows,
  wrists), whose definitions agree across skeletons best.

The **oracle** (:func:`fit_oracle`) is our body model fitted to the true joints: one shape
for the sequence and one pose per frame, by bounded least squares on the joint positions
(the same mapping by name as the scores). Its error is the floor a tracker using our model
could reach on that data; every tracker is compared to it.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.model import BodyModel
from mocap.body.skeletons import resolve_mapping

# mocap names of the limb joints scored on their own
LIMB_JOINTS = ("l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle",
               "l_elbow", "l_wrist", "r_elbow", "r_wrist")
LOST_MM = 150.0      # a frame whose raw error exceeds this is counted as lost


def heading_frames(left_hip: np.ndarray, right_hip: np.ndarray) -> np.ndarray:
    """(F, 3), (F, 3) world metres -> (F, 3, 3) world_from_heading rotations: x along the
    horizontal right-to-left hip direction, z up, y = z x x."""
    x = np.asarray(left_hip, np.float64) - np.asarray(right_hip, np.float64)
    x[:, 2] = 0.0
    n = np.linalg.norm(x, axis=1, keepdims=True)
    x = np.where(n > 1e-9, x / np.maximum(n, 1e-12), [1.0, 0.0, 0.0])
    z = np.broadcast_to([0.0, 0.0, 1.0], x.shape)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def geometric_median(points: np.ndarray, iterations: int = 100, eps: float = 1e-9) -> np.ndarray:
    """(N, 3) -> (3,): the point minimising the sum of distances (Weiszfeld's algorithm)."""
    points = np.asarray(points, np.float64)
    m = np.median(points, axis=0)
    for _ in range(iterations):
        d = np.linalg.norm(points - m, axis=1)
        w = 1.0 / np.maximum(d, eps)
        new = (w[:, None] * points).sum(axis=0) / w.sum()
        if np.linalg.norm(new - m) < 1e-10:
            return new
        m = new
    return m


def offset_removed_errors(est: np.ndarray, gt: np.ndarray, valid: np.ndarray,
                          frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """est, gt: (F, J, 3) metres; valid: (F, J) bool; frames: (F, 3, 3) world_from_heading.
    -> errors (F, J) mm with each joint's constant heading-frame offset removed (NaN where
    invalid) and the offsets (J, 3) metres in the heading frame."""
    local = np.einsum("fji,fkj->fki", frames, est - gt)          # R^T (est - gt), (F, J, 3)
    offsets = np.zeros((est.shape[1], 3))
    err = np.full(valid.shape, np.nan)
    for j in range(est.shape[1]):
        ok = valid[:, j]
        if ok.any():
            offsets[j] = geometric_median(local[ok, j])
            err[ok, j] = 1e3 * np.linalg.norm(local[ok, j] - offsets[j], axis=-1)
    return err, offsets


def _mean_of_frames(err: np.ndarray) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)      # all-NaN frames (nothing valid)
        return float(np.nanmean(np.nanmean(err, axis=1)))


@dataclass(frozen=True)
class _Matched:
    scored: list[str]            # ground-truth names scored
    ours: list[str]              # their mocap names
    gt: np.ndarray               # (F, S, 3)
    valid: np.ndarray            # (F, S)


def _match(gt_names: Sequence[str], gt_joints: np.ndarray, valid: np.ndarray | None,
           known: Sequence[str], skeleton: str | None, keep: Sequence[str] | None = None) -> _Matched:
    """Ground truth matched to ``known`` names; ``keep``: only these mocap names."""
    gt_joints = np.asarray(gt_joints, np.float64)
    mapping = resolve_mapping(gt_names, known, skeleton)
    scored = [n for n in gt_names if mapping[n] is not None and (keep is None or mapping[n] in keep)]
    idx = [list(gt_names).index(n) for n in scored]
    ok = np.isfinite(gt_joints[:, idx]).all(axis=-1)
    if valid is not None:
        ok &= np.asarray(valid, bool)[:, idx]
    return _Matched(scored, [mapping[n] for n in scored], gt_joints[:, idx], ok)


def _scores(est: np.ndarray, m: _Matched) -> dict:
    if "l_hip" not in m.ours or "r_hip" not in m.ours:
        raise ValueError("offset removal needs the ground truth's left and right hips")
    frames = heading_frames(m.gt[:, m.ours.index("l_hip")], m.gt[:, m.ours.index("r_hip")])
    raw = np.where(m.valid, 1e3 * np.linalg.norm(est - m.gt, axis=-1), np.nan)
    removed, offsets = offset_removed_errors(est, m.gt, m.valid, frames)
    limbs = [k for k, n in enumerate(m.ours) if n in LIMB_JOINTS]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)      # all-NaN frames (nothing valid)
        per_frame = np.nanmean(raw, axis=1)
        raw_mm = float(np.nanmean(per_frame))
    return {"raw_mm": raw_mm, "offset_removed_mm": _mean_of_frames(removed),
            "limbs_mm": _mean_of_frames(raw[:, limbs]) if limbs else float("nan"),
            "limbs_offset_removed_mm": _mean_of_frames(removed[:, limbs]) if limbs else float("nan"),
            "frames_lost": int(np.sum(per_frame[1:] > LOST_MM)),        # after frame 0
            "offsets_mm": {n: float(1e3 * np.linalg.norm(offsets[k])) for k, n in enumerate(m.scored)}}


def mismatch_metrics(estimate: Mapping[str, np.ndarray], gt_names: Sequence[str], gt_joints: np.ndarray,
                     valid: np.ndarray | None = None, skeleton: str | None = None) -> dict:
    """Raw, offset-removed and limb-only errors of an estimate (name -> (F, 3) metres,
    mocap names) against ground truth by name. Keys (mm): ``raw_mm``, ``offset_removed_mm``,
    ``limbs_mm``, ``limbs_offset_removed_mm``, ``frames_lost`` (frames after the first, the
    initialisation, whose raw error is above :data:`LOST_MM`: the count ``run_metrics`` reports
    at the top level too), ``offsets_mm`` (per ground-truth name, the removed offset's length)."""
    m = _match(gt_names, gt_joints, valid, list(estimate), skeleton)
    F = m.gt.shape[0]
    est = np.stack([np.asarray(estimate[n], np.float64)[:F] for n in m.ours], axis=1)
    return _scores(est, m)


# -- the oracle ------------------------------------------------------------------------------

@dataclass(frozen=True)
class OracleFit:
    """Our body fitted to ground-truth joints: alpha (K,), chi (F, D), and the metrics of
    :func:`mismatch_metrics` of its joints (key ``metrics``)."""

    alpha: np.ndarray
    chi: np.ndarray
    metrics: dict


#: the oracle's solvers (:func:`fit_oracle`'s ``method``)
ORACLE_METHODS = ("trust_region", "tracked")


def fit_oracle(body: BodyModel, gt_names: Sequence[str], gt_joints: np.ndarray,
               valid: np.ndarray | None = None, skeleton: str | None = None,
               shape_frames: int = 10, starts: int = 4, shape_bound: float = 3.0,
               seed: int = 0, method: str = "trust_region") -> OracleFit:
    """Fit one shape and per-frame poses of ``body`` to ground-truth joints (F, J, 3) metres.

    Every ground-truth name the skeleton maps to a joint or a landmark of the catalogue is fitted
    (names that map to nothing are left out). Joint limits are bounds, shape coefficients lie
    within +-``shape_bound``.

    ``method="trust_region"`` (the original oracle): bounded trust-region least squares
    (scipy, forward differences):
    1. poses of every frame with the mean shape, from ``starts`` starting points (the rest
       pose and random poses within the limits; the root from a Kabsch fit of the torso),
       keeping each frame's best (a block-diagonal problem, solved for all frames at once);
    2. shape and poses jointly on ``shape_frames`` frames spread over the sequence (dense);
    3. every frame's pose with that shape, from step 1's poses.

    ``method="tracked"`` (what a run's metrics use, :mod:`mocap.eval.run_metrics`; ~100x faster
    on long sequences): the same three steps as retargeting solves them
    (:func:`mocap.clips.retarget.retarget_points`): the ``starts`` starting points on the
    ``shape_frames`` frames only, shape and those poses jointly by Levenberg-Marquardt on the
    analytic Jacobian, then every frame's pose warm-started from the previous frame's (restarted
    from the previous and the rest angles where a point stays over 40 mm off). Its errors equal
    the trust region's within the tolerance stated in tests/clips/test_fit.py.
    """
    if method not in ORACLE_METHODS:
        raise ValueError(f"oracle method {method!r}: one of {', '.join(ORACLE_METHODS)}")
    from mocap.body.catalogue import CATALOGUE
    from mocap.clips.fit import (
        PointFunction,
        fit_poses,
        fit_shape,
        multistart_poses,
        pose_bounds,
        torso_points,
    )

    known = list(dict.fromkeys([*body.joint_names, *CATALOGUE]))
    m = _match(gt_names, gt_joints, valid, known, skeleton)
    if len(m.ours) < 4:
        raise ValueError(f"the oracle needs at least 4 ground-truth joints of the body, got {m.ours}")
    F = m.gt.shape[0]
    if method == "tracked":
        from mocap.clips.retarget import retarget_points

        chi, alpha, est, _ = retarget_points(m.ours, m.gt, body, shape_frames=shape_frames, starts=starts,
                                             shape_bound=shape_bound, seed=seed, valid=m.valid)
        return OracleFit(alpha=alpha, chi=chi, metrics=_scores(est, m))
    fn = PointFunction(body, m.ours)
    w = m.valid.astype(np.float64)[..., None]
    target = np.where(m.valid[..., None], m.gt, 0.0)
    lo_d, hi_d = pose_bounds(body)
    # 1. poses with the mean shape, several starts per frame
    rng = np.random.default_rng(seed)
    alpha = np.zeros(body.num_shape)
    best = multistart_poses(fn, alpha, target, w, m.gt, m.valid, lo_d, hi_d, torso_points(m.ours),
                            starts, rng)
    # 2. shape and poses jointly on a few frames
    sel = np.unique(np.linspace(0, F - 1, min(shape_frames, F)).round().astype(int))
    alpha, _ = fit_shape(fn, target[sel], w[sel], best[sel], lo_d, hi_d, shape_bound)
    # 3. every pose with that shape
    chi, _ = fit_poses(fn, alpha, best, target, w, lo_d, hi_d)
    est = fn(alpha, chi)
    return OracleFit(alpha=alpha, chi=chi, metrics=_scores(est, m))
