"""The surface oracle: our body's shape and poses fitted to the TRUE SURFACE, the floor a tracker
using our model could reach on the surface metrics (:mod:`mocap.eval.surface`).

ICP-style, from a start (the joint oracle's fit, :func:`mocap.eval.mismatch.fit_oracle`):
each round fixes the correspondences at the current fit and solves a bounded least-squares
problem (scipy ``least_squares``, trust region, joint limits as bounds, shape within
+-``shape_bound``) on

- every true point minus its closest point on our mesh (exact point to triangle; the
  triangle and barycentric coordinates fixed for the round, the point moving with the body),
- every one of our vertices minus its closest point of the true surface (of its triangles
  when the surface has faces, else the nearest true point), fixed for the round,

each direction's residuals scaled by 1/sqrt(count) so both weigh the same. First the shape and
the poses jointly on ``shape_frames`` frames spread over the sequence, then each scored frame's
pose at that shape, frame by frame, warm-started from the previous scored frame's fit (or from
the joint oracle's pose of the frame where that starts closer). The Jacobians are forward
differences of the float64 body, all columns posed in one batch.

Cost: a few seconds a frame (the closest-point queries dominate), so a run scores the oracle on
every ``stride``-th frame (:class:`SurfaceOracleSettings`, default every 6th of the run's frames:
10 of 60: 0, 6, ..., 54), fitting every 5th of our vertices and every 2nd true point: ~70 s of
one core per sequence. On dev/walk_heavy_man it reaches 6.85 mm (true surface -> our mesh);
denser settings (all true points, every 2nd vertex, 8 rounds of 30 evaluations for the poses
too: ~160 s) 6.43 mm, so the default's floor is ~0.4 mm high there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from mocap.body.model import BodyModel
from mocap.eval.surface import closest_points_on_mesh, surface_metrics

POINT_WEIGHT = 0.2


@dataclass(frozen=True)
class SurfaceOracleSettings:
    """stride: score every stride-th frame (0, stride, 2 stride, ...); shape_frames: frames the
    shape is fitted on; rounds: correspondence updates per fit; max_nfev: evaluations per round;
    shape_bound: |alpha| bound; step: forward-difference step (m, rad, shape units); tol: a fit
    stops when a round lowers the cost by less than this fraction; vertex_stride, point_stride:
    every vertex_stride-th of our vertices and every point_stride-th true point are fitted
    (all are scored); shape_rounds, shape_max_nfev: rounds and evaluations of the joint shape
    fit (the floor depends on it most)."""

    stride: int = 6
    shape_frames: int = 3
    rounds: int = 4
    max_nfev: int = 10
    shape_bound: float = 3.0
    step: float = 1e-6
    tol: float = 1e-5
    vertex_stride: int = 5
    shape_rounds: int = 8
    shape_max_nfev: int = 30
    point_stride: int = 2


@dataclass(frozen=True)
class SurfaceOracleFit:
    """alpha (K,), chi (n, D) on frames (n,) (indices into the sequence), and the surface
    metrics of that fit (:func:`mocap.eval.surface.surface_metrics`)."""

    alpha: np.ndarray
    chi: np.ndarray
    frames: np.ndarray
    metrics: dict


def float64_body(body: BodyModel) -> BodyModel:
    """The same body computed in float64 (finite differences need it)."""
    if body.dtype == np.float64:
        return body
    return BodyModel(body.data, body.dofs, dtype=np.float64, name=body.name)


class _Correspondences:
    """One frame's fixed correspondences: true points p (N, 3) on our triangles (corner ids, bary),
    our vertices ``used`` (U,) on targets c (U, 3) of the true surface (normals m (U, 3) with
    faces). Residuals: point to plane (our moving triangle's normal; the true triangle's) plus
    point to point at weight :data:`POINT_WEIGHT` (it keeps the correspondences from sliding)."""

    def __init__(self, faces: np.ndarray, used: np.ndarray, verts: np.ndarray, true_points: np.ndarray,
                 true_faces: np.ndarray | None, tree: cKDTree | None, point_stride: int = 1):
        fitted = true_points[::point_stride]
        _, tri, bary = closest_points_on_mesh(fitted, verts, faces)
        self.corner = faces[tri]                          # (N, 3) our vertex ids
        self.bary = bary
        self.p = fitted
        self.m = None
        if true_faces is None:
            self.c = true_points[tree.query(verts[used])[1]]
        else:
            _, t, b = closest_points_on_mesh(verts[used], true_points, true_faces)
            tri_pts = true_points[true_faces[t]]
            self.c = np.einsum("nk,nkc->nc", b, tri_pts)
            n = np.cross(tri_pts[:, 1] - tri_pts[:, 0], tri_pts[:, 2] - tri_pts[:, 0])
            self.m = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-15)
        self.used = used
        self.wf = 1.0 / np.sqrt(len(fitted))
        self.wb = 1.0 / np.sqrt(len(used))

    def residual(self, verts: np.ndarray) -> np.ndarray:
        """verts (..., V, 3) -> (..., R) residuals."""
        corners = verts[..., self.corner, :]                          # (..., N, 3, 3)
        q = np.einsum("nk,...nkc->...nc", self.bary, corners)
        n = np.cross(corners[..., 1, :] - corners[..., 0, :], corners[..., 2, :] - corners[..., 0, :])
        n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-15)
        dq = q - self.p
        dv = verts[..., self.used, :] - self.c
        lead = verts.shape[:-2]
        parts = [np.einsum("...nc,...nc->...n", n, dq) * self.wf,
                 (POINT_WEIGHT * self.wf * dq).reshape(*lead, -1)]
        if self.m is not None:
            parts.append(np.einsum("nc,...nc->...n", self.m, dv) * self.wb)
            parts.append((POINT_WEIGHT * self.wb * dv).reshape(*lead, -1))
        else:
            parts.append((self.wb * dv).reshape(*lead, -1))
        return np.concatenate(parts, axis=-1)


def _clip(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    span = np.where(np.isfinite(hi - lo), 1e-9, 0.0)
    return np.clip(x, lo + span, hi - span)


def _fit_shape(body: BodyModel, truth: np.ndarray, true_faces, alpha: np.ndarray, chi: np.ndarray,
               s: SurfaceOracleSettings, lo_d, hi_d) -> tuple[np.ndarray, np.ndarray]:
    """Shape (K,) and poses (n, D) jointly on n frames: truth (n, N, 3)."""
    n, D = chi.shape
    K = body.num_shape
    faces = np.asarray(body.faces, np.intp)
    used = np.unique(faces)[::s.vertex_stride]
    trees = [None if true_faces is not None else cKDTree(t) for t in truth]
    lo = np.r_[np.tile(lo_d, n), np.full(K, -s.shape_bound)]
    hi = np.r_[np.tile(hi_d, n), np.full(K, s.shape_bound)]
    x = _clip(np.r_[chi.ravel(), alpha], lo, hi)
    last = np.inf

    def verts_of(a, c):
        return body.shaped(a).vertices(c)

    for _ in range(s.shape_rounds):
        V = verts_of(x[n * D:], x[:n * D].reshape(n, D))
        cors = [_Correspondences(faces, used, V[f], truth[f], true_faces, trees[f], s.point_stride)
                for f in range(n)]

        def residual(y, cors=cors):
            Vy = verts_of(y[n * D:], y[:n * D].reshape(n, D))
            return np.concatenate([c.residual(Vy[f]) for f, c in enumerate(cors)])

        def jacobian(y, cors=cors):
            a, c = y[n * D:], y[:n * D].reshape(n, D)
            base = verts_of(a, c)                                      # (n, V, 3)
            r0 = [cr.residual(base[f]) for f, cr in enumerate(cors)]
            sizes = [len(r) for r in r0]
            J = np.zeros((sum(sizes), n * D + K))
            row = 0
            shaped = body.shaped(a)
            for f, cr in enumerate(cors):        # pose columns: frame f's D poses in one batch
                P = np.repeat(c[f][None], D, axis=0) + s.step * np.eye(D)
                block = (cr.residual(shaped.vertices(P)) - r0[f]) / s.step
                J[row:row + sizes[f], f * D:(f + 1) * D] = block.T
                row += sizes[f]
            for k in range(K):                   # shape columns: all frames
                b = a.copy()
                b[k] += s.step
                Vk = verts_of(b, c)
                J[:, n * D + k] = (np.concatenate([cr.residual(Vk[f]) for f, cr in enumerate(cors)])
                                   - np.concatenate(r0)) / s.step
            return J

        r = least_squares(residual, x, jac=jacobian, bounds=(lo, hi), method="trf", tr_solver="exact",
                          max_nfev=s.shape_max_nfev)
        x = r.x
        if r.cost > (1 - s.tol) * last:
            break
        last = r.cost
    return x[n * D:], x[:n * D].reshape(n, D)


def _fit_pose(shaped, faces, used, truth: np.ndarray, true_faces, tree, chi: np.ndarray,
              s: SurfaceOracleSettings, lo_d, hi_d) -> np.ndarray:
    """One frame's pose (D,) at a fixed shape on truth (N, 3)."""
    D = len(chi)
    x = _clip(chi, lo_d, hi_d)
    last = np.inf
    for _ in range(s.rounds):
        cor = _Correspondences(faces, used, shaped.vertices(x)[0], truth, true_faces, tree, s.point_stride)

        def jacobian(y, cor=cor):
            P = np.vstack([y, y + s.step * np.eye(D)])
            R = cor.residual(shaped.vertices(P))
            return ((R[1:] - R[0]) / s.step).T

        r = least_squares(lambda y, cor=cor: cor.residual(shaped.vertices(y)[0]), x, jac=jacobian,
                          bounds=(lo_d, hi_d), method="trf", tr_solver="exact", max_nfev=s.max_nfev)
        x = r.x
        if r.cost > (1 - s.tol) * last:
            break
        last = r.cost
    return x


