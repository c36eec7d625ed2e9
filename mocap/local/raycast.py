"""First hits of rays from one point (a camera centre) on a triangle mesh, compiled (numba).

The SIFT correspondences attach keypoints to the body by casting their pixel rays onto the
posed mesh (Zhang et al. 2013, Sec. 4.1). A general ray caster (trimesh's, over an R-tree it
rebuilds for every posed mesh) spent ~1 s per frame there. Rays that share their origin need
no 3D tree: seen from that origin each triangle covers a region of ray directions, so a grid
over the rays' directions (x/z, y/z in a frame looking along their mean) holds, per cell, the
triangles whose direction box touches it; each ray then runs the exact Möller-Trumbore test
on its cell's triangles only and keeps the nearest hit in front of the origin. Triangles
not wholly in front of the origin's plane facing that mean direction are tested by every
ray (none for a camera looking at a body), and so is every triangle when the rays spread
wider than ~85 degrees around their mean.
"""

from __future__ import annotations

import numpy as np

from mocap.compiled import HAVE_NUMBA, njit

_EPS = 1e-12
_TOL = 1e-9      # barycentric slack: a ray through an edge or a vertex hits one of its triangles


if HAVE_NUMBA:

    @njit(cache=True, inline="always")
    def _hit(o, d, verts, a, b, c):
        """Möller-Trumbore, in scalars: (t, u, v) of the ray o + t d on triangle (a, b, c) of
        verts; t = inf where it misses (parallel, outside by more than _TOL, or behind the
        origin)."""
        ax, ay, az = verts[a, 0], verts[a, 1], verts[a, 2]
        e1x, e1y, e1z = verts[b, 0] - ax, verts[b, 1] - ay, verts[b, 2] - az
        e2x, e2y, e2z = verts[c, 0] - ax, verts[c, 1] - ay, verts[c, 2] - az
        px, py, pz = d[1] * e2z - d[2] * e2y, d[2] * e2x - d[0] * e2z, d[0] * e2y - d[1] * e2x
        det = e1x * px + e1y * py + e1z * pz
        if abs(det) < _EPS:
            return np.inf, 0.0, 0.0
        inv = 1.0 / det
        sx, sy, sz = o[0] - ax, o[1] - ay, o[2] - az
        u = (sx * px + sy * py + sz * pz) * inv
        if u < -_TOL or u > 1.0 + _TOL:
            return np.inf, 0.0, 0.0
        qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
        v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv
        if v < -_TOL or u + v > 1.0 + _TOL:
            return np.inf, 0.0, 0.0
        t = (e2x * qx + e2y * qy + e2z * qz) * inv
        if t <= 0.0:
            return np.inf, 0.0, 0.0
        return t, u, v

    @njit(cache=True)
    def _first_hits(verts, faces, origin, dirs, axes, grid, brute, tri_out, t_out, bary_out):
        M = dirs.shape[0]
        F = faces.shape[0]
        # ray directions in the frame (axes rows: x, y, z = mean direction) as x/z, y/z
        rx = np.empty(M)
        ry = np.empty(M)
        for i in range(M):
            dz = max(dirs[i] @ axes[2], 1e-9)          # brute: any value will do
            rx[i] = (dirs[i] @ axes[0]) / dz
            ry[i] = (dirs[i] @ axes[1]) / dz
        x0, x1, y0, y1 = rx.min(), rx.max(), ry.min(), ry.max()
        cw = max((x1 - x0) / grid, 1e-9)
        ch = max((y1 - y0) / grid, 1e-9)
        # each triangle's direction box -> cells (two passes: counts, then a CSR fill)
        lo = np.full((F, 2), -1, np.int64)
        hi = np.full((F, 2), -2, np.int64)
        always = np.zeros(F, np.bool_)
        for f in range(F):
            bx0 = np.inf
            bx1 = -np.inf
            by0 = np.inf
            by1 = -np.inf
            front = True
            for k in range(3):
                r0 = verts[faces[f, k], 0] - origin[0]
                r1 = verts[faces[f, k], 1] - origin[1]
                r2 = verts[faces[f, k], 2] - origin[2]
                z = r0 * axes[2, 0] + r1 * axes[2, 1] + r2 * axes[2, 2]
                if z <= 1e-9:
                    front = False
                    break
                x = (r0 * axes[0, 0] + r1 * axes[0, 1] + r2 * axes[0, 2]) / z
                y = (r0 * axes[1, 0] + r1 * axes[1, 1] + r2 * axes[1, 2]) / z
                bx0, bx1 = min(bx0, x), max(bx1, x)
                by0, by1 = min(by0, y), max(by1, y)
            if not front or brute:
                always[f] = True
                continue
            bx0, bx1, by0, by1 = bx0 - 1e-7, bx1 + 1e-7, by0 - 1e-7, by1 + 1e-7
            if bx1 < x0 or bx0 > x1 or by1 < y0 or by0 > y1:
                continue
            lo[f, 0] = max(0, int((bx0 - x0) / cw))
            hi[f, 0] = min(grid - 1, int((bx1 - x0) / cw))
            lo[f, 1] = max(0, int((by0 - y0) / ch))
            hi[f, 1] = min(grid - 1, int((by1 - y0) / ch))
        start = np.zeros(grid * grid + 1, np.int64)
        for f in range(F):
            for a in range(lo[f, 0], hi[f, 0] + 1):
                for b in range(lo[f, 1], hi[f, 1] + 1):
                    start[a * grid + b + 1] += 1
        for c in range(grid * grid):
            start[c + 1] += start[c]
        fill = start[:-1].copy()
        cells = np.empty(start[-1], np.int64)
        for f in range(F):
            for a in range(lo[f, 0], hi[f, 0] + 1):
                for b in range(lo[f, 1], hi[f, 1] + 1):
                    cells[fill[a * grid + b]] = f
                    fill[a * grid + b] += 1
        extra = np.flatnonzero(always)
        for i in range(M):
            a = min(grid - 1, max(0, int((rx[i] - x0) / cw)))
            b = min(grid - 1, max(0, int((ry[i] - y0) / ch)))
            c = a * grid + b
            best, bu, bv, bf = np.inf, 0.0, 0.0, -1
            for n in range(start[c], start[c + 1] + extra.size):
                f = cells[n] if n < start[c + 1] else extra[n - start[c + 1]]
                t, u, v = _hit(origin, dirs[i], verts, faces[f, 0], faces[f, 1], faces[f, 2])
                if t < best:
                    best, bu, bv, bf = t, u, v, f
            tri_out[i] = bf
            t_out[i] = best
            bary_out[i, 0] = 1.0 - bu - bv
            bary_out[i, 1] = bu
            bary_out[i, 2] = bv


