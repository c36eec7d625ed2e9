"""Per-limb misalignment detection (Zhang et al. 2013, end of Sec. 4.1).

A limb's error is the share of its vertices that project outside the observed silhouette
(dilated by ``tolerance_px`` at the check's resolution), averaged over the views. A limb
above ``threshold`` is misaligned, and so is every limb after it in the kinematic chain.
Under model mismatch a limb of the right pose still has vertices outside (a body fitted by
another model is thicker here, thinner there), so with ``relative`` (the default) the first
check sets each limb's baseline error, at most ``baseline_cap`` (a limb already far off at
the first check stays detectable), and a limb is misaligned when its error exceeds the
baseline by ``threshold`` (the paper's absolute test when ``relative=False``).
The check runs at ``resolution`` px on the images' longest side (an absolute size, so that a
forearm covers the same few pixels whatever the cameras' resolution; ``scale`` relative to the
cameras instead, if given).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig, project
from mocap.energy.silhouette import downscale_masks


@dataclass(frozen=True)
class LimbCheck:
    """flagged: (J,) bool per joint's limb; names: flagged limbs; errors: limb -> error."""

    flagged: np.ndarray
    names: list[str]
    errors: dict


def descendants(parents: np.ndarray, joint: int) -> list[int]:
    out, stack = [], [joint]
    while stack:
        j = stack.pop()
        out.append(j)
        stack += [int(k) for k in np.flatnonzero(parents == j)]
    return out


class MisalignmentDetector:
    def __init__(self, body: BodyModel, rig: Rig, threshold: float = 0.15, resolution: int = 256,
                 tolerance_px: int = 1, scale: float | None = None, relative: bool = True,
                 baseline_cap: float = 0.15):
        if scale is None:
            scale = min(1.0, resolution / float(np.max(rig.sizes)))
        self.body, self.threshold, self.scale = body, threshold, scale
        self.relative, self.baseline_cap = relative, baseline_cap
        self.baseline: np.ndarray | None = None
        self.small = rig.scaled(scale)
        self.tolerance = tolerance_px
        self.limbs = [j for j in range(body.num_joints) if np.any(body.part_labels == j)]

    def limb_errors(self, vertices: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """(J,) share of each limb's vertices outside the observed silhouettes (NaN: no vertex)."""
        obs = downscale_masks(masks, self.scale)
        if self.tolerance:
            k = np.ones((2 * self.tolerance + 1,) * 2, np.uint8)
            obs = np.stack([cv2.dilate(o.astype(np.uint8), k) > 0 for o in obs])
        px = project(self.small, vertices)                          # (C, V, 2)
        C, h, w = obs.shape
        u, v = np.round(px[..., 0]).astype(int), np.round(px[..., 1]).astype(int)
        inside_img = (u >= 0) & (u < w) & (v >= 0) & (v < h)
        hit = np.zeros(u.shape, bool)
        for c in range(C):
            ok = inside_img[c]
            hit[c, ok] = obs[c, v[c, ok], u[c, ok]]
        valid_views = obs.reshape(C, -1).any(axis=1)
        outside = (~hit[valid_views]).mean(axis=0)                  # (V,) averaged over views
        err = np.full(self.body.num_joints, np.nan)
        for j in self.limbs:
            err[j] = outside[self.body.part_labels == j].mean()
        return err

    def __call__(self, vertices: np.ndarray, masks: np.ndarray) -> LimbCheck:
        err = self.limb_errors(vertices, masks)
        if self.relative and self.baseline is None:
            self.baseline = np.minimum(np.nan_to_num(err), self.baseline_cap)
        base = self.baseline if self.relative else 0.0
        flagged = np.zeros(self.body.num_joints, bool)
        for j in np.flatnonzero(err - base > self.threshold):
            flagged[descendants(self.body.parents, int(j))] = True
        names = [self.body.joint_names[j] for j in np.flatnonzero(flagged)]
        return LimbCheck(flagged, names, {self.body.joint_names[j]: float(err[j]) for j in self.limbs})

    def free_dofs(self, check: LimbCheck) -> np.ndarray:
        """(D,) bool: the DOFs a global search over the misaligned limbs varies: those of each
        flagged limb's joint and of its parent joint (the limb's own placement), and the global
        twist when the root limb itself is flagged."""
        body = self.body
        joints = set()
        for j in np.flatnonzero(check.flagged):
            joints.add(int(j))
            if body.parents[j] >= 0:
                joints.add(int(body.parents[j]))
        free = np.zeros(body.num_dofs, bool)
        free[6:] = np.isin(body.dof_joint, list(joints))
        if check.flagged[0]:
            free[:6] = True
        return free
