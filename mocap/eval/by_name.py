"""Scoring against ground-truth joints matched by NAME, in any skeleton.

Ground truth is (F, J, 3) points with J names (and optionally an (F, J) validity mask). Each
ground-truth name maps to one of the estimate's named points: mocap's joints or, where a
skeleton marks a point no joint sits at (top of the head, toes, the base of the neck, the
centre of the head), a landmark of the catalogue (:mod:`mocap.body.catalogue`).
The mappings of common skeletons are :data:`mocap.body.skeletons.SKELETONS`; names of mocap's own skeleton map
to themselves. Points of a skeleton that mocap does not model (eyes,
ears, nose, heels) map to ``None`` and are left out of the scores (listed in ``unscored``).

Metrics (mm):
- ``mpjpe_mm``: mean over frames of the mean error of the valid scored joints (raw, world);
- ``mpjpe_root_aligned_mm``: the same after subtracting each skeleton's root (the pelvis, or
  the mid-point of the hips when there is no pelvis) from both, per frame;
- ``per_joint_mm`` (ground-truth names), ``per_frame_mm``;
- ``pcp``: Percentage of Correct Parts, Shelf/Campus protocol (Belagiannis et al. 2014): a limb
  is correct in a frame when the mean of its two endpoint errors is at most half the
  ground-truth limb length. Limbs (mocap names): head (neck-head_top), torso (pelvis-neck),
  upper/lower arms, upper/lower legs; a limb counts only where both ends are scored and valid.
  ``pcp_per_limb`` gives each limb's share, ``pcp`` the mean over all limb instances.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mocap.body.skeletons import SKELETONS, JointNameError, resolve_mapping

PCP_LIMBS = {"head": ("neck", "head_top"), "torso": ("pelvis", "neck"),
             "l_upper_arm": ("l_shoulder", "l_elbow"), "r_upper_arm": ("r_shoulder", "r_elbow"),
             "l_lower_arm": ("l_elbow", "l_wrist"), "r_lower_arm": ("r_elbow", "r_wrist"),
             "l_upper_leg": ("l_hip", "l_knee"), "r_upper_leg": ("r_hip", "r_knee"),
             "l_lower_leg": ("l_knee", "l_ankle"), "r_lower_leg": ("r_knee", "r_ankle")}


def _root(points: Mapping[str, np.ndarray]) -> np.ndarray | None:
    if "pelvis" in points:
        return points["pelvis"]
    if "l_hip" in points and "r_hip" in points:
        return 0.5 * (points["l_hip"] + points["r_hip"])
    return None


def score_by_name(estimate: Mapping[str, np.ndarray], gt_names: Sequence[str], gt_joints: np.ndarray,
                  valid: np.ndarray | None = None, skeleton: str | None = None,
                  only: Sequence[str] | None = None, required: Sequence[str] = ()) -> dict:
    """estimate: name -> (F, 3) metres (joints and landmarks); gt_joints: (F, J, 3) metres with
    ``gt_names``; valid: (F, J) bool (None: all valid; non-finite ground truth is invalid too).
    ``only``: score just these ground-truth names (e.g. the 15 HumanEva evaluation joints of
    mocap's own skeleton). Returns the metrics of the module docstring plus ``scored`` and
    ``unscored`` (names)."""
    gt_joints = np.asarray(gt_joints, np.float64)
    F, J = gt_joints.shape[:2]
    if gt_joints.shape != (F, len(gt_names), 3):
        raise JointNameError(f"ground-truth joints {gt_joints.shape} do not match "
                             f"{len(gt_names)} names")
    mapping = resolve_mapping(gt_names, list(estimate), skeleton, required)
    ok = np.isfinite(gt_joints).all(axis=-1)
    if valid is not None:
        valid = np.asarray(valid, bool)
        if valid.shape != (F, J):
            raise JointNameError(f"validity mask {valid.shape} does not match ground truth ({F}, {J})")
        ok &= valid
    scored = [n for n in gt_names if mapping[n] is not None and (only is None or n in only)]
    unscored = [n for n in gt_names if n not in scored]
    if not scored:
        raise JointNameError("no ground-truth joint has a counterpart in the estimate")
    idx = [list(gt_names).index(n) for n in scored]
    gt = gt_joints[:, idx]
    est = np.stack([np.asarray(estimate[mapping[n]], np.float64)[:F] for n in scored], axis=1)
    if est.shape != gt.shape:
        raise JointNameError(f"estimate has {est.shape[0]} frames, ground truth {F}")
    m = ok[:, idx]
    err = np.where(m, 1e3 * np.linalg.norm(est - gt, axis=-1), np.nan)
    with np.errstate(invalid="ignore"):
        per_frame = np.nanmean(np.where(m.any(axis=1, keepdims=True), err, 0.0), axis=1)
    per_frame[~m.any(axis=1)] = np.nan
    out = {"mpjpe_mm": float(np.nanmean(per_frame)), "mpjpe_std_mm": float(np.nanstd(per_frame)),
           "per_joint_mm": {n: float(np.nanmean(err[:, k])) if m[:, k].any() else float("nan")
                            for k, n in enumerate(scored)},
           "per_frame_mm": [float(e) for e in per_frame], "scored": scored, "unscored": unscored}
    by_ours = {mapping[n]: (gt[:, k], est[:, k], m[:, k]) for k, n in enumerate(scored)}
    g_root = _root({k: v[0] for k, v in by_ours.items()})
    e_root = _root({k: v[1] for k, v in by_ours.items()})
    root_ok = _root({k: v[2].astype(float) for k, v in by_ours.items()})
    if g_root is not None:
        rm = m & (root_ok[:, None] > 0.99)
        diff = (est - e_root[:, None]) - (gt - g_root[:, None])
        aligned = np.where(rm, 1e3 * np.linalg.norm(diff, axis=-1), np.nan)
        with np.errstate(invalid="ignore"):
            out["mpjpe_root_aligned_mm"] = float(np.nanmean(np.nanmean(aligned, axis=1)))
    correct, per_limb = [], {}
    for limb, (a, b) in PCP_LIMBS.items():
        if a not in by_ours or b not in by_ours:
            continue
        (ga, ea, ma), (gb, eb, mb) = by_ours[a], by_ours[b]
        both = ma & mb
        if not both.any():
            continue
        mean_err = 0.5 * (np.linalg.norm(ea - ga, axis=-1) + np.linalg.norm(eb - gb, axis=-1))
        hit = (mean_err <= 0.5 * np.linalg.norm(ga - gb, axis=-1))[both]
        per_limb[limb] = float(hit.mean())
        correct.append(hit)
    if correct:
        out["pcp"] = float(np.concatenate(correct).mean())
        out["pcp_per_limb"] = per_limb
    return out


def estimate_points(joint_names: Sequence[str], joints: np.ndarray,
                    landmark_names: Sequence[str] = (), landmarks: np.ndarray | None = None) -> dict:
    """name -> (F, 3) from joints (F, J, 3) and landmarks (F, L, 3); joints win a shared name."""
    pts = {}
    if landmarks is not None:
        pts.update({n: landmarks[:, i] for i, n in enumerate(landmark_names)})
    pts.update({n: joints[:, i] for i, n in enumerate(joint_names)})
    return pts


def check_ground_truth(gt, body) -> None:
    """A ground truth's pose part fits ``body``: chi of the body's width, DOF names equal."""
    if gt.chi is None:
        return
    chi = np.asarray(gt.chi)
    if chi.ndim != 2 or chi.shape[1] != body.num_dofs:
        raise ValueError(f"ground-truth chi is {chi.shape}, but body {body.name!r} has {body.num_dofs} "
                         f"DOFs: it was made for another body (ground truth body {gt.body!r}); "
                         "score it by joint names instead (leave chi out of gt.npz)")
    if gt.dof_names and tuple(gt.dof_names) != tuple(body.dof_names):
        diff = [f"{a}≠{b}" for a, b in zip(gt.dof_names, body.dof_names, strict=False) if a != b][:5]
        raise ValueError(f"ground-truth dof_names differ from body {body.name!r}'s: {', '.join(diff)}")


class NameScorer:
    """Scores a body's poses against a ground truth by joint names (see the module docstring).
    mocap's own names: the 15 HumanEva evaluation joints (``mocap.eval.metrics.EVAL_JOINTS``)."""

    def __init__(self, body, gt):
        from mocap.body.catalogue import landmarks_with
        from mocap.eval.metrics import EVAL_JOINTS

        check_ground_truth(gt, body)
        self.body, self.gt = body, gt
        targets = SKELETONS[gt.skeleton].values() if gt.skeleton in SKELETONS else gt.joint_names
        self.landmarks = landmarks_with(body, list(targets))
        own = not gt.skeleton
        self.kwargs = {"skeleton": gt.skeleton or None, "only": EVAL_JOINTS if own else None,
                       "required": EVAL_JOINTS if own else ()}
        known = list(dict.fromkeys([*body.joint_names, *self.landmarks.names]))
        self.mapping = resolve_mapping(gt.joint_names, known, self.kwargs["skeleton"],
                                       self.kwargs["required"])

    def points(self, shaped, chis: np.ndarray) -> dict:
        chis = np.atleast_2d(chis)
        return estimate_points(self.body.joint_names, shaped.joints(chis), self.landmarks.names,
                               self.landmarks.positions(shaped, chis))

    def points_by_shape(self, alphas: np.ndarray, chis: np.ndarray, joint_offsets: np.ndarray | None = None
                        ) -> dict:
        """:meth:`points` of poses chis (F, D) with shapes alphas (K,) or one per frame (F, K) and
        rest-joint corrections ``joint_offsets`` (None, (J, 3) or (F, J, 3))."""
        from mocap.eval.estimates import per_shape

        J = self.body.num_joints
        both = per_shape(self.body, alphas, chis, lambda shaped, c: np.concatenate(
            [shaped.joints(c), self.landmarks.positions(shaped, c)], axis=1), joint_offsets)
        return estimate_points(self.body.joint_names, both[:, :J], self.landmarks.names, both[:, J:])

    def metrics(self, shaped, chis: np.ndarray, start: int = 0) -> dict:
        """Metrics of poses chis (F, D) against ground-truth frames start..start+F-1."""
        return self.score(self.points(shaped, chis), start)

    def score(self, points: dict, start: int = 0) -> dict:
        """Metrics of named points (name -> (F, 3)) against ground-truth frames start..start+F-1."""
        F = len(next(iter(points.values())))
        valid = None if self.gt.joint_valid is None else self.gt.joint_valid[start:start + F]
        return score_by_name(points, self.gt.joint_names, self.gt.joints[start:start + F], valid,
                             **self.kwargs)

    def truth_in_body_order(self, f: int) -> np.ndarray | None:
        """Ground-truth joints of frame f in the body's joint order (None unless the ground truth
        names every body joint), e.g. to draw its skeleton."""
        names = list(self.gt.joint_names)
        if not set(self.body.joint_names) <= set(names):
            return None
        return np.asarray(self.gt.joints[f])[[names.index(n) for n in self.body.joint_names]]
