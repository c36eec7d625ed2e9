"""A per-person skeleton inside the shape's outline: rest-joint corrections fitted to 3D keypoints.

Our PCA body fitted to a foreign body's surface carries its own skeleton inside that surface
(docs/results/surface.md, "The two-cue hybrid's skeleton"), so one shape cannot meet the
silhouettes' outline and the keypoints' joints at once. As OpenSim / Pose2Sim scale a model's
segments to markers, the skeleton is decoupled from the outline here: corrections delta (J, 3)
to the shape's rest joints (:meth:`mocap.body.model.BodyModel.shaped`, ``joint_offsets``), fitted
to keypoints triangulated over frames with the frames' poses held, the rest mesh untouched.

For fixed pose angles and fixed DOF axes the posed landmarks are AFFINE in the rest joints: each
twist is a rotation about a rest joint q, x -> R x + (I - R) q, and a landmark is its joint's
transform applied to a rest point that is a rest joint, a mean of rest joints or a rest vertex.
So given the poses, delta is a linear least squares (:func:`offset_map` builds the map exactly);
the axes, resolved from the corrected joints, are re-linearised a few times (Gauss-Newton), and
the residuals are weighted by Huber's rule (a keypoint triangulated wrong does not move a joint):

    E(delta) = sum_f sum_l rho(|A_fl delta + b_fl - y_fl|) / noise^2 + |delta|^2 / std^2
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocap.body.dofs import resolve_axes
from mocap.body.kinematics import chain_transforms
from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel


def posed_landmarks(body: BodyModel, landmarks: LandmarkSet, alpha: np.ndarray, chis: np.ndarray,
                    rest_joints: np.ndarray, axes: np.ndarray | None = None,
                    rest_offsets: np.ndarray | None = None) -> np.ndarray:
    """Landmarks (P, L, 3) float64 of poses chis (P, D) on the shape alpha (K,)'s rest mesh with
    rest joints ``rest_joints`` (P, J, 3) (one set per pose); ``axes`` (P, D, 3) or (D, 3) the DOF
    axes (None: resolved from each row's rest joints); ``rest_offsets`` (L, 3): added to the rest
    landmarks (a keypoint cue's learned offsets)."""
    chis = np.atleast_2d(np.asarray(chis, np.float64))
    J = np.asarray(rest_joints, np.float64)
    verts, _ = body.rest(np.asarray(alpha, np.float64))
    verts = np.asarray(verts, np.float64)
    if axes is None:
        axes = resolve_axes(body.dofs, body.joint_names, J)
    G = chain_transforms(body.parents, body.dof_joint, np.asarray(axes, np.float64), J,
                         chis[:, :6], chis[:, 6:])                                   # (P, J, 4, 4)
    rest = np.stack([np.broadcast_to(lm.rest_point(body, J, verts), (len(chis), 3))
                     for lm in landmarks.landmarks], axis=1)                         # (P, L, 3)
    if rest_offsets is not None:
        rest = rest + rest_offsets
    Gl = G[:, landmarks.joint]
    return (Gl[..., :3, :3] @ rest[..., None])[..., 0] + Gl[..., :3, 3]


def offset_map(body: BodyModel, landmarks: LandmarkSet, alpha: np.ndarray, chis: np.ndarray,
               rest_joints: np.ndarray, axes: np.ndarray | None, rest_offsets: np.ndarray | None = None,
               step: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """The map of rest-joint changes to posed landmarks: for poses chis (F, D), rest joints (J, 3)
    and axes (D, 3), A (F, L, 3, 3J) and b (F, L, 3) with landmarks(rest_joints + delta) =
    A vec(delta) + b, each column the difference of two evaluations ``step`` m apart over
    ``step``. With the axes held the map is affine and this is exact; with ``axes`` None (resolved
    from each moved set of joints, as :meth:`~mocap.body.model.BodyModel.shaped` resolves them)
    it is the Jacobian (a small ``step``) of a map that is not."""
    chis = np.atleast_2d(np.asarray(chis, np.float64))
    F, Jn = len(chis), body.num_joints
    base = np.asarray(rest_joints, np.float64)
    moved = np.repeat(base[None], 1 + 3 * Jn, axis=0)
    moved[1:].reshape(3 * Jn, 3 * Jn)[np.arange(3 * Jn), np.arange(3 * Jn)] += step
    pts = posed_landmarks(body, landmarks, alpha, np.repeat(chis, 1 + 3 * Jn, axis=0),
                          np.tile(moved, (F, 1, 1)), axes, rest_offsets)
    pts = pts.reshape(F, 1 + 3 * Jn, len(landmarks), 3)
    b = pts[:, 0]
    A = ((pts[:, 1:] - b[:, None]) / step).transpose(0, 2, 3, 1)                     # (F, L, 3, 3J)
    return A, b


def joint_offsets_of(estimates, joints: int) -> np.ndarray | None:
    """(F, J, 3) the rest-joint corrections of per-frame estimates (their ``joint_offsets``,
    zeros where one has none); None when none has any (every frame posed on the shape's own
    skeleton, as before the corrections existed)."""
    offsets = [getattr(e, "joint_offsets", None) for e in estimates]
    if all(o is None for o in offsets):
        return None
    return np.stack([np.zeros((joints, 3)) if o is None else np.asarray(o, np.float64) for o in offsets])


def frames_by_body(alphas: np.ndarray, joint_offsets: np.ndarray | None, frames: int
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """The frames that share one body: shapes ``alphas`` (K,) for every frame or (F, K) one per
    frame, rest-joint corrections ``joint_offsets`` None, (J, 3) for every frame or (F, J, 3) one
    per frame, ``frames`` F -> [(frame indices (n,), shape (K,) float64, corrections (J, 3) or
    None where they are all zero: the shape's own skeleton, the same body to the bit)], one entry
    per distinct (shape, corrections). A ValueError when a per-frame array has another count."""
    alphas = np.asarray(alphas, np.float64)
    if alphas.ndim == 1:
        alphas = np.repeat(alphas[None], frames, axis=0)
    if len(alphas) != frames:
        raise ValueError(f"{len(alphas)} shapes for {frames} poses")
    K = alphas.shape[1]
    if joint_offsets is None:
        keys, offsets = alphas, None
    else:
        offsets = np.asarray(joint_offsets, np.float64)
        if offsets.ndim == 2:
            offsets = np.repeat(offsets[None], frames, axis=0)
        if len(offsets) != frames:
            raise ValueError(f"{len(offsets)} joint offsets for {frames} poses")
        keys = np.hstack([alphas, offsets.reshape(frames, -1)])
    out = []
    for key in np.unique(keys, axis=0):
        sel = np.flatnonzero((keys == key).all(axis=1))
        d = None if offsets is None or not offsets[sel[0]].any() else offsets[sel[0]]
        out.append((sel, key[:K].copy(), d))
    return out


def marked_joints(body: BodyModel, landmarks: LandmarkSet) -> np.ndarray:
    """(n,) sorted indices of the joints a landmark's rest point is made of (``at`` / ``between``):
    the joints keypoints measure directly. A joint that is only a rotation centre (no landmark on
    it: e.g. the spine) is measured through its children's motion alone, weakly; its correction
    is held at zero."""
    names = {n for lm in landmarks.landmarks for n in ((lm.at,) if lm.at else ()) + tuple(lm.between)}
    return np.array(sorted(body.joint_index(n) for n in names), dtype=np.int64)


@dataclass(frozen=True)
class OffsetFit:
    """delta (J, 3) metres and a report (observations used, RMS residual before and after, mm)."""

    offsets: np.ndarray
    report: dict


def fit_joint_offsets(body: BodyModel, landmarks: LandmarkSet, alpha: np.ndarray, chis: np.ndarray,
                      measured: np.ndarray, std: float, noise: float = 0.015,
                      rest_offsets: np.ndarray | None = None, start: np.ndarray | None = None,
                      iterations: int = 3, huber: float = 2.0) -> OffsetFit:
    """delta (J, 3) minimising the module docstring's E over frames with poses chis (F, D) held and
    landmarks ``measured`` (F, L, 3) world metres (NaN: unmeasured), the shape alpha (K,):
    ``std`` (m) the prior's spread of each offset coordinate (> 0), ``noise`` (m) a keypoint's,
    residuals beyond ``huber`` x noise down-weighted (Huber); ``iterations`` re-linearisations
    about the axes of the corrected joints, from ``start`` (J, 3; None: zero). Only the joints a
    landmark is made of (:func:`marked_joints`) move; the others keep ``start``'s."""
    chis = np.atleast_2d(np.asarray(chis, np.float64))
    y = np.asarray(measured, np.float64)
    if y.shape != (len(chis), len(landmarks), 3):
        raise ValueError(f"joint offsets: measured landmarks have shape {y.shape}, expected "
                         f"({len(chis)}, {len(landmarks)}, 3)")
    if not std > 0:
        raise ValueError(f"joint offsets: the prior's spread must be > 0 m, got {std}")
    Jn = body.num_joints
    _, joints = body.rest(np.asarray(alpha, np.float64))
    joints = np.asarray(joints, np.float64)
    delta = np.zeros((Jn, 3)) if start is None else np.array(start, np.float64)
    seen = np.isfinite(y).all(axis=2)                                                 # (F, L)
    free = (3 * marked_joints(body, landmarks)[:, None] + np.arange(3)).ravel()       # (n,) coordinates
    report = {"observations": int(seen.sum()), "frames": int(len(chis))}
    if not seen.any():
        return OffsetFit(delta, {**report, "rms_before_mm": float("nan"), "rms_after_mm": float("nan")})
    w = np.ones(seen.shape)

    def residuals(d):
        J = joints + d
        x = posed_landmarks(body, landmarks, alpha, chis, np.broadcast_to(J, (len(chis), Jn, 3)),
                            rest_offsets=rest_offsets)
        return np.where(seen[..., None], x - np.nan_to_num(y), 0.0)

    r0 = residuals(delta)
    report["rms_before_mm"] = round(1e3 * float(np.sqrt((r0[seen] ** 2).sum(axis=1).mean())), 2)
    for _ in range(max(iterations, 1)):
        J = joints + delta
        A, b = offset_map(body, landmarks, alpha, chis, J, None, rest_offsets, step=1e-5)
        r = np.where(seen[..., None], b - np.nan_to_num(y), 0.0)                        # at delta
        norm = np.linalg.norm(r, axis=2)
        w = np.where(seen, np.minimum(1.0, huber * noise / np.maximum(norm, 1e-12)), 0.0)
        Aw = A[seen][..., free] * np.sqrt(w[seen])[:, None, None]                      # (N, 3, n)
        rw = r[seen] * np.sqrt(w[seen])[:, None]
        H = np.einsum("nci,ncj->ij", Aw, Aw) / noise**2 + np.eye(len(free)) / std**2
        g = np.einsum("nci,nc->i", Aw, rw) / noise**2 + delta.ravel()[free] / std**2
        step = -np.linalg.solve(H, g)
        flat = delta.ravel().copy()
        flat[free] += step
        delta = flat.reshape(Jn, 3)
        if np.abs(step).max() < 1e-6:
            break
    r1 = residuals(delta)
    report["rms_after_mm"] = round(1e3 * float(np.sqrt((r1[seen] ** 2).sum(axis=1).mean())), 2)
    report["downweighted"] = int((w[seen] < 1).sum())
    report["largest_mm"] = round(1e3 * float(np.linalg.norm(delta, axis=1).max()), 1)
    return OffsetFit(delta, report)
