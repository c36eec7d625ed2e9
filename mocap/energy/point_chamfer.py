"""A cheap stand-in for E_S from points, no raster (issue 38, the initialiser's wide early layers).

Per view C, with D_C the observed silhouette's distance transform (the target's), the model's
surface samples x_i (a mesh's vertices, projected) with weights w_i (each vertex's share of the
mesh's surface area at rest: a third of its triangles' areas) and samples q_k of the observed
silhouette (K evenly along its outer contours, K evenly among its pixels):

    E_P^C = sum_i w_i D_C(x_i) / sum_i w_i  +  1/(2K) sum_k min_i |q_k - x_i|

the two terms of Eq. 11's symmetric chamfer (:mod:`mocap.energy.silhouette`) with the model's
silhouette replaced by its projected surface points: term 1 reads the observed transform at the
points (bilinear) instead of summing it over the model's pixels (the area weights stand for the
pixels a point covers: a decimated mesh keeps many vertices at the hands, feet and face, and
unweighted they ranked real particles far less like E_S: Spearman 0.74 against 0.97 for term 1
alone, issue 38 version 7), term 2 measures how far each observed sample lies from the nearest
projected point instead of taking the model's distance transform over the observed pixels (the
contour samples see a limb the model misses, the pixel samples weight it by its area, as E_S).
No model mask is drawn and no transform taken per particle, so the cost is the skinning, the
projection, N lookups and 2K x N distances per particle-view, whatever the resolution of the
target. The points are a surface's samples, not its silhouette's, so term 2 does not reach 0 for
a perfect fit (the nearest point to an observed sample lies up to about half a vertex spacing
away); a ranking of particles is what the annealed search's early layers need from it (the
weights are normalised by the layer's energy spread).

A point outside the image reads the transform at the nearest image pixel plus its distance to
the image; a view where no point lies in front of the camera scores ``penalty`` (the image
diagonal) for each term. Distances are in pixels of the target's resolution.
"""

from __future__ import annotations

import cv2
import numpy as np

from mocap.body.energy_mesh import EnergyMesh
from mocap.cameras import Rig, camera_coordinates
from mocap.compiled import HAVE_NUMBA, njit, prange

if HAVE_NUMBA:
    from mocap.energy.fused import project_view

_FAR = 1e9          # a pixel coordinate no contour sample is near: points behind the camera


