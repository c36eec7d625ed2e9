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

import threading
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
)
from mocap.compiled import HAVE_NUMBA, njit
from mocap.local.nearest import NearestPoints
from mocap.local.settings import ContourSettings
from mocap.local.solver import PointLines
from mocap.render import get_rasterizer

if HAVE_NUMBA:
    from mocap.local.nearest import bucket_grid, nearest_on_grid
    from mocap.render._compiled import KeptMasks


@dataclass(frozen=True)
class ObservedContours:
    """Per view: contour points (M, 2) in camera pixels and their nearest-point index (None:
    no contour). ``cache``: what the matcher derives from them once per frame (the observed
    outline is the same for every iteration): the points' Plücker lines per rig
    (:meth:`ContourMatcher.observed_lines`), the grids packed for the compiled matcher
    (:func:`packed_grids`)."""

    points: list[np.ndarray]
    trees: list[NearestPoints | None]
    cache: dict = field(default_factory=dict, compare=False, repr=False)


def _cat(arrays: list[np.ndarray], dtype) -> np.ndarray:
    """np.concatenate, or an empty 1D array of ``dtype`` for no arrays."""
    return np.concatenate(arrays) if arrays else np.zeros(0, dtype)


def packed_grids(observed: ObservedContours) -> tuple:
    """The views' nearest-point grids in flat arrays (once per frame, kept in the cache):
    sorted coordinates xs, ys and ids (P,), bucket offsets (all views' in a row), the
    points (P, 2), per view (origin x, origin y, cell) (C, 3) and (nx, ny, first point,
    first offset, point count) (C, 5) int64; a view without a contour has point count 0."""
    if "grids" not in observed.cache:
        C = len(observed.points)
        fpar, ipar = np.zeros((C, 3)), np.zeros((C, 5), np.int64)
        xs, ys, ids, starts = [], [], [], []
        n_pts = n_start = 0
        for c, (pts, tree) in enumerate(zip(observed.points, observed.trees, strict=True)):
            if tree is None:
                ipar[c, 2:4] = n_pts, n_start
                continue
            fpar[c] = tree.origin[0], tree.origin[1], tree.cell
            ipar[c] = tree.nx, tree.ny, n_pts, n_start, len(pts)
            xs.append(tree.xs)
            ys.append(tree.ys)
            ids.append(tree.order)
            starts.append(tree.start)
            n_pts += len(pts)
            n_start += len(tree.start)
        points = [p for p in observed.points if len(p)]
        observed.cache["grids"] = (_cat(xs, np.float64), _cat(ys, np.float64), _cat(ids, np.int64),
                                   _cat(starts, np.int64),
                                   np.concatenate(points) if points else np.zeros((0, 2)), fpar, ipar)
    return observed.cache["grids"]


def observed_contours(masks: np.ndarray) -> ObservedContours:
    """Outline pixels of observed silhouettes (C, H, W) bool, once per frame."""
    pts, trees = [], []
    for m in masks:
        p = np.zeros((0, 2))
        u8 = np.ascontiguousarray(m, bool).view(np.uint8)
        x, y, w, h = cv2.boundingRect(u8)
        if w:      # on the mask's box grown by a pixel (clipped): the same contours (tested)
            x0, y0 = max(x - 1, 0), max(y - 1, 0)
            crop = u8[y0:min(y + h + 1, u8.shape[0]), x0:min(x + w + 1, u8.shape[1])].copy()
            contours, _ = cv2.findContours(crop, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE,
                                           offset=(x0, y0))
            if contours:
                p = np.concatenate([c[:, 0, :] for c in contours]).astype(np.float64)
        pts.append(p)
        trees.append(NearestPoints(p) if len(p) else None)
    return ObservedContours(pts, trees)


