"""Rigs as pose vectors, and a calibration compared with a reference one after a similarity
alignment (Umeyama 1991: the scale, rotation and translation that best map one set of
camera centres onto the other)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mocap.cameras import Camera, Rig, rodrigues_from_rotation, rotation_from_rodrigues


def rig_from_poses(names: Sequence[str], K: np.ndarray, dist: np.ndarray, sizes: Sequence[tuple[int, int]],
                   cams: np.ndarray) -> Rig:
    """A rig from (C, 6) rvec | t world-to-camera poses and intrinsics K (C, 3, 3), dist (C, 5)."""
    R = rotation_from_rodrigues(cams[:, :3])
    return Rig(tuple(Camera(n, K[i], dist[i], R[i], cams[i, 3:], *sizes[i]) for i, n in enumerate(names)))


def poses_of(rig: Rig) -> np.ndarray:
    """(C, 6) rvec | t of a rig's cameras."""
    return np.concatenate([rodrigues_from_rotation(rig.R), rig.t], axis=1)


def transform_rig(rig: Rig, s: float, R: np.ndarray, t: np.ndarray) -> Rig:
    """The rig in the world frame ``x' = s R x + t`` (cameras move with the world: centres
    c' = s R c + t, rotations R_cam' = R_cam R^T, translations -R_cam' c')."""
    cams = []
    for cam in rig:
        Rc = cam.R @ R.T
        cams.append(cam.replace(R=Rc, t=-Rc @ (s * R @ cam.center + t)))
    return Rig(tuple(cams))


def umeyama(src: np.ndarray, dst: np.ndarray, scale: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R (3, 3), t (3,)) minimising sum |dst - (s R src + t)|^2; src, dst (N, 3), N >= 3."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / (a ** 2).sum(1).mean()) if scale else 1.0
    return s, R, mu_d - s * R @ mu_s


@dataclass(frozen=True)
class RigComparison:
    """Per camera (in the reference's order): centre_error (m) and rotation_error (degrees)
    after the alignment, focal_error (relative, fx and fy mean) and principal_point_error (px);
    scale: the alignment's scale factor (1: the calibration's metres are the reference's)."""

    names: tuple[str, ...]
    centre_error: np.ndarray
    rotation_error: np.ndarray
    focal_error: np.ndarray
    principal_point_error: np.ndarray
    scale: float

    def table(self) -> str:
        rows = ["camera   centre (cm)  rotation (deg)  focal (%)  principal point (px)"]
        for i, n in enumerate(self.names):
            rows.append(f"{n:<8} {100 * self.centre_error[i]:11.2f}  {self.rotation_error[i]:14.3f}  "
                        f"{100 * self.focal_error[i]:9.3f}  {self.principal_point_error[i]:20.1f}")
        rows.append(f"alignment scale {self.scale:.4f}")
        return "\n".join(rows)


def rotation_angle_deg(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (...) angle of the rotation, degrees."""
    c = (np.trace(R, axis1=-2, axis2=-1) - 1) / 2
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def compare_rigs(rig: Rig, reference: Rig, similarity: bool = True, poses: bool = True) -> RigComparison:
    """Align ``rig`` to ``reference`` (cameras matched by name ignoring case and separators,
    else by order; a similarity, or a rigid motion when ``similarity`` is False) and measure
    what differs. The alignment maps the camera centres and, per camera, a point on its
    optical axis at the rig's size from its centre (so that cameras in a row still fix it)."""
    def key(s: str) -> str:
        return "".join(ch for ch in s.lower() if ch.isalnum())
    by_key = {key(n): cam for n, cam in zip(rig.names, rig, strict=True)}
    if all(key(n) in by_key for n in reference.names):
        rig = Rig(tuple(by_key[key(n)] for n in reference.names))
    def anchors(r: Rig) -> np.ndarray:
        size = np.linalg.norm(r.centers - r.centers.mean(0), axis=1).mean()
        return np.concatenate([r.centers, r.centers + size * r.R[:, 2, :]])
    f = (rig.K[:, 0, 0] + rig.K[:, 1, 1]) / (reference.K[:, 0, 0] + reference.K[:, 1, 1]) - 1
    pp = np.linalg.norm(rig.K[:, :2, 2] - reference.K[:, :2, 2], axis=1)
    if not poses:                                   # intrinsics only
        nan = np.full(len(rig), np.nan)
        return RigComparison(reference.names, nan, nan, np.abs(f), pp, float("nan"))
    s, R, t = umeyama(anchors(rig), anchors(reference), scale=similarity)
    aligned = transform_rig(rig, s, R, t)
    centre = np.linalg.norm(aligned.centers - reference.centers, axis=1)
    rot = rotation_angle_deg(aligned.R @ np.swapaxes(reference.R, -1, -2))
    return RigComparison(reference.names, centre, rot, np.abs(f), pp, s)