def fit_surface_oracle(body: BodyModel, truth: np.ndarray, true_faces: np.ndarray | None,
                       alpha0: np.ndarray, chi0: np.ndarray,
                       settings: SurfaceOracleSettings = SurfaceOracleSettings()) -> SurfaceOracleFit:
    """Our body fitted to the true surface truth (F, N, 3) (faces (M, 3) or None) from shape
    alpha0 (K,) and poses chi0 (F, D) (the joint oracle's); scored on every ``stride``-th frame."""
    from mocap.clips.fit import pose_bounds

    s = settings
    body = float64_body(body)
    truth = np.asarray(truth, np.float64)
    chi0 = np.asarray(chi0, np.float64)
    F = len(truth)
    if chi0.shape != (F, body.num_dofs):
        raise ValueError(f"chi0 must be ({F}, {body.num_dofs}), got {chi0.shape}")
    lo_d, hi_d = pose_bounds(body)
    frames = np.arange(0, F, max(1, s.stride))
    spread = np.linspace(0, len(frames) - 1, min(s.shape_frames, len(frames))).round().astype(int)
    sel = frames[np.unique(spread)]
    alpha, _ = _fit_shape(body, truth[sel], true_faces, np.asarray(alpha0, np.float64), chi0[sel], s,
                          lo_d, hi_d)
    shaped = body.shaped(alpha)
    faces = np.asarray(body.faces, np.intp)
    used = np.unique(faces)[::s.vertex_stride]
    chi = np.zeros((len(frames), body.num_dofs))
    prev = None
    for i, f in enumerate(frames):
        tree = None if true_faces is not None else cKDTree(truth[f])
        start = chi0[f]
        if prev is not None:                     # warm start: the previous fit where it starts closer
            starts = np.stack([prev, chi0[f]])
            costs = [np.mean(cKDTree(v[used]).query(truth[f])[0] ** 2) for v in shaped.vertices(starts)]
            start = starts[int(np.argmin(costs))]
        chi[i] = _fit_pose(shaped, faces, used, truth[f], true_faces, tree, start, s, lo_d, hi_d)
        prev = chi[i]
    verts = shaped.vertices(chi)
    metrics = surface_metrics(truth[frames], verts, faces, true_faces)
    metrics["frames"] = [int(f) for f in frames]
    return SurfaceOracleFit(alpha=alpha, chi=chi, frames=frames, metrics=metrics)