if HAVE_NUMBA:

    @njit(cache=True)
    def _contour_marks(verts, faces, centers, edge_faces, edge_vertices, ids, counts):
        """ids[c, :counts[c]] (increasing) = the vertices of edges whose two faces face opposite
        ways from centre c: the numpy path of :meth:`ContourMatcher.contour_vertices` in one
        pass, with its arithmetic (n . centroid - n . centre, each a 3-term sum in order); at
        most 64 views (:meth:`ContourMatcher.contour_ids` splits more)."""
        F = faces.shape[0]
        C = centers.shape[0]
        normal = np.empty((3, F))       # rows: the views' loop reads each one in order
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
            normal[0, f], normal[1, f], normal[2, f] = nx, ny, nz
            offset[f] = nx * cx + ny * cy + nz * cz
        # the views' facing signs as bits of one word per face (C <= 64), so that one pass
        # over the edges serves every view: the edges whose faces differ in some view's bit
        bits = np.zeros(F, np.uint64)
        n0, n1, n2 = normal[0], normal[1], normal[2]
        for k in range(C):
            px, py, pz = centers[k, 0], centers[k, 1], centers[k, 2]
            kk = np.uint64(k)
            for f in range(F):           # branch-free: vectorised
                below = offset[f] - (px * n0[f] + py * n1[f] + pz * n2[f]) < 0
                bits[f] |= np.uint64(below) << kk
        vbits = np.zeros(verts.shape[0], np.uint64)     # per vertex: the views it is marked in
        for e in range(edge_faces.shape[0]):            # branch-free (~half the edges cross)
            x = bits[edge_faces[e, 0]] ^ bits[edge_faces[e, 1]]
            vbits[edge_vertices[e, 0]] |= x
            vbits[edge_vertices[e, 1]] |= x
        for k in range(C):               # compacted without a branch
            kk = np.uint64(k)
            row = ids[k]
            n = 0
            for v in range(vbits.shape[0]):
                row[n] = v
                n += (vbits[v] >> kk) & np.uint64(1)
            counts[k] = n


if HAVE_NUMBA:

    @njit(cache=True)
    def _pixels_in_two_rigs(X, K, dist, distort, skew, out):
        """:func:`~mocap.cameras.pixels_from_camera` of camera coordinates X (C, 3, V) in two
        rigs that share R, t and distortion (the full-size one and the visibility one) in one
        pass: K (2, C, 3, 3), dist (C, 5), distort (apply the distortion model: some view
        has one), skew (2,) (add K[0, 1] y) -> out (2, C, V, 2); its arithmetic, op for op."""
        for c in range(X.shape[0]):
            k1, k2, p1, p2, k3 = dist[c, 0], dist[c, 1], dist[c, 2], dist[c, 3], dist[c, 4]
            for v in range(X.shape[2]):
                inv_z = 1.0 / X[c, 2, v]
                x = X[c, 0, v] * inv_z
                y = X[c, 1, v] * inv_z
                if distort:
                    x2, y2, xy = x * x, y * y, x * y
                    r2 = x2 + y2
                    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                    x, y = (x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2),
                            y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy)
                for r in range(2):
                    u = K[r, c, 0, 0] * x + K[r, c, 0, 2]
                    if skew[r]:
                        u += K[r, c, 0, 1] * y
                    out[r, c, v, 0] = u
                    out[r, c, v, 1] = K[r, c, 1, 1] * y + K[r, c, 1, 2]


