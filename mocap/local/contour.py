"""Contour correspondences (Zhang et al. 2013, Sec. 4.1; Rosenhahn et al.): points of the
model's projected occluding contour matched to the closest points of the observed
silhouette contour, each pair turned into a 3D model point and the Plücker line of the
observed pixel's ray.

Matching goes both ways: every visible model contour point to its closest observed contour
point, and every observed contour point to its closest model contour point (so an observed
limb the model has lost still pulls it back).

The model's occluding contour is the set of mesh edges whose two faces face opposite ways
as seen from the camera centre (the contour generator); of those vertices we keep the ones
that are not hidden by other body parts, i.e. that project onto the outline of the model's
own silhouette. Matches farther than ``max(reject_factor x 90th percentile, min_reject_px)``
or ``max_distance`` (a fraction of the image height) are rejected as outliers: a limb that
moved shows up as a tail of long matches, which must survive the rejection.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
import trimesh

from mocap.body.model import BodyModel
from mocap.cameras import (
    Rig,
    camera_coordinates,
    pixel_rays,
    pixels_from_camera,
    plucker_from_rays,
    view_rigs,
)
from mocap.compiled import HAVE_NUMBA, njit
from mocap.local.nearest import NearestPoints
from mocap.local.settings import ContourSettings
from mocap.local.solver import PointLines
from mocap.render import get_rasterizer


@dataclass(frozen=True)
class ObservedContours:
    """Per view: contour points (M, 2) in camera pixels and their nearest-point index (None:
    no contour). ``lines``: the Plücker lines of the points, per rig (filled by
    :meth:`ContourMatcher.observed_lines`: the observed outline is the same for every
    iteration of a frame, so its rays are back-projected once)."""

    points: list[np.ndarray]
    trees: list[NearestPoints | None]
    lines: dict = field(default_factory=dict, compare=False, repr=False)


def observed_contours(masks: np.ndarray) -> ObservedContours:
    """Outline pixels of observed silhouettes (C, H, W) bool, once per frame."""
    pts, trees = [], []
    for m in masks:
        contours, _ = cv2.findContours(m.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
        p = (np.concatenate([c[:, 0, :] for c in contours]).astype(np.float64) if contours
             else np.zeros((0, 2)))
        pts.append(p)
        trees.append(NearestPoints(p) if len(p) else None)
    return ObservedContours(pts, trees)


if HAVE_NUMBA:

    @njit(cache=True)
    def _contour_marks(verts, faces, centers, edge_faces, edge_vertices, mark):
        """mark[c, v] = True for the vertices of edges whose two faces face opposite ways
        from centre c: the numpy path of :meth:`ContourMatcher.contour_vertices` in one
        pass, with its arithmetic (n . centroid - n . centre, each a 3-term sum in order)."""
        F = faces.shape[0]
        C = centers.shape[0]
        normal = np.empty((F, 3))
        offset = np.empty(F)
        for f in range(F):
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            e1x, e1y, e1z = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
            e2x, e2y, e2z = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
            nx = e1y * e2z - e1z * e2y
            ny = e1z * e2x - e1x * e2z
            nz = e1x * e2y - e1y * e2x
            cx = (verts[a, 0] + verts[b, 0] + verts[c, 0]) / 3.0
            cy = (verts[a, 1] + verts[b, 1] + verts[c, 1]) / 3.0
            cz = (verts[a, 2] + verts[b, 2] + verts[c, 2]) / 3.0
            normal[f, 0], normal[f, 1], normal[f, 2] = nx, ny, nz
            offset[f] = nx * cx + ny * cy + nz * cz
        facing = np.empty(F, np.bool_)
        for k in range(C):
            px, py, pz = centers[k, 0], centers[k, 1], centers[k, 2]
            for f in range(F):
                facing[f] = offset[f] - (px * normal[f, 0] + py * normal[f, 1] + pz * normal[f, 2]) < 0
            for e in range(edge_faces.shape[0]):
                if facing[edge_faces[e, 0]] != facing[edge_faces[e, 1]]:
                    mark[k, edge_vertices[e, 0]] = True
                    mark[k, edge_vertices[e, 1]] = True


def percentile90(x: np.ndarray) -> float:
    """``np.percentile(x, 90)`` (linear interpolation, numpy's arithmetic) by partial sort:
    the same value without np.percentile's per-call overhead (~0.4 ms; 8 calls per
    iteration)."""
    n = len(x)
    pos = 0.9 * (n - 1)
    lo = int(np.floor(pos))
    hi = min(lo + 1, n - 1)
    part = np.partition(x, [lo, hi])
    a, b = float(part[lo]), float(part[hi])
    t = pos - lo
    return b - (b - a) * (1.0 - t) if t >= 0.5 else a + (b - a) * t


def outline_band(mask: np.ndarray, kernel3: np.ndarray, kernel_tol: np.ndarray) -> np.ndarray:
    """(h, w) bool mask -> (h, w) uint8, nonzero within ``kernel_tol`` of the mask's outline
    (its pixels with a 3x3 neighbour outside it; beyond the image border counts as inside,
    cv2.erode's default): ``dilate(m - erode(m, kernel3), kernel_tol)``, taken on the mask's
    bounding box grown by the tolerance's radius + 1. The same image (tested): the crop's
    edge pixels are 0, so the erosion there does not depend on what lies beyond, and the
    dilated outline stays inside; zeros elsewhere. A person covers ~15 % of the frame."""
    m = np.ascontiguousarray(mask).view(np.uint8)
    out = np.zeros_like(m)
    x, y, bw, bh = cv2.boundingRect(m)
    if bw == 0:
        return out
    g = kernel_tol.shape[0] // 2 + 1
    x0, y0 = max(x - g, 0), max(y - g, 0)
    x1, y1 = min(x + bw + g, m.shape[1]), min(y + bh + g, m.shape[0])
    crop = m[y0:y1, x0:x1]
    out[y0:y1, x0:x1] = cv2.dilate(crop - cv2.erode(crop, kernel3), kernel_tol)
    return out


_D = ContourSettings()   # the defaults of the keyword arguments


class ContourMatcher:
    """Builds contour correspondences for one body topology and rig."""

    def __init__(self, body: BodyModel, rig: Rig, visibility_scale: float = _D.visibility_scale,
                 visibility_tolerance_px: float = _D.visibility_tolerance_px,
                 reject_factor: float = _D.reject_factor, min_reject_px: float = _D.min_reject_px,
                 max_distance: float = _D.max_distance, stride: int = _D.stride,
                 observed_stride: int = _D.observed_stride):
        self.body, self.rig = body, rig
        mesh = trimesh.Trimesh(body.data.mean, body.faces, process=False)
        self.edge_faces = np.ascontiguousarray(mesh.face_adjacency, np.int64)           # (E, 2)
        self.edge_vertices = np.ascontiguousarray(mesh.face_adjacency_edges, np.int64)  # (E, 2)
        self.faces64 = np.ascontiguousarray(body.faces, np.int64)
        self.scale = visibility_scale
        self.small = rig.scaled(visibility_scale)
        w, h = (int(v) for v in self.small.sizes[0])
        self.small_size = (h, w)
        self.raster = get_rasterizer(body.faces, body.num_vertices)
        r = int(np.ceil(visibility_tolerance_px))
        self.kernel3 = np.ones((3, 3), np.uint8)
        self.kernel_tol = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        self.reject_factor, self.min_reject_px = reject_factor, min_reject_px
        self.max_distance_px = max_distance * float(rig.sizes[0][1])
        self.stride, self.observed_stride = stride, observed_stride
        self.view_rigs = view_rigs(rig)        # 16 projections / back-projections per iteration

    def contour_vertices(self, verts: np.ndarray, centers: np.ndarray) -> list[np.ndarray]:
        """Vertex ids on the contour generator seen from each camera centre (C, 3)."""
        if HAVE_NUMBA:
            mark = np.zeros((len(centers), len(verts)), bool)
            _contour_marks(np.ascontiguousarray(verts, np.float64), self.faces64,
                           np.ascontiguousarray(centers, np.float64), self.edge_faces,
                           self.edge_vertices, mark)
            return [np.flatnonzero(m) for m in mark]
        tri = verts[self.body.faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        centroids = tri.mean(axis=1)
        # n . (x - c) for every view at once: (C, F)
        facing = (np.einsum("fc,fc->f", normals, centroids)[None] - centers @ normals.T) < 0
        f = self.edge_faces
        crossing = facing[:, f[:, 0]] != facing[:, f[:, 1]]                 # (C, E)
        out = []
        mark = np.zeros(len(verts), bool)
        for sel in crossing:             # sorted unique ids, without np.unique's sort
            mark[:] = False
            mark[self.edge_vertices[sel]] = True
            out.append(np.flatnonzero(mark))
        return out

    def observed_lines(self, observed: ObservedContours) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Plücker lines (directions, moments; (M_c, 3) each per view) of every observed
        contour point, back-projected in one call for all views (the views padded to one
        length with their principal point), once per frame: kept in ``observed.lines``."""
        cached = observed.lines.get(id(self.rig))
        if cached is not None and cached[0] is self.rig:
            return cached[1], cached[2]
        n = max((len(q) for q in observed.points), default=0)
        if n == 0:
            return [np.zeros((0, 3))] * len(observed.points), [np.zeros((0, 3))] * len(observed.points)
        px = np.broadcast_to(self.rig.K[:, :2, 2][:, None, :], (len(self.rig), n, 2)).copy()
        for c, q in enumerate(observed.points):
            px[c, : len(q)] = q
        d, mo = plucker_from_rays(*pixel_rays(self.rig, px))
        lines = ([d[c, : len(q)] for c, q in enumerate(observed.points)],
                 [mo[c, : len(q)] for c, q in enumerate(observed.points)])
        observed.lines[id(self.rig)] = (self.rig, *lines)
        return lines

    def __call__(self, verts: np.ndarray, observed: ObservedContours) -> tuple[PointLines, dict]:
        """Correspondences for posed vertices (V, 3); diagnostics: per-view counts, and the
        views without an observed contour."""
        h, w = self.small_size
        # camera coordinates once: the visibility rig (rescaled) shares R, t with the rig
        cam_xyz = camera_coordinates(self.rig, verts)                   # (C, 3, V)
        px_small, depth_small = pixels_from_camera(self.small, cam_xyz)
        model_masks = self.raster(px_small, h, w, depth_small, near=0.05)
        X, limbs, D, M = [], [], [], []
        counts, empty = [], []
        obs_d, obs_m = self.observed_lines(observed)
        generators = self.contour_vertices(verts, self.rig.centers)
        for c, cam in enumerate(self.view_rigs):
            tree = observed.trees[c]
            if tree is None:
                counts.append(0)
                empty.append(self.rig.names[c])
                continue
            vid = generators[c][:: self.stride]
            if len(vid) == 0:
                counts.append(0)
                continue
            # visible: the vertex projects onto the outline of the model's own silhouette
            near_outline = outline_band(model_masks[c], self.kernel3, self.kernel_tol)
            ps = px_small[c, vid]
            inside = (ps[:, 0] >= 0) & (ps[:, 0] <= w - 1) & (ps[:, 1] >= 0) & (ps[:, 1] <= h - 1)
            vid, ps = vid[inside], ps[inside]
            ui, vi = np.round(ps).astype(int).T
            vid = vid[near_outline[vi, ui] > 0]
            if len(vid) == 0:
                counts.append(0)
                continue
            p = pixels_from_camera(cam, cam_xyz[c:c + 1, :, vid])[0][0]
            # both directions: each model contour point to its closest observed contour
            # point, and each observed contour point to its closest model contour point, so
            # that observed outline no model part explains still pulls the model
            dist, idx = tree.query(p)
            obs_ids = np.arange(0, len(observed.points[c]), self.observed_stride)
            back_dist, back_idx = NearestPoints(p).query(observed.points[c][obs_ids])
            vid = np.concatenate([vid, vid[back_idx]])
            oid = np.concatenate([idx, obs_ids])           # the observed points paired
            dist = np.concatenate([dist, back_dist])
            thr = min(max(self.reject_factor * percentile90(dist), self.min_reject_px),
                      self.max_distance_px)
            keep = dist <= thr
            vid, oid = vid[keep], oid[keep]
            X.append(verts[vid])
            limbs.append(self.body.part_labels[vid])
            D.append(obs_d[c][oid])
            M.append(obs_m[c][oid])
            counts.append(int(len(vid)))
        if X:
            pts = np.concatenate(X).astype(np.float64)
            corr = PointLines(pts, np.concatenate(limbs), np.concatenate(D), np.concatenate(M),
                              np.ones(len(pts)))
        else:
            z = np.zeros((0, 3))
            corr = PointLines(z, np.zeros(0, int), z, z, np.zeros(0))
        return corr, {"contour_per_view": counts, "views_without_contour": empty}
