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

That test is one-sided: a limb the model has folded inside the torso's silhouette (a forearm
turned the wrong way in front of the chest) has every vertex inside and is never flagged,
while the observed arm beside the body goes unexplained. With ``unexplained`` > 0 the check
also looks at the other side: observed pixels the model's own silhouette does not cover
(the model mask grown by ``tolerance_px`` + 1, the leftover shrunk by one pixel so that the
slivers of a differently shaped body vanish). Each limb chain (a joint with angles whose
parent has none, with its unbranched subtree: an arm from the shoulder, a leg from the hip)
is charged with the leftover pixels whose nearest projected chain vertex is its own (the
trunk is not a candidate: a missing arm beside the body is nearest to the arm's remaining
part). A chain charged with more than ``unexplained`` x the observed silhouette area (summed
over views), above its recent level, is misaligned with all its limbs: the limit is
``unexplained`` + the median of the chain's shares over the last ``unexplained_window`` checks
(0: a fixed limit). Real silhouettes leave pixels that no pose of the body explains (a cast
shadow at the feet, a loose coat) in every frame; a limb that goes wrong shows as a rise above
that level, while a fixed limit fires on every frame. A limb that stays wrong for longer than
half the window becomes the level itself: the search has had that many frames to fix it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import cv2
import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig, project
from mocap.compiled import HAVE_NUMBA, njit
from mocap.energy.silhouette import downscale_masks
from mocap.local.nearest import NearestPoints
from mocap.local.settings import MisalignmentSettings
from mocap.render import get_rasterizer

if HAVE_NUMBA:

    @njit(cache=True)
    def _outside_counts(obs, px, tol, out):
        """out[v] = the number of views with some observed pixel (obs (C, h, w) bool) where
        vertex v's pixel px[c, v] (rounded half to even) is outside the image or farther than
        ``tol`` pixels (a square: the mask dilated by a (2 tol + 1)^2 box, cv2.dilate's border)
        from every observed pixel; returns that number of views."""
        C, h, w = obs.shape
        V = px.shape[1]
        for v in range(V):
            out[v] = 0
        valid = 0
        for c in range(C):
            m = obs[c]
            seen = False
            for r in range(h):
                for j in range(w):
                    if m[r, j]:
                        seen = True
                        break
                if seen:
                    break
            if not seen:
                continue
            valid += 1
            for v in range(V):
                x = np.rint(px[c, v, 0])
                y = np.rint(px[c, v, 1])
                hit = False
                if x >= 0 and x < w and y >= 0 and y < h:
                    u, r = int(x), int(y)
                    for rr in range(max(r - tol, 0), min(r + tol + 1, h)):
                        for uu in range(max(u - tol, 0), min(u + tol + 1, w)):
                            hit |= m[rr, uu]
                out[v] += not hit
        return valid


@dataclass(frozen=True)
class LimbCheck:
    """flagged: (J,) bool per joint's limb; names: flagged limbs; errors: limb -> error;
    unexplained: chain root -> share of the observed area left unexplained and charged to that
    chain (empty when that side is not checked); unexplained_limit: chain root -> the share
    above which it is flagged at this check."""

    flagged: np.ndarray
    names: list[str]
    errors: dict
    unexplained: dict = field(default_factory=dict)
    unexplained_limit: dict = field(default_factory=dict)


def descendants(parents: np.ndarray, joint: int) -> list[int]:
    out, stack = [], [joint]
    while stack:
        j = stack.pop()
        out.append(j)
        stack += [int(k) for k in np.flatnonzero(parents == j)]
    return out


def limb_chains(body: BodyModel) -> list[tuple[int, list[int]]]:
    """(root joint, its limbs) of each limb chain: a joint with angles whose parent has none
    (the root's global twist does not count), whose subtree does not branch."""
    has_dofs = np.zeros(body.num_joints, bool)
    has_dofs[np.unique(body.dof_joint)] = True
    has_vertices = np.zeros(body.num_joints, bool)
    has_vertices[np.unique(body.part_labels)] = True
    chains = []
    for j in range(1, body.num_joints):
        p = body.parents[j]
        if not has_dofs[j] or (p > 0 and has_dofs[p]):
            continue
        sub = descendants(body.parents, j)
        if any(np.count_nonzero(body.parents == k) > 1 for k in sub):
            continue                                           # branches: the trunk, not a limb
        limbs = [k for k in sub if has_vertices[k]]
        if limbs:
            chains.append((j, limbs))
    return chains


_D = MisalignmentSettings()   # the defaults of the keyword arguments


