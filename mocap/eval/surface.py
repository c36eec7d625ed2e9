"""Scoring a tracked body against the true body SURFACE (not its joints).

The ground truth gives points on the true surface per frame (``gt.npz`` field ``surface``
(F, N, 3) metres, optionally ``surface_faces`` (M, 3) when the points are a mesh's vertices;
:mod:`mocap.data.sequence_io`). Two directions, each in mm per frame:

- ``surface_to_mesh``: every true point's exact distance to the tracked mesh (point to
  triangle, :func:`closest_points_on_mesh`): how much of the true body the tracked body
  misses or misplaces;
- ``mesh_to_surface``: every tracked vertex's distance to the true mesh (point to triangle)
  when ``surface_faces`` is given, else to the nearest true point: how much tracked surface
  lies where there is no body.

Per frame the mean and the 90th percentile of the distances; over frames (the keys of
:func:`surface_metrics`) the mean of the per-frame means and the mean of the per-frame 90th
percentiles, over every frame (frame 0, the initialisation, included, like ``mpjpe_mm``).

``silhouette_iou``: overlap (intersection over union) of the tracked body's exact silhouette
(:func:`mocap.render.rasterize_silhouettes`, full resolution) with the observed masks, per frame
and view.

All functions are pure numpy, batch-first; points and vertices in metres.
"""

from __future__ import annotations

from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

_CANDIDATES_PER_CHUNK = 2_000_000       # (point, triangle) pairs tested at once
_NEAREST = 8                            # nearest triangle centroids tested first, per size group


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
                                ) -> tuple[np.ndarray, np.ndarray]:
    """Exact closest points of points p (N, 3) on triangles (a, b, c) (N, 3) each (Ericson,
    Real-Time Collision Detection, 5.1.5). -> closest points (N, 3) and their barycentric
    coordinates (N, 3) (weights of a, b, c). Degenerate triangles give a closest point on
    their edges or vertices."""
    p, a, b, c = (np.asarray(x, np.float64) for x in (p, a, b, c))
    ab, ac, ap = b - a, c - a, p - a
    dot = lambda x, y: np.einsum("ni,ni->n", x, y)  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    n = len(p)
    bary = np.empty((n, 3))
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v_in, w_in = vb / denom, vc / denom
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    # regions in order of precedence (the first that applies wins): assign in reverse order
    inside = np.isfinite(v_in) & np.isfinite(w_in)
    bary[:] = np.where(inside[:, None], np.stack([1 - v_in - w_in, v_in, w_in], 1), [1.0, 0.0, 0.0])
    cases = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), lambda t: np.stack([0 * t, 1 - t, t], 1), t_bc),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), lambda t: np.stack([1 - t, 0 * t, t], 1), t_ac),
        ((d6 >= 0) & (d5 <= d6), lambda t: np.tile([0.0, 0.0, 1.0], (len(t), 1)), t_ac),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), lambda t: np.stack([1 - t, t, 0 * t], 1), t_ab),
        ((d3 >= 0) & (d4 <= d3), lambda t: np.tile([0.0, 1.0, 0.0], (len(t), 1)), t_ab),
        ((d1 <= 0) & (d2 <= 0), lambda t: np.tile([1.0, 0.0, 0.0], (len(t), 1)), t_ab),
    ]
    for sel, make, t in cases:
        if sel.any():
            tt = np.nan_to_num(t[sel], nan=0.0, posinf=0.0, neginf=0.0).clip(0.0, 1.0)
            bary[sel] = make(tt)
    q = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    return q, bary


