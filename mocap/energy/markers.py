"""The marker likelihood of Canton-Ferrer et al. 2010 (Sec. 3.3-3.4), batched over particles.

Per frame, the 2D detections are arranged per landmark and view (:func:`arrange_detections`:
a labelled detection is a candidate for its landmark, an unlabelled one for every landmark;
several candidates per landmark and view are allowed: false positives, other people).
For a batch of particles with landmarks X: (P, L, 3):

1. Every landmark is projected into every view: u: (P, L, C, 2) undistorted pixels.
2. Outlier thresholding (Sec. 3.3): in each view the candidate nearest to u within the gate
   tau (pixels) is kept, z: (P, L, C, 2); farther ones are dismissed.
3. Each kept measurement z_a is scored by the generalised symmetric epipolar distance
   (:mod:`mocap.energy.epipolar`) of the point set {z_a} + {u_b, b = 1..C}, i.e. the
   measurement against the hypothesis's own projections, which are exact correspondences:
   the pairs (z_a, u_b), b != a, contribute d_sym(z_a, u_b)^2 / 2 (the mean of
   d(u_b, F_ab z_a)^2 and d(z_a, F_ab^T u_b)^2), and the same-view pair (z_a, u_a), where two
   points correspond only if they coincide, contributes |z_a - u_a|^2::

       c_a = 1/2 |z_a - u_a|^2 + 1/2 mean_{b != a} d_sym(z_a, u_b)^2 / 2       (pixels^2)

   It is zero only if the landmark lies on the ray of z_a; with measurements in several views
   only at their common point. The cost of a view is min(c_a, tau^2); a view without a kept
   measurement (missed, occluded, or gated out) costs tau^2, so outliers cost no more than a
   miss (a truncated quadratic). With ``use_confidence`` the kept measurement's detector
   confidence w in [0, 1] makes it a mixture of a good detection and an uninformative one:
   w min(c_a, tau^2) + (1 - w) tau^2 (a confidence-1 detection as before, a confidence-0
   one as a miss).
4. Occlusion management (Sec. 3.4): landmarks with candidates in fewer than ``min_views``
   views around their predicted position are "weak". Their neighbours constrain them
   through the kinematic chain; temporal coherence adds one virtual view per weak landmark,
   tau^2 min(1, |X_l - X^_l|^2 / r^2), pulling it towards its predicted position X^_l.

The energy of a particle is the mean of these costs over landmarks x views (pixels^2),
plus the coherence terms over the same count.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.kinematics import chain_transforms
from mocap.body.landmarks import LandmarkSet
from mocap.body.model import ShapedBody
from mocap.cameras import Rig, fundamental_matrices, undistort_points
from mocap.data.sequence import Detections
from mocap.energy.fallback import warn_once
from mocap.energy.marker_likelihood import MarkerLikelihood  # noqa: F401  (re-exported: its settings)

try:                                    # the compiled kernels need numba; numpy is the fallback
    from mocap.energy.marker_kernel import (
        landmark_points,
        nearest_candidates,
        project_points,
        view_costs_fused,
    )
    HAVE_NUMBA = True
except ImportError:                     # pragma: no cover - exercised by monkeypatching HAVE_NUMBA
    landmark_points = nearest_candidates = project_points = view_costs_fused = None
    HAVE_NUMBA = False



def compiled_available() -> bool:
    """True when the compiled marker kernels can be used; warns once when they cannot."""
    if HAVE_NUMBA:
        return True
    warn_once("markers", "the marker likelihood runs on the slower numpy reference (same energies)")
    return False


@dataclass(frozen=True)
class MarkerObservation:
    """One frame's detections per landmark and view, padded to K candidates.

    xy: (L, C, K, 2) undistorted pixels; valid: (L, C, K) bool; confidence: (L, C, K).
    """

    xy: np.ndarray
    valid: np.ndarray
    confidence: np.ndarray

    @property
    def num_candidates(self) -> int:
        return self.xy.shape[2]

    def views_with_candidates(self) -> np.ndarray:
        """(L,) number of views holding at least one candidate."""
        return self.valid.any(axis=2).sum(axis=1)


def arrange_detections(det: Detections, landmark_names: Sequence[str], rig: Rig,
                       min_confidence: float = 0.0,
                       views: Sequence[Rig] | None = None) -> MarkerObservation:
    """Arrange one frame's detections (all rows of ``det`` are used) for the likelihood.

    A labelled detection goes to the landmark of the same name (labels the tracker does not
    fit are dropped); an unlabelled one (label -1) to every landmark. Detections below
    ``min_confidence`` are dropped. Distortion is removed with the rig's model, view by view
    (``views``: :func:`~mocap.cameras.view_rigs` of ``rig``, built once by a caller that arranges every
    frame; the same numbers as undistorting with ``rig[c]``).
    """
    names = list(landmark_names)
    L, C = len(names), len(rig)
    index = {n: i for i, n in enumerate(names)}
    to_landmark = np.array([index.get(n, -2) for n in det.labels] + [-1], dtype=np.int64)
    keep = det.confidence >= min_confidence
    lab = to_landmark[np.where(det.label >= 0, det.label, len(det.labels))][keep]
    view, xy, conf = det.view[keep], np.asarray(det.xy, np.float64)[keep], det.confidence[keep]
    if np.any((view < 0) | (view >= C)):
        raise ValueError(f"detections: view index out of range for a rig of {C} views")
    labelled = lab >= 0
    unl = np.flatnonzero(lab == -1)
    rows_l = np.concatenate([lab[labelled], np.repeat(np.arange(L), len(unl))])
    rows = np.concatenate([np.flatnonzero(labelled), np.tile(unl, L)])
    if len(rows) and not np.any(rig.dist):
        undist = _through_pinhole(rig, view, xy)
    elif len(rows):
        undist = np.empty_like(xy)
        for c in range(C):          # C small: undistort per view
            sel = view == c
            if sel.any():
                if views is None:
                    undist[sel] = undistort_points(rig[c], xy[sel])
                else:
                    undist[sel] = undistort_points(views[c], xy[sel][None])[0]
    else:
        undist = xy
    key = rows_l * C + view[rows]
    order = np.argsort(key, kind="stable")
    key, rows, rows_l = key[order], rows[order], rows_l[order]
    counts = np.bincount(key, minlength=L * C)
    K = max(1, int(counts.max()) if len(counts) else 1)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rank = np.arange(len(key)) - start[key]
    out_xy = np.zeros((L, C, K, 2))
    valid = np.zeros((L, C, K), bool)
    out_conf = np.zeros((L, C, K))
    li, ci = rows_l, view[rows]
    out_xy[li, ci, rank] = undist[rows]
    valid[li, ci, rank] = True
    out_conf[li, ci, rank] = conf[rows]
    return MarkerObservation(out_xy, valid, out_conf)


def _through_pinhole(rig: Rig, view: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """:func:`~mocap.cameras.undistort_points` of pixels xy (N, 2) seen in views ``view`` (N,)
    of a rig without distortion, all rows at once: its arithmetic (pixels to normalised
    coordinates and back) elementwise, so the same numbers as undistorting view by view."""
    K = rig.K[view]
    fx, s, cx, fy, cy = K[:, 0, 0], K[:, 0, 1], K[:, 0, 2], K[:, 1, 1], K[:, 1, 2]
    y = (xy[:, 1] - cy) / fy
    x = (xy[:, 0] - cx - s * y) / fx
    return np.stack([fx * x + s * y + cx, fy * y + cy], axis=-1)


def pinhole_project(rig: Rig, points: np.ndarray,
                    compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted projection of points (..., L, 3) world metres into all views:
    pixels (..., L, C, 2) and depth (..., L, C) metres.

    float64 points are projected by the compiled kernel when numba is there (``compiled``
    None or True; :func:`mocap.energy.marker_kernel.project_points`, the compiled
    likelihood's own projection, equal to this numpy one to rounding); ``compiled=False``
    and other dtypes run numpy."""
    points = np.asarray(points)
    if (compiled is None or compiled) and HAVE_NUMBA and points.dtype == np.float64 and points.ndim >= 2:
        lead = points.shape[:-2]
        X = np.ascontiguousarray(points.reshape((-1,) + points.shape[-2:]))
        C = len(rig)
        u = np.empty(X.shape[:2] + (C, 2))
        z = np.empty(X.shape[:2] + (C,))
        project_points(X, np.ascontiguousarray(rig.R, np.float64), np.ascontiguousarray(rig.t, np.float64),
                       np.ascontiguousarray(rig.K, np.float64), u, z)
        return u.reshape(lead + u.shape[1:]), z.reshape(lead + z.shape[1:])
    dtype = np.result_type(points.dtype, np.float32)
    R, t, K = (np.asarray(a, dtype) for a in (rig.R, rig.t, rig.K))       # no copy when float64
    X = np.einsum("cij,...lj->...lci", R, points) + t
    z = X[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = X[..., 0] / z, X[..., 1] / z
    u = K[:, 0, 0] * x + K[:, 0, 1] * y + K[:, 0, 2]
    v = K[:, 1, 1] * y + K[:, 1, 2]
    return np.stack([u, v], axis=-1), z


@dataclass(frozen=True)
class EpipolarTables:
    """Particle-independent parts of the symmetric epipolar distance for one frame.

    lines: (L * C * K, C, 3) the epipolar line F_ab z~_a in every view b of every candidate
    z_a (row (l * C + a) * K + k), scaled to a unit normal so that a point's distance to it
    is one dot product; zero rows for b == a and for empty candidate slots.
    epipoles: (C, C, 3) homogeneous epipole of camera b in view a (the image of b's centre),
    unit norm.
    """

    lines: np.ndarray
    epipoles: np.ndarray

    @staticmethod
    def build(obs: MarkerObservation, rig: Rig, F: np.ndarray) -> EpipolarTables:
        L, C, K, _ = obs.xy.shape
        zh = np.concatenate([obs.xy, np.ones_like(obs.xy[..., :1])], axis=-1)     # (L, C, K, 3)
        lines = np.einsum("abij,lakj->lakbi", F, zh)                              # (L, C, K, C, 3)
        norm = np.hypot(lines[..., 0], lines[..., 1])
        ok = (norm > 0) & obs.valid[..., None]
        lines = np.where(ok[..., None], lines / np.where(ok, norm, 1.0)[..., None], 0.0)
        centers = np.concatenate([rig.centers, np.ones((C, 1))], axis=1)            # (C, 4)
        epipoles = np.einsum("aij,bj->abi", rig.P, centers)
        epipoles[np.arange(C), np.arange(C)] = 0.0            # a camera has no epipole of itself
        norm = np.linalg.norm(epipoles, axis=-1, keepdims=True)
        epipoles = epipoles / np.where(norm > 0, norm, 1.0)
        return EpipolarTables(lines.reshape(L * C * K, C, 3), epipoles)

    def astype(self, dtype) -> EpipolarTables:
        return EpipolarTables(self.lines.astype(dtype), self.epipoles.astype(dtype))


def view_costs(u: np.ndarray, front: np.ndarray, obs: MarkerObservation, tables: EpipolarTables,
               gate_px: float, use_confidence: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Per-view costs of the module docstring.

    u: (P, L, C, 2) projections; front: (P, L, C) bool, in front of the camera.
    Returns cost: (P, L, C) pixels^2 in [0, tau^2], and kept: (P, L, C) bool (a measurement
    passed the gate).

    The two halves of d_sym(z_a, u_b)^2 are computed as: d(u_b, F_ab z~_a), a dot product
    with the precomputed line of the candidate; d(z_a, F_ab^T u~_b), the distance of z_a from
    the line through u_a and the epipole e_ab (u_a and u_b are projections of one 3D point,
    so the epipolar line of u_b in view a passes through u_a).
    """
    tau2 = float(gate_px) ** 2
    P, L, C, _ = u.shape
    K = obs.num_candidates
    ux, uy = u[..., 0], u[..., 1]                                     # (P, L, C)
    dx = obs.xy[None, ..., 0] - ux[..., None]                          # (P, L, C, K): z - u
    dy = obs.xy[None, ..., 1] - uy[..., None]
    d2 = dx * dx
    d2 += dy * dy
    d2 += np.where(obs.valid, 0.0, np.inf).astype(d2.dtype)           # (L, C, K): empty slots never win
    if K == 1:
        k = np.zeros((P, L, C), np.int64)
        r2, dx, dy = d2[..., 0], dx[..., 0], dy[..., 0]
    else:
        k = np.argmin(d2, axis=3)
        flat = np.arange(P * L * C).reshape(P, L, C) * K + k
        r2, dx, dy = d2.reshape(-1)[flat], dx.reshape(-1)[flat], dy.reshape(-1)[flat]
    kept = (r2 < tau2) & front
    rows = (np.arange(L)[:, None] * C + np.arange(C)) * K + k                 # (P, L, C)
    line = tables.lines[rows]                                         # (P, L, a, b, 3)
    ub_x, ub_y = ux[..., None, :], uy[..., None, :]
    d_b = line[..., 0] * ub_x + line[..., 1] * ub_y + line[..., 2]     # (P, L, a, b); 0 for a == b
    e = tables.epipoles                                               # (a, b, 3); 0 for a == b
    wx = e[..., 2] * ux[..., :, None] - e[..., 0]                      # direction u_a - e_ab
    wy = e[..., 2] * uy[..., :, None] - e[..., 1]
    cross = dx[..., None] * wy - dy[..., None] * wx
    sym = d_b * d_b + cross * cross / (wx * wx + wy * wy + 1e-12)       # 0 for a == b
    if front.all():                                                   # the usual case
        epi, n = sym.sum(axis=-1), C - 1
    else:
        frontf = front.astype(u.dtype)
        epi = (sym * frontf[..., None, :]).sum(axis=-1)               # sum over b != a in front
        n = np.maximum(frontf.sum(axis=-1, keepdims=True) - frontf, 1)    # views b != a in front
    c = 0.5 * r2 + 0.25 * epi / n                                     # 1/2 r^2 + 1/2 mean d_sym^2 / 2
    cost = np.where(kept & np.isfinite(c), np.minimum(c, tau2), tau2)
    if use_confidence:
        w = np.clip(obs.confidence, 0.0, 1.0).astype(cost.dtype)[np.arange(L)[:, None], np.arange(C), k]
        cost = np.where(kept, w * cost + (1 - w) * tau2, cost)
    return cost, kept


class MarkerEnergy:
    """E(chi): (P, D) -> (P,) pixels^2, for one frame (see the module docstring).

    landmarks/shaped: the fitted landmark set and body; rig: the cameras, projected without
    distortion (obs holds undistorted pixels); obs: this frame's arranged detections;
    F: (C, C, 3, 3) the rig's fundamental matrices (computed when None); predicted: (L, 3)
    predicted landmark positions (for coherence); weak: (L,) bool landmarks that get the
    coherence term; rest_points: (L, 3) the landmarks' rest points of ``shaped`` when the
    caller keeps them (None: computed). Forward kinematics and view costs run in the compiled kernels of
    :mod:`mocap.energy.marker_kernel` (float64); ``compiled=False``, or a machine without
    numba (said once, as a warning), uses the numpy reference (:func:`view_costs`, in the
    body's dtype).
    """

    def __init__(self, landmarks: LandmarkSet, shaped: ShapedBody, rig: Rig, obs: MarkerObservation,
                 settings: MarkerLikelihood, F: np.ndarray | None = None,
                 predicted: np.ndarray | None = None, weak: np.ndarray | None = None,
                 compiled: bool | None = None, rest_offsets: np.ndarray | None = None,
                 rest_points: np.ndarray | None = None):
        self.landmarks, self.shaped, self.rig, self.obs, self.settings = landmarks, shaped, rig, obs, settings
        self.F = fundamental_matrices(rig) if F is None else F
        self.compiled = (settings.compiled if compiled is None else compiled) and compiled_available()
        tables = EpipolarTables.build(obs, rig, self.F)
        L, C, K, _ = obs.xy.shape
        rest = self._rest_points(landmarks, shaped, rest_offsets, rest_points)     # once (float64)
        if self.compiled:
            self.tables = tables
            self.obs_cast = obs
            self._lines = np.ascontiguousarray(tables.lines.reshape(L, C, K, C, 3))
            self._weight = (np.ascontiguousarray(np.clip(obs.confidence, 0.0, 1.0), np.float64)
                            if settings.use_confidence else np.ones(obs.valid.shape))
            self._cams = (np.ascontiguousarray(rig.R, np.float64), np.ascontiguousarray(rig.t, np.float64),
                          np.ascontiguousarray(rig.K, np.float64))
            m = landmarks.model
            self._fk = (np.asarray(m.parents, np.int64), np.asarray(m.dof_joint, np.int64),
                        np.ascontiguousarray(shaped.axes, np.float64),
                        np.ascontiguousarray(shaped.rest_joints, np.float64),
                        np.asarray(landmarks.joint, np.int64),
                        np.ascontiguousarray(rest, np.float64))
        else:
            dtype = landmarks.model.dtype                   # float32 bodies: float32 costs
            self.tables = tables.astype(dtype)
            self.obs_cast = MarkerObservation(obs.xy.astype(dtype), obs.valid, obs.confidence)
        self.rest = rest.astype(landmarks.model.dtype)
        L = len(landmarks)
        self.predicted = predicted
        self.weak = np.zeros(L, bool) if weak is None or predicted is None else np.asarray(weak, bool)

    @staticmethod
    def _rest_points(landmarks: LandmarkSet, shaped: ShapedBody, offsets: np.ndarray | None,
                     given: np.ndarray | None = None) -> np.ndarray:
        """Rest landmarks (L, 3) (``given``: ``landmarks.rest_points(shaped)`` as the caller
        has it), plus keypoint offsets in their joints' rest frames
        (:mod:`mocap.trackers.markers.offsets`) when given."""
        rest = np.asarray(landmarks.rest_points(shaped) if given is None else given, np.float64)
        return rest if offsets is None else rest + offsets

    def points(self, chi: np.ndarray) -> np.ndarray:
        """Landmarks (P, L, 3) of poses (P, D), in the body's dtype (forward kinematics as
        :meth:`LandmarkSet.positions`, with the rest points computed once)."""
        m = self.landmarks.model
        if self.compiled:
            parents, dof_joint, axes, rest_joints, lm_joint, rest = self._fk
            chi = np.ascontiguousarray(np.atleast_2d(chi), np.float64)
            return landmark_points(parents, dof_joint, axes, rest_joints, chi, lm_joint, rest)
        chi = np.atleast_2d(np.asarray(chi, dtype=m.dtype))
        G = chain_transforms(m.parents, m.dof_joint, self.shaped.axes, self.shaped.rest_joints,
                             chi[:, :6], chi[:, 6:])
        return self.landmarks.from_transforms(G, self.rest)

    def costs_of_points(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-landmark costs of landmarks X: (P, L, 3): (markers (P, L), coherence (P, L)),
        each divided by L x C so that their sum over landmarks is the energy (pixels^2)."""
        s = self.settings
        if self.compiled:
            cost, _ = view_costs_fused(np.ascontiguousarray(X, np.float64), *self._cams, self.obs.xy,
                                       self.obs.valid, self._lines, self.tables.epipoles,
                                       float(s.gate_px) ** 2, float(s.near), self._weight)
        else:
            u, depth = pinhole_project(self.rig, X, compiled=False)
            cost, _ = view_costs(u, depth > s.near, self.obs_cast, self.tables, s.gate_px,
                                 s.use_confidence)
        P, L, C = cost.shape
        markers = cost.sum(axis=2) / (L * C)
        coh = np.zeros((P, L), cost.dtype)
        if s.coherence_weight and self.weak.any():
            d2 = ((X[:, self.weak] - self.predicted[self.weak]) ** 2).sum(axis=-1)
            coh[:, self.weak] = (s.coherence_weight * s.gate_px**2 / (L * C)
                                 * np.minimum(d2 / s.coherence_radius**2, 1.0))
        return markers, coh

    def terms_of_points(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """{"markers": (P,), "coherence": (P,)} pixels^2 for landmarks X: (P, L, 3)."""
        markers, coh = self.costs_of_points(X)
        return {"markers": markers.sum(axis=1), "coherence": coh.sum(axis=1)}

    def terms(self, chi: np.ndarray) -> dict[str, np.ndarray]:
        return self.terms_of_points(self.points(np.atleast_2d(chi)))

    def landmark_costs(self, chi: np.ndarray) -> np.ndarray:
        """(P, D) -> (P, L) per-landmark energy (the crossover of the annealing uses it)."""
        markers, coh = self.costs_of_points(self.points(np.atleast_2d(chi)))
        return markers + coh

    def __call__(self, chi: np.ndarray) -> np.ndarray:
        """(P, D) -> (P,) energy, pixels^2."""
        return self.landmark_costs(chi).sum(axis=1)


def views_near(obs: MarkerObservation, rig: Rig, points: np.ndarray, gate_px: float) -> np.ndarray:
    """(L,) number of views with a candidate within ``gate_px`` of the projection of each
    landmark (points: (L, 3), e.g. the predicted landmarks)."""
    u, depth = pinhole_project(rig, points[None])
    d2 = ((obs.xy - u[0][:, :, None, :]) ** 2).sum(axis=-1)
    near = (obs.valid & (d2 < gate_px**2)).any(axis=2) & (depth[0] > 0)
    return near.sum(axis=1)


def reprojection_errors(points: np.ndarray, obs: MarkerObservation, rig: Rig, gate_px: float) -> np.ndarray:
    """(L, C) pixel distance from each landmark's projection (points: (L, 3)) to its nearest
    candidate within the gate; NaN where none."""
    u, depth = pinhole_project(rig, points[None])
    d = np.sqrt(((obs.xy - u[0][:, :, None, :]) ** 2).sum(axis=-1))
    d = np.where(obs.valid, d, np.inf).min(axis=2)
    return np.where((d < gate_px) & (depth[0] > 0), d, np.nan)


def associate(u: np.ndarray, front: np.ndarray, obs: MarkerObservation,
              gate_px: float, compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest candidate within the gate per landmark and view (the marker tracker's
    refinement, the two-cue hybrid's keypoint correspondences). u: (L, C, 2) projections,
    front: (L, C). Returns z (L, C, 2), confidence (L, C), ok (L, C) bool. With numba
    (``compiled`` None or True) one compiled loop
    (:func:`mocap.energy.marker_kernel.nearest_candidates`), the same values."""
    if (compiled is None or compiled) and HAVE_NUMBA:
        L, C = front.shape
        z, conf, ok = np.empty((L, C, 2)), np.empty((L, C)), np.empty((L, C), bool)
        nearest_candidates(np.ascontiguousarray(u, np.float64), np.ascontiguousarray(front, bool),
                           np.ascontiguousarray(obs.xy, np.float64), np.ascontiguousarray(obs.valid, bool),
                           np.ascontiguousarray(obs.confidence, np.float64), float(gate_px) ** 2, z, conf, ok)
        return z, conf, ok
    d2 = ((obs.xy - u[:, :, None, :]) ** 2).sum(axis=-1)
    d2 = np.where(obs.valid, d2, np.inf)
    k = np.argmin(d2, axis=2)
    best = np.take_along_axis(d2, k[..., None], axis=2)[..., 0]
    z = np.take_along_axis(obs.xy, k[..., None, None], axis=2)[:, :, 0]
    conf = np.take_along_axis(obs.confidence, k[..., None], axis=2)[..., 0]
    return z, conf, (best < gate_px**2) & front