class MisalignmentDetector:
    def __init__(self, body: BodyModel, rig: Rig, threshold: float = _D.threshold,
                 resolution: int = _D.resolution, tolerance_px: int = _D.tolerance_px,
                 scale: float | None = _D.scale, relative: bool = _D.relative,
                 baseline_cap: float = _D.baseline_cap, unexplained: float = _D.unexplained,
                 unexplained_window: int = _D.unexplained_window):
        if scale is None:
            scale = rig.scale_for(resolution)
        self.body, self.threshold, self.scale = body, threshold, scale
        self.relative, self.baseline_cap = relative, baseline_cap
        self.baseline: np.ndarray | None = None
        self.small = rig.scaled(scale)
        self.tolerance = tolerance_px
        self.limbs = [j for j in range(body.num_joints) if np.any(body.part_labels == j)]
        self._limb_vertices = [np.flatnonzero(body.part_labels == j) for j in self.limbs]
        if unexplained < 0:
            raise ValueError(f"unexplained must be >= 0, got {unexplained}")
        if unexplained_window < 0:
            raise ValueError(f"unexplained_window must be >= 0, got {unexplained_window}")
        self.unexplained = float(unexplained)
        self.recent: deque = deque(maxlen=int(unexplained_window))   # past shares (K,); 0 keeps none
        self.chains = limb_chains(body) if unexplained > 0 else []
        self._raster = get_rasterizer(body.faces, body.num_vertices) if unexplained > 0 else None
        self._chain_vertex = np.full(body.num_vertices, -1)       # chain index of each vertex
        for i, (_, limbs) in enumerate(self.chains):
            self._chain_vertex[np.isin(body.part_labels, limbs)] = i

    def _observed(self, vertices: np.ndarray, masks: np.ndarray):
        """What both sides of the check read: the observed masks at the check's scale
        (C, h, w) and the vertices' pixels (C, V, 2) and depths (C, V) there."""
        px, depth = project(self.small, vertices, return_depth=True)
        return downscale_masks(masks, self.scale), px, depth

    def unexplained_share(self, vertices: np.ndarray, masks: np.ndarray) -> dict[int, float]:
        """Chain root -> observed pixels left unexplained by the model's silhouette whose
        nearest projected chain vertex is the chain's, as a share of the observed silhouette
        area (all views)."""
        return self._unexplained(*self._observed(vertices, masks))

    def _unexplained(self, obs: np.ndarray, px: np.ndarray, depth: np.ndarray) -> dict[int, float]:
        C, h, w = obs.shape
        model = self._raster(px, h, w, depth, near=0.05)
        grow = np.ones((2 * self.tolerance + 3,) * 2, np.uint8)
        counts = np.zeros(len(self.chains))
        on_chain = self._chain_vertex >= 0
        for c in range(C):
            left = obs[c] & ~(cv2.dilate(model[c].astype(np.uint8), grow) > 0)
            left = cv2.erode(left.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
            ys, xs = np.nonzero(left)
            front = on_chain & (depth[c] > 0.05)
            if len(xs) == 0 or not front.any():
                continue
            _, nearest = NearestPoints(px[c, front]).query(np.stack([xs, ys], 1).astype(np.float64))
            counts += np.bincount(self._chain_vertex[front][nearest], minlength=len(self.chains))
        area = max(int(obs.sum()), 1)
        return {j: float(n / area) for (j, _), n in zip(self.chains, counts, strict=True)}

    def limb_errors(self, vertices: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """(J,) share of each limb's vertices outside the observed silhouettes (NaN: no vertex)."""
        obs, px, _ = self._observed(vertices, masks)
        return self._limb_errors(obs, px)

    def _limb_errors(self, obs: np.ndarray, px: np.ndarray) -> np.ndarray:
        if HAVE_NUMBA:    # the same counts in one pass, without the dilated masks (tested)
            count = np.empty(px.shape[1], np.int64)
            valid = _outside_counts(np.ascontiguousarray(obs, bool), np.ascontiguousarray(px, np.float64),
                                    int(self.tolerance), count)
            outside = count / np.float64(valid)           # = the mean of 0 / 1 over the views
            err = np.full(self.body.num_joints, np.nan)
            for j, ids in zip(self.limbs, self._limb_vertices, strict=True):
                err[j] = outside[ids].mean()
            return err
        if self.tolerance:
            k = np.ones((2 * self.tolerance + 1,) * 2, np.uint8)
            obs = np.stack([cv2.dilate(o.astype(np.uint8), k) > 0 for o in obs])
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
        """vertices (V, 3) posed, masks (C, H, W) observed."""
        observed = self._observed(vertices, masks)
        err = self._limb_errors(*observed[:2])
        if self.relative and self.baseline is None:
            self.baseline = np.minimum(np.nan_to_num(err), self.baseline_cap)
        base = self.baseline if self.relative else 0.0
        flagged = np.zeros(self.body.num_joints, bool)
        for j in np.flatnonzero(err - base > self.threshold):
            flagged[descendants(self.body.parents, int(j))] = True
        share = self._unexplained(*observed) if self.chains else {}
        limit = self.unexplained_limits()
        for (j, limbs), lim in zip(self.chains, limit, strict=True):
            if share[j] > lim:
                flagged[limbs] = True
        if self.chains:
            self.recent.append(np.array([share[j] for j, _ in self.chains]))
        names = [self.body.joint_names[j] for j in np.flatnonzero(flagged)]
        chain_names = [self.body.joint_names[j] for j, _ in self.chains]
        return LimbCheck(flagged, names, {self.body.joint_names[j]: float(err[j]) for j in self.limbs},
                         {self.body.joint_names[j]: v for j, v in share.items()},
                         dict(zip(chain_names, map(float, limit), strict=True)))

    def unexplained_limits(self) -> np.ndarray:
        """(K,) the share above which each chain is flagged at the next check: ``unexplained``
        plus the median of its last ``unexplained_window`` shares (none yet: ``unexplained``)."""
        level = np.median(np.stack(self.recent), axis=0) if self.recent else 0.0
        return self.unexplained + np.zeros(len(self.chains)) + level

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