def _evenly(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` rows of points (N, 2) evenly spaced by index (all of them when N <= count)."""
    return points[np.linspace(0, len(points), min(count, len(points)), endpoint=False).astype(np.int64)]


def contour_samples(masks: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(C, h, w) bool masks -> (C, 2, count) float32 pixel samples (x row, then y row) evenly spaced (by
    index) along each view's outer contours (OpenCV's, every contour pixel, all outer contours
    in turn) and (C,) int64 how many of them are set (0 for an empty mask; fewer than count
    when the contours have fewer pixels)."""
    if count < 1:
        raise ValueError(f"contour samples: count must be >= 1, got {count}")
    masks = np.asarray(masks)
    out = np.zeros((len(masks), 2, count), np.float32)
    n = np.zeros(len(masks), np.int64)
    for c, m in enumerate(masks):
        found, _ = cv2.findContours(np.ascontiguousarray(m, np.uint8), cv2.RETR_EXTERNAL,
                                    cv2.CHAIN_APPROX_NONE)
        if not found:
            continue
        pts = _evenly(np.concatenate([f[:, 0] for f in found]), count)
        out[c, :, :len(pts)] = pts.T
        n[c] = len(pts)
    return out, n


def observed_samples(masks: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The reverse term's samples: (C, 2, 2 count) float32 pixels (x row, y row), per view
    ``count`` :func:`contour_samples` then ``count`` of the set pixels evenly spaced in row-major
    order, both packed from index 0; and (C,) int64 how many are set (2 count, fewer for a tiny
    silhouette, 0 for an empty one)."""
    contour, n = contour_samples(masks, count)
    out = np.zeros((len(contour), 2, 2 * count), np.float32)
    total = np.zeros(len(contour), np.int64)
    for c, m in enumerate(np.asarray(masks)):
        ys, xs = np.nonzero(m)
        pixels = _evenly(np.c_[xs, ys], count)
        out[c, :, :n[c]] = contour[c, :, :n[c]]
        out[c, :, n[c]:n[c] + len(pixels)] = pixels.T
        total[c] = n[c] + len(pixels)
    return out, total


def vertex_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3), (F, 3) -> (V,) float64 each vertex's share of the surface area (a third of the
    area of each of its triangles; they add up to the mesh's area)."""
    v = np.asarray(vertices, np.float64)
    a, b, c = (v[faces[:, k]] for k in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    out = np.zeros(len(v))
    np.add.at(out, np.asarray(faces).ravel(), np.repeat(area / 3.0, 3))
    return out


if HAVE_NUMBA:

    @njit(cache=True, inline="always")
    def _dt_at(dt, x, y):
        """Bilinear read of dt (h, w) at pixel (x, y); outside the image, the value at the
        nearest image point plus the distance to it."""
        h, w = dt.shape
        cx = min(max(x, 0.0), w - 1.0)
        cy = min(max(y, 0.0), h - 1.0)
        outside = np.sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy))
        x0 = min(int(cx), w - 2) if w > 1 else 0
        y0 = min(int(cy), h - 2) if h > 1 else 0
        fx = cx - x0
        fy = cy - y0
        x1 = min(x0 + 1, w - 1)
        y1 = min(y0 + 1, h - 1)
        top = dt[y0, x0] * (1.0 - fx) + dt[y0, x1] * fx
        bottom = dt[y1, x0] * (1.0 - fx) + dt[y1, x1] * fx
        return top * (1.0 - fy) + bottom * fy + outside

    @njit(cache=True, fastmath=True, inline="always")
    def _nearest_sq(xs, ys, qx, qy, best):
        """best[k] = min_i (xs[i] - qx[k])^2 + (ys[i] - qy[k])^2, (K,) over the points (V,): the
        inner loop runs over the samples (contiguous), which vectorises."""
        for k in range(qx.shape[0]):
            best[k] = np.inf
        for i in range(xs.shape[0]):
            x = xs[i]
            y = ys[i]
            for k in range(qx.shape[0]):
                dx = qx[k] - x
                dy = qy[k] - y
                best[k] = min(best[k], dx * dx + dy * dy)

    @njit(cache=True, parallel=True)
    def _point_chamfer(X, cam, dist, has_dist, has_skew, weights, dt, samples, counts, valid, penalty, out,
                       bad):
        """X: (P, C, 3, V) camera coordinates; cam (C, 8), dist (C, 5), has_dist, has_skew: the
        projection (:func:`mocap.energy.fused.project_view`); weights (V,) float64 the points'
        weights in term 1; dt (C, h, w) float32; samples (C, 2, K) float32 observed samples
        (x row, y row), counts (C,) how many are set; valid (C,) bool.
        out: (P * C,) float64 energies (NaN for invalid views); bad (P * C,) vertices in front
        with a pixel not finite."""
        n_part, n_views, _, V = X.shape
        for k in prange(n_part * n_views):
            p = k // n_views
            c = k % n_views
            if not valid[c]:
                out[k] = np.nan
                continue
            xs = np.empty(V, X.dtype)
            ys = np.empty(V, X.dtype)
            vs = np.empty(V, np.bool_)
            bad[k] = project_view(X[p, c], cam[c], dist[c], has_dist, has_skew, xs, ys, vs)
            t1 = 0.0
            wsum = 0.0
            n = 0
            for v in range(V):
                if vs[v]:
                    t1 += weights[v] * _dt_at(dt[c], xs[v], ys[v])
                    wsum += weights[v]
                    n += 1
                else:
                    xs[v] = _FAR
                    ys[v] = _FAR
            if n == 0 or counts[c] == 0 or wsum <= 0.0:
                out[k] = 2.0 * penalty
                continue
            m = counts[c]
            best = np.empty(m, np.float32)
            _nearest_sq(xs, ys, samples[c, 0, :m], samples[c, 1, :m], best)
            t2 = 0.0
            for s in range(m):
                t2 += np.sqrt(best[s])
            out[k] = t1 / wsum + t2 / m


class PointChamfer:
    """The compiled point chamfer of camera coordinates against a
    :class:`~mocap.energy.silhouette.SilhouetteTarget`, with :class:`~mocap.energy.fused.
    FusedSilhouetteEnergy`'s call (so the shape searches' :func:`~mocap.trackers.shape_search.
    particle_energies` takes it as its kernel). weights: (V,) the points' area weights
    (:func:`vertex_areas`); samples: contour samples and pixel samples per view (each)."""

    def __init__(self, weights: np.ndarray, samples: int = 48):
        if not HAVE_NUMBA:
            raise RuntimeError("the point chamfer needs numba")
        if int(samples) < 1:
            raise ValueError(f"point chamfer: samples must be >= 1, got {samples}")
        self.weights = np.ascontiguousarray(weights, np.float64)
        if self.weights.ndim != 1 or not (self.weights >= 0).all() or self.weights.sum() <= 0:
            raise ValueError(f"point chamfer: weights must be (V,) >= 0, not all 0, got {self.weights.shape}")
        self.samples = int(samples)
        self._key, self._target, self._contours = None, None, None

    def contours(self, target) -> tuple[np.ndarray, np.ndarray]:
        """The target's observed samples (C, 2, K) and counts (C,), cached for the current target."""
        if self._key != id(target):
            self._contours = observed_samples(target.masks, self.samples)
            self._key, self._target = id(target), target       # alive while its id is the key
        return self._contours

    def __call__(self, camera: np.ndarray, rig: Rig, target, near: float = 0.05) -> np.ndarray:
        """camera: (P, C, 3, V) camera coordinates in the views of ``rig`` (the target's
        resolution) -> (P, C) float64 energies, NaN for views the target ignores."""
        X = np.ascontiguousarray(camera)
        if X.ndim != 4 or X.shape[2] != 3 or X.shape[1] != len(rig):
            raise ValueError(f"camera coordinates must be (P, {len(rig)}, 3, V), got {X.shape}")
        P, C, _, V = X.shape
        if V != len(self.weights):
            raise ValueError(f"camera coordinates of {V} points, {len(self.weights)} weights")
        samples, counts = self.contours(target)
        K = rig.K
        cam = np.empty((C, 8), X.dtype)
        cam[:, :5] = np.stack([K[:, 0, 0], K[:, 0, 1], K[:, 0, 2], K[:, 1, 1], K[:, 1, 2]], 1)
        cam[:, 5:] = (1.0, 2.0, near)
        dist = np.ascontiguousarray(rig.dist, dtype=X.dtype)
        h, w = target.size
        out = np.empty(P * C)
        bad = np.zeros(P * C, np.int64)
        _point_chamfer(X, cam, dist, bool(np.any(rig.dist)), bool(np.any(K[:, 0, 1])), self.weights,
                       np.ascontiguousarray(target.dt, np.float32), samples, counts, target.valid,
                       float(np.hypot(h, w)), out, bad)
        if bad.sum():
            raise ValueError(f"pixels contain NaN or inf at {int(bad.sum())} vertices in front of the camera")
        return out.reshape(P, C)


class PointChamferEnergy:
    """E_P (the module's point chamfer) of a shaped body seen by ``rig`` at an internal resolution
    ``scale``, its surface sampled by the vertices of ``mesh`` (an
    :class:`~mocap.body.energy_mesh.EnergyMesh`; None: the body's own vertices), weighted by their
    areas on the shaped body at rest: the call of :class:`~mocap.energy.silhouette.SilhouetteEnergy`,
    (P, D), target -> (P,)."""

    def __init__(self, shaped, rig: Rig, scale: float, mesh: EnergyMesh | None = None, samples: int = 48):
        if mesh is not None and mesh.num_source != shaped.model.num_vertices:
            raise ValueError(f"the point mesh reads {mesh.num_source} vertices, the body has "
                             f"{shaped.model.num_vertices}")
        self.shaped, self.mesh = shaped, mesh
        self.internal = rig.scaled(float(scale))
        self._basis = None if mesh is None else mesh.skinning_basis(shaped.skinning_basis)
        self.kernel = PointChamfer(point_weights(shaped, mesh), samples)

    def per_view(self, chi: np.ndarray, target) -> np.ndarray:
        """(P, D) -> (P, C) point chamfer per view (NaN for ignored views)."""
        vertices = self.shaped.vertices(np.atleast_2d(chi), self._basis)
        return self.kernel(camera_coordinates(self.internal, vertices), self.internal, target)

    def __call__(self, chi: np.ndarray, target) -> np.ndarray:
        """(P, D) -> (P,) the mean over valid views."""
        return np.nanmean(self.per_view(chi, target)[:, target.valid], axis=1)


def point_weights(shaped, mesh: EnergyMesh | None = None) -> np.ndarray:
    """(V,) area weights (:func:`vertex_areas`) of ``mesh``'s vertices (None: the body's own) on the
    shaped body in its rest pose."""
    vertices = shaped.vertices(np.zeros((1, shaped.model.num_dofs)))[0]
    if mesh is None:
        return vertex_areas(vertices, shaped.model.faces)
    return vertex_areas(mesh.apply(vertices[None])[0], mesh.faces)