def _frame(dirs: np.ndarray) -> np.ndarray:
    """Rows x, y, z: z the mean ray direction, x, y completing a right-handed frame."""
    z = dirs.mean(axis=0)
    z /= np.linalg.norm(z)
    helper = np.eye(3)[np.argmin(np.abs(z))]
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def first_hits(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray, directions: np.ndarray,
               grid: int = 48) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit of each ray origin + t d (t > 0) on the mesh.

    vertices (V, 3), faces (F, 3), origin (3,), directions (M, 3) (any length). Returns
    (rays (H,) the ids of the rays that hit, triangles (H,), points (H, 3)) like trimesh's
    ``intersects_location(..., multiple_hits=False)``, and barycentric coordinates (H, 3)
    of the points in their triangles.
    """
    if not HAVE_NUMBA:
        raise RuntimeError("first_hits needs numba")
    verts = np.ascontiguousarray(vertices, np.float64)
    dirs = np.asarray(directions, np.float64)
    if dirs.ndim != 2 or dirs.shape[1] != 3:
        raise ValueError(f"directions must be (M, 3), got {dirs.shape}")
    empty = np.zeros(0, np.int64)
    if len(dirs) == 0:
        return empty, empty, np.zeros((0, 3)), np.zeros((0, 3))
    dirs = np.ascontiguousarray(dirs / np.linalg.norm(dirs, axis=1, keepdims=True))
    origin = np.ascontiguousarray(origin, np.float64)
    M = len(dirs)
    axes = _frame(dirs)
    # rays wider than ~85 degrees around their mean: no direction grid, every triangle tested
    brute = bool((dirs @ axes[2]).min() < 0.1)
    tri, t, bary = np.empty(M, np.int64), np.empty(M), np.empty((M, 3))
    _first_hits(verts, np.ascontiguousarray(faces, np.int64), origin, dirs, axes, int(grid), brute,
                tri, t, bary)
    hit = np.flatnonzero(tri >= 0)
    bary = np.clip(bary[hit], 0.0, None)
    return hit, tri[hit], origin + t[hit, None] * dirs[hit], bary / bary.sum(axis=1, keepdims=True)