if HAVE_NUMBA:

    @njit(cache=True)
    def _outline(m, r0, r1, c0, c1, pad):
        """The outline of mask m (h, w) bool, False outside the box rows [r0, r1), columns
        [c0, c1): its pixels with a 3 x 3 neighbour outside it, beyond the image's border
        counting as inside (cv2.erode's default), on that box grown by ``pad`` on every side
        (r1 - r0 + 2 pad, c1 - c0 + 2 pad) uint8 0 / 1 (0 outside the box).
        The erosion separably, across 3 columns, then across 3 rows (loops over slices from 0,
        which LLVM vectorises)."""
        h, w = m.shape
        bh, bw = r1 - r0, c1 - c0
        img = m.view(np.uint8)
        across = np.ones((bh + 2, bw), np.uint8)      # rows r0 - 1 .. r1; beyond the image: 1
        a, b = max(c0, 1), min(c1, w - 1)             # columns with both neighbours in the image
        for i in range(bh + 2):
            r = r0 - 1 + i
            if r < 0 or r >= h:
                continue
            src = img[r]
            left, mid, right = src[a - 1:b - 1], src[a:b], src[a + 1:b + 1]
            dst = across[i, a - c0:b - c0]
            for j in range(b - a):
                dst[j] = left[j] & mid[j] & right[j]
            if c0 == 0:                               # column -1 beyond the image: inside
                across[i, 0] = src[0] & src[min(1, w - 1)]
            if c1 == w and bw > 0 and (w > 1 or c0 != 0):
                across[i, bw - 1] = src[w - 1] & src[max(w - 2, 0)]
        out = np.zeros((bh + 2 * pad, bw + 2 * pad), np.uint8)
        for i in range(bh):
            o, here = out[pad + i, pad:pad + bw], img[r0 + i, c0:c1]
            up, at, down = across[i], across[i + 1], across[i + 2]
            for j in range(bw):
                o[j] = here[j] & ((up[j] & at[j] & down[j]) ^ 1)
        return out

    @njit(cache=True)
    def _visible_on_masks(ids, marked, px, masks, boxes, offsets, stride, out, count):
        """The numpy path's visibility (the band of :func:`outline_band`) without drawing the
        band: per view c, every ``stride``-th marked vertex (ids[c, :marked[c]]) whose pixel
        px[c] (V, 2), in the image and rounded half to even, has within ``offsets`` ((K, 2)
        (dy, dx): the tolerance's structuring element about its anchor) a pixel of the outline
        (:func:`_outline`, on the box grown by the element's radius) of masks[c] (h, w) bool,
        False outside boxes[c] (row0, row1, col0, col1) -> out[c, :count[c]]."""
        C = ids.shape[0]
        h, w = masks.shape[1], masks.shape[2]
        R = 0
        for t in range(offsets.shape[0]):
            R = max(R, abs(offsets[t, 0]), abs(offsets[t, 1]))
        for c in range(C):
            r0, r1, c0, c1 = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
            line = _outline(masks[c], r0, r1, c0, c1, R)
            # a pixel more than R outside the box has no outline pixel within the element
            gh, gw = r1 - r0 + R, c1 - c0 + R
            n = 0
            for i in range(0, marked[c], stride):
                v = ids[c, i]
                x = px[c, v, 0]
                y = px[c, v, 1]
                if not (x >= 0 and x <= w - 1 and y >= 0 and y <= h - 1):
                    continue
                u, r = int(np.rint(x)) - c0 + R, int(np.rint(y)) - r0 + R
                if r < R or r >= gh or u < R or u >= gw:
                    if r < 0 or r >= gh + R or u < 0 or u >= gw + R:
                        continue
                    # near the padded edge: the element may reach outside the padding
                    for t in range(offsets.shape[0]):
                        oy, ox = r + offsets[t, 0], u + offsets[t, 1]
                        if oy >= 0 and oy < gh + R and ox >= 0 and ox < gw + R and line[oy, ox]:
                            out[c, n] = v
                            n += 1
                            break
                    continue
                for t in range(offsets.shape[0]):      # unsigned: no negative-index tests
                    if line[np.uint64(r + offsets[t, 0]), np.uint64(u + offsets[t, 1])]:
                        out[c, n] = v
                        n += 1
                        break
            count[c] = n