def closest_points_on_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact closest points of points (N, 3) on the triangle mesh (vertices (V, 3), faces
    (M, 3) int). -> distances (N,), the triangle of each closest point (N,) int and its
    barycentric coordinates (N, 3).

    Exact, not point-to-vertex: the distance to the nearest vertex d0 bounds the answer; every
    triangle that could come closer (its centroid within d0 + its circumradius about the
    centroid) is tested exactly (:func:`closest_points_on_triangles`), by a KD-tree over the
    triangles' centroids."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.intp)
    tri = vertices[faces]                                       # (M, 3, 3)
    cen = tri.mean(axis=1)
    rad = np.linalg.norm(tri - cen[:, None], axis=-1).max(axis=1)
    d0, _ = cKDTree(vertices[np.unique(faces)]).query(points)
    tol = 1e-12 + 1e-9 * d0
    best = np.full(len(points), np.inf)
    best_face = np.zeros(len(points), np.intp)
    best_bary = np.zeros((len(points), 3))

    def test(pi, fi):                       # exact distances of candidate pairs; keep the best
        if not len(pi):
            return
        q, bary = closest_points_on_triangles(points[pi], tri[fi, 0], tri[fi, 1], tri[fi, 2])
        d = np.linalg.norm(points[pi] - q, axis=1)
        order = np.lexsort((d, pi))                             # by point, then distance
        first = order[np.r_[True, pi[order][1:] != pi[order][:-1]]]
        take = first[d[first] < best[pi[first]]]
        best[pi[take]], best_face[pi[take]], best_bary[pi[take]] = d[take], fi[take], bary[take]

    # triangles grouped by size (circumradius within a factor 2), one KD-tree each, so that a
    # few large triangles do not widen every query; first the k nearest centroids of each
    # group (an upper bound), then a ball query where a farther triangle could still be closer
    group = np.floor(np.log2(np.maximum(rad, 1e-6) / max(float(np.median(rad)), 1e-6))).clip(0, None)
    groups = []
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        ctree = cKDTree(cen[members])
        k = min(_NEAREST, len(members))
        dist_c, idx = ctree.query(points, k)
        dist_c, idx = dist_c.reshape(len(points), k), idx.reshape(len(points), k)
        test(np.repeat(np.arange(len(points)), k), members[idx.ravel()])
        groups.append((members, ctree, dist_c[:, -1], k == len(members)))
    for members, ctree, kth, complete in groups:
        rmax = rad[members].max()
        bound = np.minimum(d0, best) + tol
        open_ = np.flatnonzero(kth - rmax <= bound) if not complete else np.zeros(0, np.intp)
        if not len(open_):
            continue
        radius = bound[open_] + rmax
        counts = ctree.query_ball_point(points[open_], radius, return_length=True)
        start = 0
        while start < len(open_):
            stop = start + 1 + int(np.searchsorted(np.cumsum(counts[start:]), _CANDIDATES_PER_CHUNK))
            stop = min(stop, len(open_))
            lists = ctree.query_ball_point(points[open_[start:stop]], radius[start:stop], return_sorted=False)
            lens = counts[start:stop]
            pi = np.repeat(open_[start:stop], lens)
            fi = members[np.fromiter(chain.from_iterable(lists), np.intp, int(lens.sum()))]
            near = np.linalg.norm(points[pi] - cen[fi], axis=1) - rad[fi] <= bound[pi]
            test(pi[near], fi[near])
            start = stop
    return best, best_face, best_bary


def point_mesh_distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact distance of each point (..., N, 3) to the mesh (vertices (V, 3), faces (M, 3)): (..., N)."""
    points = np.asarray(points)
    return closest_points_on_mesh(points, vertices, faces)[0].reshape(points.shape[:-1])


def surface_distances(true_points: np.ndarray, tracked: np.ndarray, faces: np.ndarray,
                      true_faces: np.ndarray | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per frame, the distances (metres) true points -> tracked mesh (N,) and tracked vertices
    -> true surface (V,): true_points (F, N, 3), tracked vertices (F, V, 3) with faces (T, 3),
    true_faces (M, 3) or None (then tracked vertices -> nearest true point). Tracked vertices
    not used by any face are left out."""
    true_points = np.asarray(true_points, np.float64)
    tracked = np.asarray(tracked, np.float64)
    if true_points.ndim != 3 or tracked.ndim != 3 or len(true_points) != len(tracked):
        raise ValueError(f"true points (F, N, 3) and tracked vertices (F, V, 3) must share F, got "
                         f"{true_points.shape} and {tracked.shape}")
    used = np.unique(np.asarray(faces))
    to_mesh, to_surface = [], []
    for f in range(len(tracked)):
        to_mesh.append(point_mesh_distances(true_points[f], tracked[f], faces))
        if true_faces is None:
            to_surface.append(cKDTree(true_points[f]).query(tracked[f, used])[0])
        else:
            to_surface.append(point_mesh_distances(tracked[f, used], true_points[f], true_faces))
    return to_mesh, to_surface


