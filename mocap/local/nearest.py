"""Exact nearest neighbours of 2D points (pixels) on a uniform grid of buckets, compiled.

The contour matcher asks, eight views x ten iterations per frame, for the closest observed
contour pixel of ~1500 model contour points and the closest model point of ~500 observed
ones. ``scipy.spatial.cKDTree`` answers at ~1 us per query from Python, which was 40 % of
the local tracker's time; points on an image outline are spread evenly over a plane, where
buckets of a few pixels answer the same question in a few dozen operations.

Each query scans the rings of buckets around its own (the bucket of the query clamped into
the grid) outwards, a ring's top and bottom rows each as one run of the points sorted by
bucket; every point not yet seen lies in a bucket outside the scanned square, at least the
query's distance to the nearest side of the square that is not the grid's edge away, so
the scan stops once the best distance is below that. A query still unsettled after
``max_ring`` rings (far from every point: a lost limb, a pose hypothesis far off) is
answered by brute force over all points instead. The answer is the exact nearest point
(ties, which need a query exactly equidistant from two points, go to the lowest index);
distances are Euclidean. Without numba every query runs on cKDTree (said once; its ties
may go to another of the equidistant points).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mocap.compiled import HAVE_NUMBA, njit
from mocap.energy.fallback import warn_once

if HAVE_NUMBA:

    @njit(cache=True)
    def _query(xs, ys, ids, start, origin_x, origin_y, cell, nx, ny, max_ring, queries, dist, idx):
        """xs, ys (M,) the points' coordinates sorted by bucket, ids (M,) their ids; start
        (nx * ny + 1,) bucket offsets (bucket b = iy * nx + ix); queries (N, 2) -> dist, idx;
        a query not settled within ``max_ring`` rings gets idx -1 (the caller asks the k-d
        tree: far queries would scan many empty buckets). A ring's top and bottom rows are
        each one run of the sorted points."""
        inv = 1.0 / cell
        for n in range(queries.shape[0]):
            qx = queries[n, 0]
            qy = queries[n, 1]
            cx = int(min(max(np.floor((qx - origin_x) * inv), 0.0), nx - 1.0))
            cy = int(min(max(np.floor((qy - origin_y) * inv), 0.0), ny - 1.0))
            best = np.inf
            best_i = -1
            r = 0
            while True:
                x_lo, x_hi, y_lo, y_hi = cx - r, cx + r, cy - r, cy + r
                for iy in range(max(y_lo, 0), min(y_hi, ny - 1) + 1):
                    edge = iy == y_lo or iy == y_hi
                    for side in range(1 if edge else 2):
                        # the row's run of buckets: all of it on the top and bottom rows,
                        # else its first and its last bucket
                        a = max(x_lo, 0) if edge else (x_lo if side == 0 else x_hi)
                        b = min(x_hi, nx - 1) if edge else a
                        if a < 0 or b >= nx:
                            continue
                        # unsigned: no negative-index test per point
                        for k in range(np.uint64(start[iy * nx + a]), np.uint64(start[iy * nx + b + 1])):
                            dx = xs[k] - qx
                            dy = ys[k] - qy
                            d = dx * dx + dy * dy
                            i = ids[k]
                            if d < best or (d == best and i < best_i):
                                best = d
                                best_i = i
                # a point not yet seen lies in a bucket outside the scanned square, beyond one
                # of its sides that is not the grid's edge: at least ``gap`` away
                gap = np.inf
                if x_lo > 0:
                    gap = min(gap, qx - (origin_x + x_lo * cell))
                if x_hi < nx - 1:
                    gap = min(gap, origin_x + (x_hi + 1) * cell - qx)
                if y_lo > 0:
                    gap = min(gap, qy - (origin_y + y_lo * cell))
                if y_hi < ny - 1:
                    gap = min(gap, origin_y + (y_hi + 1) * cell - qy)
                if gap == np.inf:             # the whole grid seen
                    break
                gap -= 1e-7                   # the bucket arithmetic's rounding (pixels ~1e3)
                if best_i >= 0 and gap > 0 and best < gap * gap:
                    break
                if r >= max_ring:
                    best_i = -1
                    break
                r += 1
            dist[n] = np.sqrt(best)
            idx[n] = best_i


if HAVE_NUMBA:

    @njit(cache=True)
    def nearest_on_grid(xs, ys, ids, start, origin_x, origin_y, cell, nx, ny, max_ring, points,
                        queries, dist, idx):
        """:func:`_query`, and the queries it leaves unsettled (far from every point) by
        brute force over points (M, 2) (ties to the lower id): the exact nearest point of
        every query, for compiled callers (no k-d tree)."""
        _query(xs, ys, ids, start, origin_x, origin_y, cell, nx, ny, max_ring, queries, dist, idx)
        for n in range(queries.shape[0]):
            if idx[n] >= 0:
                continue
            best = np.inf
            best_i = -1
            for i in range(points.shape[0]):
                dx = points[i, 0] - queries[n, 0]
                dy = points[i, 1] - queries[n, 1]
                d = dx * dx + dy * dy
                if d < best:
                    best = d
                    best_i = i
            dist[n] = np.sqrt(best)
            idx[n] = best_i


if HAVE_NUMBA:

    @njit(cache=True)
    def bucket_grid(points, cell):
        """The grid over points (M, 2): cell (the argument where > 0, else ~2 points per
        bucket), nx, ny, origin (x, y), and the point ids ordered by bucket (a stable
        counting sort: the order of a stable argsort) with each bucket's start offset.
        One call instead of a dozen numpy ones (the matcher builds one grid per view and
        iteration)."""
        lo_x = hi_x = points[0, 0]
        lo_y = hi_y = points[0, 1]
        for i in range(1, points.shape[0]):
            lo_x = min(lo_x, points[i, 0])
            hi_x = max(hi_x, points[i, 0])
            lo_y = min(lo_y, points[i, 1])
            hi_y = max(hi_y, points[i, 1])
        ex = max(hi_x - lo_x, 1.0)
        ey = max(hi_y - lo_y, 1.0)
        # about 2 points per bucket on an outline (points spread along a curve, not an area)
        if cell <= 0:
            cell = max(2.0, np.sqrt(ex * ey / max(points.shape[0] / 2.0, 1.0)))
        nx = int(ex // cell) + 1
        ny = int(ey // cell) + 1
        inv = 1.0 / cell                      # the query's bucket arithmetic, exactly
        bucket = np.empty(points.shape[0], np.int64)
        start = np.zeros(nx * ny + 1, np.int64)
        for i in range(points.shape[0]):
            ix = int(min(max(np.floor((points[i, 0] - lo_x) * inv), 0.0), nx - 1.0))
            iy = int(min(max(np.floor((points[i, 1] - lo_y) * inv), 0.0), ny - 1.0))
            bucket[i] = iy * nx + ix
            start[bucket[i] + 1] += 1
        for b in range(nx * ny):
            start[b + 1] += start[b]
        fill = start[:-1].copy()
        order = np.empty(points.shape[0], np.int64)
        xs = np.empty(points.shape[0])
        ys = np.empty(points.shape[0])
        for i in range(points.shape[0]):
            k = fill[bucket[i]]
            order[k] = i
            xs[k] = points[i, 0]
            ys[k] = points[i, 1]
            fill[bucket[i]] += 1
        return cell, nx, ny, lo_x, lo_y, order, start, xs, ys


class NearestPoints:
    """Nearest-neighbour index over points (M, 2) (M >= 1); ``query(q)`` -> (dist (N,),
    idx (N,)) like ``cKDTree(points).query(q)``."""

    def __init__(self, points: np.ndarray, cell: float | None = None, max_ring: int = 4):
        pts = np.ascontiguousarray(points, np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
            raise ValueError(f"points must be a non-empty (M, 2) array, got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("points must be finite")
        self.points = pts
        self.compiled = HAVE_NUMBA
        self.max_ring = int(max_ring)
        self._tree: cKDTree | None = None
        if not self.compiled:
            warn_once("nearest", "contour matching queries a k-d tree (cKDTree), slower")
            return
        cell, self.nx, self.ny, ox, oy, self.order, self.start, self.xs, self.ys = bucket_grid(
            pts, -1.0 if cell is None else float(cell))
        self.cell = float(cell)
        self.origin = np.array([ox, oy])

    def query(self, queries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q = np.ascontiguousarray(queries, np.float64).reshape(-1, 2)
        if not np.all(np.isfinite(q)):
            raise ValueError("queries must be finite")
        if not self.compiled:
            return self.tree.query(q)
        dist = np.empty(len(q))
        idx = np.empty(len(q), np.int64)
        nearest_on_grid(self.xs, self.ys, self.order, self.start, float(self.origin[0]),
                        float(self.origin[1]), self.cell, self.nx, self.ny, self.max_ring,
                        self.points, q, dist, idx)
        return dist, idx

    @property
    def tree(self) -> cKDTree:
        """The k-d tree over the same points (built on first use): the answer without numba."""
        if self._tree is None:
            self._tree = cKDTree(self.points)
        return self._tree