if HAVE_NUMBA:

    @njit(cache=True)
    def _percentile90(x):
        """:func:`percentile90` compiled (x is reordered)."""
        n = x.shape[0]
        pos = 0.9 * (n - 1)
        lo = int(np.floor(pos))
        hi = min(lo + 1, n - 1)
        part = np.partition(x, lo)
        a = part[lo]
        b = a
        if hi > lo:                      # the next order statistic: the least above lo
            b = part[hi]
            for k in range(hi + 1, n):
                b = min(b, part[k])
        t = pos - lo
        return b - (b - a) * (1.0 - t) if t >= 0.5 else a + (b - a) * t

    @njit(cache=True)
    def _pair_views(vis, count, px, xs, ys, ids, starts, points, fpar, ipar, stride,
                    reject_factor, min_reject_px, max_distance_px, out_vid, out_oid, counts):
        """:meth:`ContourMatcher.pairs` for every view in one pass: vis (C, V) visible vertex
        ids (count (C,) of them per view), px (C, V, 2) their pixels, the observed grids of
        :func:`packed_grids`; writes the kept pairs (vertex, observed point) view by view,
        forward then backward, into out_vid, out_oid, their number per view into counts, and
        returns the total."""
        t = 0
        for c in range(vis.shape[0]):
            nv = count[c]
            nx, ny, first, first_start, m = ipar[c, 0], ipar[c, 1], ipar[c, 2], ipar[c, 3], ipar[c, 4]
            if m == 0 or nv == 0:
                counts[c] = 0
                continue
            p = np.empty((nv, 2))
            for k in range(nv):
                p[k, 0] = px[c, vis[c, k], 0]
                p[k, 1] = px[c, vis[c, k], 1]
            obs = points[first:first + m]
            nb = (m + stride - 1) // stride
            dist = np.empty(nv + nb)
            idx = np.empty(nv, np.int64)
            nearest_on_grid(xs[first:first + m], ys[first:first + m], ids[first:first + m],
                            starts[first_start:first_start + nx * ny + 1], fpar[c, 0], fpar[c, 1],
                            fpar[c, 2], nx, ny, 4, obs, p, dist[:nv], idx)
            q = np.empty((nb, 2))
            for j in range(nb):
                q[j, 0] = obs[j * stride, 0]
                q[j, 1] = obs[j * stride, 1]
            cell, bnx, bny, ox, oy, order, bstart, bxs, bys = bucket_grid(p, -1.0)
            back = np.empty(nb, np.int64)
            nearest_on_grid(bxs, bys, order, bstart, ox, oy, cell, bnx, bny, 4, p, q, dist[nv:], back)
            thr = min(max(reject_factor * _percentile90(dist.copy()), min_reject_px), max_distance_px)
            n = 0
            for k in range(nv):
                if dist[k] <= thr:
                    out_vid[t] = vis[c, k]
                    out_oid[t] = first + idx[k]
                    t += 1
                    n += 1
            for j in range(nb):
                if dist[nv + j] <= thr:
                    out_vid[t] = vis[c, back[j]]
                    out_oid[t] = first + j * stride
                    t += 1
                    n += 1
            counts[c] = n
        return t


if HAVE_NUMBA:

    @njit(cache=True)
    def _gather_pairs(vid, oid, verts, labels, obs_d, obs_m, X, limbs, D, M):
        """X, limbs = verts[vid], labels[vid]; D, M = obs_d[oid], obs_m[oid] (one pass: numpy's
        four fancy-indexing copies of ~12,000 rows cost ~0.9 ms)."""
        for n in range(vid.shape[0]):
            v, o = vid[n], oid[n]
            limbs[n] = labels[v]
            for k in range(3):
                X[n, k] = verts[v, k]
                D[n, k] = obs_d[o, k]
                M[n, k] = obs_m[o, k]


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