def summarise(per_frame: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Distances per frame (metres) -> per-frame mean (F,) and 90th percentile (F,), mm."""
    mean = np.array([1e3 * d.mean() for d in per_frame])
    p90 = np.array([1e3 * np.percentile(d, 90) for d in per_frame])
    return mean, p90


def surface_metrics(true_points: np.ndarray, tracked: np.ndarray, faces: np.ndarray,
                    true_faces: np.ndarray | None = None) -> dict:
    """The surface scores of tracked vertices (F, V, 3) (mesh faces (T, 3)) against the true
    surface (F, N, 3) (faces (M, 3) or None). Keys (mm): ``surface_to_mesh_mm``,
    ``surface_to_mesh_p90_mm``, ``mesh_to_surface_mm``, ``mesh_to_surface_p90_mm`` (means over
    frames) and ``surface_per_frame`` {the same four names -> (F,) lists}."""
    to_mesh, to_surface = surface_distances(true_points, tracked, faces, true_faces)
    m1, p1 = summarise(to_mesh)
    m2, p2 = summarise(to_surface)
    per_frame = {"surface_to_mesh_mm": m1, "surface_to_mesh_p90_mm": p1,
                 "mesh_to_surface_mm": m2, "mesh_to_surface_p90_mm": p2}
    out: dict = {k: float(v.mean()) for k, v in per_frame.items()}
    out["surface_per_frame"] = {k: [float(x) for x in v] for k, v in per_frame.items()}
    return out


def silhouette_iou(rig, faces: np.ndarray, vertices: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """Intersection over union of the silhouettes of vertices (F, V, 3) (faces (T, 3)) in the
    views of ``rig`` with masks (F, C, H, W) bool -> (F, C) (1 where both are empty)."""
    from mocap.cameras import project
    from mocap.render import rasterize_silhouettes

    masks = np.asarray(masks, bool)
    F, C, H, W = masks.shape
    if len(vertices) != F or len(rig) != C:
        raise ValueError(f"vertices {np.shape(vertices)} and masks {masks.shape} must share frames, "
                         f"the rig's {len(rig)} views the masks' views")
    iou = np.ones((F, C))
    for f in range(F):
        pix, depth = project(rig, np.asarray(vertices[f], np.float64), return_depth=True)
        sil = rasterize_silhouettes(pix, faces, H, W, depth)
        inter = (sil & masks[f]).sum(axis=(1, 2))
        union = (sil | masks[f]).sum(axis=(1, 2))
        iou[f] = np.where(union > 0, inter / np.maximum(union, 1), 1.0)
    return iou


def iou_metrics(iou: np.ndarray, view_names) -> dict:
    """(F, C) IoU -> ``silhouette_iou`` (mean over frames and views), ``silhouette_iou_per_view``
    {view: mean over frames} and ``silhouette_iou_per_frame`` (mean over views)."""
    return {"silhouette_iou": float(iou.mean()),
            "silhouette_iou_per_view": {str(v): float(x) for v, x in zip(view_names, iou.mean(axis=0),
                                                                           strict=True)},
            "silhouette_iou_per_frame": [float(x) for x in iou.mean(axis=1)]}
