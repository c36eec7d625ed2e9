"""Vectorised nonzero-winding rasterization of a triangle mesh's projected union.

Why it is exact: orient every projected triangle counter-clockwise (flip the ones that
project clockwise). The sum of their boundaries is a 2D edge chain whose winding number at a
point equals the number of triangles covering it, so "winding != 0" is the union of all
triangles. In that sum an edge shared by two triangles of the same orientation cancels; only
edges whose adjacent faces project with opposite orientation (the contour generator of a
closed mesh), mesh-boundary edges and edges next to culled faces survive, with weight
``o_forward - o_backward`` (``o`` = +1 / -1 / 0 for counter-clockwise / clockwise / culled or
degenerate). For the body that is ~750 of 15,000 edges per view, which are scan-converted
all at once over a batch of views.

Scan conversion runs along columns: an edge crosses column ``j`` when
``x_lo <= j < x_hi`` (half-open, so a vertex shared by two edges counts once); it adds its
weight to every pixel centre at or below the crossing, ``i >= y_cross``. The increments are
scattered into an int16 image and accumulated down the rows; pixels with a nonzero sum are in
(the sum counts covering triangles, so int16 holds any realistic depth complexity).
A pixel centre exactly on the union's boundary is in on top/left edges and out on
bottom/right ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EdgeTable:
    """Undirected edges of a triangle mesh and the faces on either side.

    a, b: (E,) vertex ids with a < b. forward, backward: (E, K) ids of faces that traverse
    the edge as a->b / b->a, padded with F (the number of faces, a slot that is always 0).
    K is 1 for a consistently oriented manifold mesh.
    """

    a: np.ndarray
    b: np.ndarray
    forward: np.ndarray
    backward: np.ndarray
    num_faces: int
    num_vertices: int

    @classmethod
    def from_faces(cls, faces: np.ndarray, num_vertices: int) -> EdgeTable:
        """faces: (F, 3) int vertex ids in [0, num_vertices)."""
        faces = np.asarray(faces, dtype=np.int64)
        n_f = len(faces)
        half = faces[:, [0, 1, 1, 2, 2, 0]].reshape(n_f * 3, 2)
        face_of = np.repeat(np.arange(n_f), 3)
        fwd = half[:, 0] < half[:, 1]
        lo = np.minimum(half[:, 0], half[:, 1])
        hi = np.maximum(half[:, 0], half[:, 1])
        keep = lo != hi                       # a repeated vertex id: a degenerate "edge"
        lo, hi, fwd, face_of = lo[keep], hi[keep], fwd[keep], face_of[keep]
        key = lo * num_vertices + hi
        uniq, inv = np.unique(key, return_inverse=True)
        sides = []
        for direction in (fwd, ~fwd):
            ids, slot_face = inv[direction], face_of[direction]
            order = np.argsort(ids, kind="stable")
            ids, slot_face = ids[order], slot_face[order]
            counts = np.bincount(ids, minlength=len(uniq))
            k = max(1, int(counts.max(initial=0)))
            slot = np.arange(len(ids)) - np.repeat(np.cumsum(counts) - counts, counts)
            table = np.full((len(uniq), k), n_f, dtype=np.intp)
            table[ids, slot] = slot_face
            sides.append(table)
        return cls(a=uniq // num_vertices, b=uniq % num_vertices, forward=sides[0],
                   backward=sides[1], num_faces=n_f, num_vertices=num_vertices)


def face_orientation(x: np.ndarray, y: np.ndarray, faces: np.ndarray,
                     culled: np.ndarray | None, block: int = 2048) -> np.ndarray:
    """Sign of each projected triangle's area: +1 counter-clockwise in (x, y), -1 clockwise,
    0 degenerate or culled.

    Vertex-major layout (gathering whole rows is ~5x faster than gathering columns):
    x, y: (V, N); faces: (F, 3); culled: (F, N) bool or None -> (F + 1, N) int8, last row 0.
    Faces are processed ``block`` at a time so the per-face temporaries stay in cache.
    """
    out = np.zeros((len(faces) + 1, x.shape[1]), dtype=np.int8)
    for s in range(0, len(faces), block):
        f = faces[s:s + block]
        x0, x1, x2 = (np.take(x, f[:, k], axis=0) for k in range(3))
        y0, y1, y2 = (np.take(y, f[:, k], axis=0) for k in range(3))
        x1 -= x0
        x2 -= x0
        y1 -= y0
        y2 -= y0
        lhs = np.multiply(x1, y2, out=x1)
        rhs = np.multiply(y1, x2, out=y1)
        pos = lhs > rhs
        neg = lhs < rhs
        if culled is not None:
            keep = ~culled[s:s + block]
            pos &= keep
            neg &= keep
        np.subtract(pos.view(np.int8), neg.view(np.int8), out=out[s:s + len(f)])
    return out


def edge_weights(orient: np.ndarray, edges: EdgeTable) -> np.ndarray:
    """orient: (F + 1, N) int8 -> (E, N) int8 winding weight of each edge taken as a->b."""
    w = np.take(orient, edges.forward[:, 0], axis=0)
    w -= np.take(orient, edges.backward[:, 0], axis=0)
    for k in range(1, edges.forward.shape[1]):
        w += np.take(orient, edges.forward[:, k], axis=0)
    for k in range(1, edges.backward.shape[1]):
        w -= np.take(orient, edges.backward[:, k], axis=0)
    return w


def rasterize_chunk(x: np.ndarray, y: np.ndarray, edges: EdgeTable, faces: np.ndarray,
                    height: int, width: int, culled: np.ndarray | None,
                    out: np.ndarray) -> None:
    """Union of the non-culled triangles of N views, sampled at pixel centres.

    x, y: (V, N) C-contiguous pixel coordinates (vertex-major); faces: (F, 3);
    culled: (F, N) bool or None; out: (N, height, width) bool, written in place.
    """
    n = x.shape[1]
    w = edge_weights(face_orientation(x, y, faces, culled), edges)
    flat = np.flatnonzero(w != 0)                   # = edge * n + view
    weight = np.take(w, flat).astype(np.int16)
    edge = flat // n
    view = flat - edge * n
    ia = edges.a[edge] * n + view
    ib = edges.b[edge] * n + view
    xa, xb = np.take(x, ia), np.take(x, ib)
    # Columns crossed: ceil(x_lo) <= j < ceil(x_hi), clipped to the image.
    c_lo = np.ceil(np.clip(np.minimum(xa, xb), 0, width))
    count = np.ceil(np.clip(np.maximum(xa, xb), 0, width))
    count -= c_lo
    keep = np.flatnonzero(count)
    if len(keep) == 0:
        out[...] = False
        return
    ia, ib, view, weight = ia[keep], ib[keep], view[keep], weight[keep]
    c_lo, count = c_lo[keep].astype(np.intp), count[keep].astype(np.intp)
    xa, xb = xa[keep].astype(np.float64), xb[keep].astype(np.float64)
    ya, yb = np.take(y, ia).astype(np.float64), np.take(y, ib).astype(np.float64)
    # Walking left to right adds the weight below the edge, right to left subtracts it.
    np.negative(weight, out=weight, where=xa > xb)
    slope = (yb - ya) / (xb - xa)
    idx = np.repeat(np.arange(len(count)), count)
    cols = np.arange(len(idx)) - np.repeat(np.cumsum(count) - count - c_lo, count)
    y_cross = (cols - xa[idx]) * slope[idx] + ya[idx]
    rows = np.ceil(np.clip(y_cross, 0, height)).astype(np.intp)
    # Accumulate only inside the window that has crossings: columns outside it are empty,
    # rows above it are 0 and rows below its last crossing keep that row's sum.
    c0, c1 = int(c_lo.min()), int((c_lo + count).max())
    r0, r1 = int(rows.min()), int(rows.max()) + 1
    nr, nc = r1 - r0, c1 - c0
    rows -= r0
    rows += view[idx] * nr
    rows *= nc
    rows += cols - c0
    acc = np.zeros((n, nr, nc), dtype=np.int16)
    np.add.at(acc.reshape(-1), rows, weight[idx])
    for i in range(1, nr):
        np.add(acc[:, i - 1], acc[:, i], out=acc[:, i])
    out[...] = False
    r_end = min(r1, height)
    np.not_equal(acc[:, :r_end - r0], 0, out=out[:, r0:r_end, c0:c1])
    if r_end < height:
        np.not_equal(acc[:, -1:], 0, out=out[:, r_end:, c0:c1])