def outline_band(mask: np.ndarray, kernel3: np.ndarray, kernel_tol: np.ndarray,
                 box: tuple[int, int, int, int] | None = None, out: np.ndarray | None = None
                 ) -> np.ndarray:
    """(h, w) bool mask -> (h, w) uint8, nonzero within ``kernel_tol`` of the mask's outline
    (its pixels with a 3x3 neighbour outside it; beyond the image border counts as inside,
    cv2.erode's default): ``dilate(m - erode(m, kernel3), kernel_tol)``, taken on the mask's
    bounding box grown by the tolerance's radius + 1. The same image (tested): the crop's
    edge pixels are 0, so the erosion there does not depend on what lies beyond, and the
    dilated outline stays inside; zeros elsewhere. A person covers ~15 % of the frame.
    ``box`` (x, y, width, height): a box known to hold every mask pixel (the same image;
    default: ``cv2.boundingRect``); ``out``: an (h, w) uint8 image of zeros to write into."""
    m = np.ascontiguousarray(mask).view(np.uint8)
    out = np.zeros_like(m) if out is None else out
    x, y, bw, bh = cv2.boundingRect(m) if box is None else box
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
        self.two_K = np.ascontiguousarray(np.stack([self.small.K, rig.K]), np.float64)   # (2, C, 3, 3)
        self.two_skew = np.array([np.any(self.small.K[:, 0, 1]), np.any(rig.K[:, 0, 1])])
        self.raster = get_rasterizer(body.faces, body.num_vertices)
        r = int(np.ceil(visibility_tolerance_px))
        self.kernel3 = np.ones((3, 3), np.uint8)
        self.kernel_tol = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        # the tolerance's offsets (dy, dx) about its anchor, nearest first (the search stops
        # at the first outline pixel)
        off = np.argwhere(self.kernel_tol > 0) - np.array(self.kernel_tol.shape) // 2
        self.tol_offsets = np.ascontiguousarray(off[np.argsort((off**2).sum(1), kind="stable")],
                                                np.int64)
        self.kept: dict[int, KeptMasks] = {}   # thread id -> its model masks kept between calls (compiled)
        self.reject_factor, self.min_reject_px = reject_factor, min_reject_px
        self.max_distance_px = max_distance * float(rig.sizes[0][1])
        self.stride, self.observed_stride = stride, observed_stride

    def pixels(self, cam_xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Camera coordinates (C, 3, V) -> pixels (C, V, 2) in the visibility rig and in the
        rig, and the depth (C, V) (compiled in one pass where the coordinates are float64:
        :func:`_pixels_in_two_rigs`, the same floats)."""
        if not (HAVE_NUMBA and cam_xyz.dtype == np.float64):
            px_small, depth = pixels_from_camera(self.small, cam_xyz)
            return px_small, pixels_from_camera(self.rig, cam_xyz)[0], depth
        out = np.empty((2, cam_xyz.shape[0], cam_xyz.shape[2], 2))
        _pixels_in_two_rigs(np.ascontiguousarray(cam_xyz), self.two_K, self.rig.dist.astype(np.float64),
                            bool(np.any(self.rig.dist)), self.two_skew, out)
        return out[0], out[1], cam_xyz[:, 2, :]

    def model_masks(self, px_small: np.ndarray, depth_small: np.ndarray) -> np.ndarray:
        """The model's silhouettes (C, h, w) bool in the visibility rig from its pixels (C, V, 2)
        and depths (C, V) (faces with a vertex at depth <= 0.05 culled). Compiled: drawn into
        masks kept between calls (:class:`~mocap.render._compiled.KeptMasks`: only the last
        call's boxes cleared and scanned; the array returned is overwritten by the next call of
        the same thread: each thread calling a matcher has masks of its own, so threads may
        share one); the rasterizer's checks where a pixel is not finite."""
        h, w = self.small_size
        px_small = np.asarray(px_small, np.float64)
        if not (HAVE_NUMBA and self.raster.compiled and np.isfinite(px_small).all()):
            return self.raster(px_small, h, w, depth_small, near=0.05)
        kept = self.kept.get(threading.get_ident())
        if kept is None or kept.masks.shape[0] != len(px_small):
            kept = self.kept[threading.get_ident()] = KeptMasks(len(px_small), h, w)
        faces, edges = self.raster.kernel_arrays
        return kept.draw(np.ascontiguousarray(px_small[..., 0]), np.ascontiguousarray(px_small[..., 1]),
                         np.ascontiguousarray(depth_small > 0.05), faces, edges)

    def contour_ids(self, verts: np.ndarray, centers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The vertices on the contour generator seen from each camera centre (C, 3): ids
        (C, V), row c's first counts[c] (C,) in increasing order (compiled:
        :func:`_contour_marks`)."""
        ids = np.empty((len(centers), len(verts)), np.int64)
        counts = np.zeros(len(centers), np.int64)
        verts = np.ascontiguousarray(verts, np.float64)
        centers = np.ascontiguousarray(centers, np.float64)
        for s in range(0, len(centers), 64):
            _contour_marks(verts, self.faces64, centers[s:s + 64], self.edge_faces,
                           self.edge_vertices, ids[s:s + 64], counts[s:s + 64])
        return ids, counts

    def contour_vertices(self, verts: np.ndarray, centers: np.ndarray) -> list[np.ndarray]:
        """Vertex ids on the contour generator seen from each camera centre (C, 3)."""
        if HAVE_NUMBA:
            ids, counts = self.contour_ids(verts, centers)
            return [ids[c, :counts[c]].copy() for c in range(len(centers))]
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

    def visible_contour_vertices(self, verts: np.ndarray, px_small: np.ndarray,
                                 model_masks: np.ndarray) -> list[np.ndarray]:
        """Per view the ids of the contour-generator vertices (every ``stride``-th) that are
        visible: in the image, and projecting (px_small (C, V, 2), rounded) onto the outline
        band of the model's own silhouette (model_masks (C, h, w)). Compiled: one pass over all
        views that looks for an outline pixel around each vertex (:func:`_visible_on_masks`, no
        band image); otherwise :func:`outline_band` per view."""
        h, w = self.small_size
        if HAVE_NUMBA:
            out, count = self._visible_compiled(verts, px_small, model_masks)
            return [out[c, :count[c]] for c in range(len(out))]
        visible = []
        for c, vid in enumerate(self.contour_vertices(verts, self.rig.centers)):
            vid = vid[:: self.stride]
            near_outline = outline_band(model_masks[c], self.kernel3, self.kernel_tol)
            ps = px_small[c, vid]
            inside = (ps[:, 0] >= 0) & (ps[:, 0] <= w - 1) & (ps[:, 1] >= 0) & (ps[:, 1] <= h - 1)
            vid, ps = vid[inside], ps[inside]
            ui, vi = np.round(ps).astype(int).T
            visible.append(vid[near_outline[vi, ui] > 0])
        return visible

    def _visible_compiled(self, verts: np.ndarray, px_small: np.ndarray, model_masks: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`visible_contour_vertices` compiled, as arrays: ids (C, V), row c's first
        count[c] (C,) visible."""
        h, w = self.small_size
        ids, marked = self.contour_ids(verts, self.rig.centers)
        out = np.empty(ids.shape, np.int64)
        count = np.zeros(len(ids), np.int64)
        kept = self.kept.get(threading.get_ident())
        if kept is not None and model_masks is kept.masks:
            boxes = kept.boxes
        else:
            boxes = np.zeros((len(ids), 4), np.int64)
            boxes[:, 1], boxes[:, 3] = h, w
        _visible_on_masks(ids, marked, np.ascontiguousarray(px_small, np.float64),
                          np.ascontiguousarray(model_masks), boxes, self.tol_offsets,
                          self.stride, out, count)
        return out, count

    def observed_lines(self, observed: ObservedContours) -> tuple[np.ndarray, np.ndarray]:
        """Plücker lines (directions, moments; (P, 3) each) of every observed contour point,
        the views' points one after the other, back-projected in one call for all views (the
        views padded to one length with their principal point), once per frame: kept in
        ``observed.cache``."""
        cached = observed.cache.get(("lines", id(self.rig)))
        if cached is not None and cached[0] is self.rig:
            return cached[1], cached[2]
        n = max((len(q) for q in observed.points), default=0)
        if n == 0:
            return np.zeros((0, 3)), np.zeros((0, 3))
        px = np.broadcast_to(self.rig.K[:, :2, 2][:, None, :], (len(self.rig), n, 2)).copy()
        for c, q in enumerate(observed.points):
            px[c, : len(q)] = q
        d, mo = plucker_from_rays(*pixel_rays(self.rig, px))
        lines = (np.concatenate([d[c, : len(q)] for c, q in enumerate(observed.points)]),
                 np.concatenate([mo[c, : len(q)] for c, q in enumerate(observed.points)]))
        observed.cache[("lines", id(self.rig))] = (self.rig, *lines)
        return lines

    def pairs(self, px: np.ndarray, visible: list[np.ndarray], observed: ObservedContours
              ) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """Matched pairs, both directions: each visible model contour point (px (C, V, 2)
        full-size pixels, ``visible`` the ids per view) to its closest observed contour point,
        and each ``observed_stride``-th observed contour point to its closest model contour
        point, so that observed outline no model part explains still pulls the model; pairs
        farther than the rejection threshold dropped. Returns vertex ids (N,), observed point
        ids (N,) (into the views' points one after the other) and the count per view.
        Compiled: one pass over all views (:func:`_pair_views`)."""
        if HAVE_NUMBA:
            count = np.array([len(v) for v in visible], np.int64)
            vis = np.zeros((len(visible), max(1, int(count.max()))), np.int64)
            for c, v in enumerate(visible):
                vis[c, :len(v)] = v
            return self._pairs_compiled(px, vis, count, observed)
        vids, oids, counts = [], [], []
        first = 0
        for c, vid in enumerate(visible):
            tree, obs = observed.trees[c], observed.points[c]
            if tree is None or len(vid) == 0:
                counts.append(0)
                first += len(obs)
                continue
            p = px[c, vid]
            dist, idx = tree.query(p)
            obs_ids = np.arange(0, len(obs), self.observed_stride)
            back_dist, back_idx = NearestPoints(p).query(obs[obs_ids])
            vid = np.concatenate([vid, vid[back_idx]])
            oid = np.concatenate([idx, obs_ids])           # the observed points paired
            dist = np.concatenate([dist, back_dist])
            thr = min(max(self.reject_factor * percentile90(dist), self.min_reject_px),
                      self.max_distance_px)
            keep = dist <= thr
            vids.append(vid[keep])
            oids.append(oid[keep] + first)
            counts.append(int(keep.sum()))
            first += len(obs)
        return _cat(vids, np.int64), _cat(oids, np.int64), counts

    def _pairs_compiled(self, px: np.ndarray, vis: np.ndarray, count: np.ndarray,
                        observed: ObservedContours) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """:meth:`pairs` compiled, the visible ids as arrays (vis (C, n), count (C,))."""
        xs, ys, ids, starts, points, fpar, ipar = packed_grids(observed)
        m = ipar[:, 4]
        size = int(np.where((m > 0) & (count > 0), count + -(-m // self.observed_stride), 0).sum())
        vid, oid = np.empty(size, np.int64), np.empty(size, np.int64)
        counts = np.zeros(len(count), np.int64)
        n = _pair_views(vis, count, np.ascontiguousarray(px, np.float64), xs, ys, ids, starts,
                        points, fpar, ipar, self.observed_stride, self.reject_factor,
                        self.min_reject_px, self.max_distance_px, vid, oid, counts)
        return vid[:n], oid[:n], counts.tolist()

    def __call__(self, verts: np.ndarray, observed: ObservedContours) -> tuple[PointLines, dict]:
        """Correspondences for posed vertices (V, 3); diagnostics: per-view counts, and the
        views without an observed contour."""
        h, w = self.small_size
        # camera coordinates once: the visibility rig (rescaled) shares R, t with the rig
        cam_xyz = camera_coordinates(self.rig, verts)                   # (C, 3, V)
        px_small, px, depth_small = self.pixels(cam_xyz)
        model_masks = self.model_masks(px_small, depth_small)
        if HAVE_NUMBA:
            vid, oid, counts = self._pairs_compiled(
                px, *self._visible_compiled(verts, px_small, model_masks), observed)
        else:
            vid, oid, counts = self.pairs(
                px, self.visible_contour_vertices(verts, px_small, model_masks), observed)
        empty = [self.rig.names[c] for c, t in enumerate(observed.trees) if t is None]
        if len(vid) and HAVE_NUMBA:
            X, D, M = np.empty((len(vid), 3)), np.empty((len(vid), 3)), np.empty((len(vid), 3))
            labels = self.body.part_labels
            limbs = np.empty(len(vid), labels.dtype)
            _gather_pairs(vid, oid, np.ascontiguousarray(verts, np.float64), labels,
                          *self.observed_lines(observed), X, limbs, D, M)
            corr = PointLines(X, limbs, D, M, np.ones(len(vid)))
        elif len(vid):
            obs_d, obs_m = self.observed_lines(observed)
            corr = PointLines(verts[vid].astype(np.float64), self.body.part_labels[vid],
                              obs_d[oid], obs_m[oid], np.ones(len(vid)))
        else:
            z = np.zeros((0, 3))
            corr = PointLines(z, np.zeros(0, int), z, z, np.zeros(0))
        return corr, {"contour_per_view": counts, "views_without_contour": empty}
