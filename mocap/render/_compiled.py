"""The compiled (numba) scan conversion of a projected mesh's silhouette, shared by the fused
silhouette energy (:mod:`mocap.energy.fused`) and the mask rasterizer here.

Same algorithm and float arithmetic as :mod:`mocap.render._scanline` (read its docstring):
each face's projected orientation, the edges whose faces' orientations do not cancel, their
column crossings scattered into an accumulation image; summing that image down the rows
gives each pixel's winding number, nonzero inside the silhouette (the fused energy sorts the
same crossings per column instead: :func:`contour_edges`, :func:`edge_line` and
:func:`crossing_row` are its parts of :func:`scan_edges`). Per image, not batched, so no
(E, N) arrays: the kernels loop over particle-views in parallel instead.
"""

from __future__ import annotations

import numpy as np

from mocap.compiled import HAVE_NUMBA, njit, prange

if HAVE_NUMBA:

    @njit(cache=True)
    def contour_weights(orient, fwd, bwd, weight):
        """weight[e] = sum_k orient[fwd[e, k]] - orient[bwd[e, k]], edge e's winding step (0:
        not a contour edge). orient is int32 so that the K == 1 and K == 2 loops vectorise
        (AVX2 gathers; the general loop does not: 3x slower on the energy mesh, whose few
        non-manifold edges make K 2)."""
        E, K = fwd.shape
        if K == 1:
            for e in range(E):
                weight[e] = orient[fwd[e, 0]] - orient[bwd[e, 0]]
        elif K == 2:       # a few non-manifold edges (a decimated mesh): still vectorised
            for e in range(E):
                weight[e] = orient[fwd[e, 0]] + orient[fwd[e, 1]] - orient[bwd[e, 0]] - orient[bwd[e, 1]]
        else:
            for e in range(E):
                w = 0
                for k in range(K):
                    w += orient[fwd[e, k]] - orient[bwd[e, k]]
                weight[e] = w

    @njit(cache=True, inline="always")
    def scan_buffers(num_faces, num_edges, height, width):
        """Work arrays of :func:`scan_edges` and the row sums, one set per thread: orient,
        acc (zeroed), run (the running column sums), live, weight, cols."""
        return (np.zeros(num_faces + 1, np.int32), np.zeros((height + 1, width), np.int32),
                np.zeros(width, np.int32), np.empty(num_edges, np.int32),
                np.empty(num_edges, np.int32), np.empty((num_edges, 2), np.int32))

    @njit(cache=True, inline="always")
    def contour_edges(xs, ys, vs, faces, ea, eb, fwd, bwd, orient, weight, live, cols, width):
        """The contour edges of one projected mesh (pixels xs, ys (V,); vs (V,) vertex in front
        of the near plane) that cross a column centre: returns n, with live[:n] those edges
        and cols[:n] their columns [lo, hi) (lo < hi); orient (F + 1,) the faces'
        orientations and weight (E,) the edges' winding steps (:func:`contour_weights`).
        orient, weight, live (E,), cols (E, 2) are work arrays."""
        F = faces.shape[0]
        E = ea.shape[0]
        allvis = True
        for v in range(vs.shape[0]):
            if not vs[v]:
                allvis = False
                break
        if allvis:
            for f in range(F):       # branchless: 3x faster than with the culling test
                a = faces[f, 0]
                x0 = xs[a]
                y0 = ys[a]
                lhs = (xs[faces[f, 1]] - x0) * (ys[faces[f, 2]] - y0)
                rhs = (ys[faces[f, 1]] - y0) * (xs[faces[f, 2]] - x0)
                orient[f] = np.int32(lhs > rhs) - np.int32(lhs < rhs)
        else:
            for f in range(F):
                a, b, d = faces[f, 0], faces[f, 1], faces[f, 2]
                if not (vs[a] and vs[b] and vs[d]):
                    orient[f] = 0
                    continue
                lhs = (xs[b] - xs[a]) * (ys[d] - ys[a])
                rhs = (ys[b] - ys[a]) * (xs[d] - xs[a])
                orient[f] = np.int32(lhs > rhs) - np.int32(lhs < rhs)
        orient[F] = 0
        # edges whose weight is not 0 (~10 %): weighed by a vectorised gather, then
        # compacted without a branch (a branch per edge mispredicts on every contour
        # edge); of those, the ones that cross a column centre (~60 %: at 256 px most
        # contour edges are short) compacted the same way with their columns [lo, hi),
        # then scan-converted (1.2x faster than a branch on hi == lo in that loop)
        contour_weights(orient, fwd, bwd, weight)
        n_live = 0
        for e in range(E):
            live[n_live] = e
            n_live += weight[e] != 0
        n_cross = 0
        for i_live in range(n_live):
            e = live[i_live]
            xa = xs[ea[e]]
            xb = xs[eb[e]]
            lo = np.ceil(min(max(min(xa, xb), 0.0), width))
            hi = np.ceil(min(max(max(xa, xb), 0.0), width))
            live[n_cross] = e                # n_cross <= i_live: read already
            cols[n_cross, 0] = int(lo)
            cols[n_cross, 1] = int(hi)
            n_cross += hi != lo
        return n_cross

    @njit(cache=True, inline="always")
    def edge_line(e, xs, ys, ea, eb, weight):
        """Contour edge e's signed weight (the winding step where it crosses a column: its
        weight, negated when it runs right to left) and its line in float64: (w, xa, ya,
        slope). The crossing row in column j is :func:`crossing_row`."""
        w = np.int64(weight[e])
        xa = xs[ea[e]]
        xb = xs[eb[e]]
        if xa > xb:
            w = -w
        fxa = np.float64(xa)
        fya = np.float64(ys[ea[e]])
        slope = (np.float64(ys[eb[e]]) - fya) / (np.float64(xb) - fxa)
        return w, fxa, fya, slope

    @njit(cache=True, inline="always")
    def crossing_row(j, fxa, fya, slope, height):
        """The first row whose centre lies below the line at column j's centre, in [0, height]."""
        yc = (j - fxa) * slope + fya
        return int(np.ceil(min(max(yc, 0.0), np.float64(height))))

    @njit(cache=True, inline="always")
    def scan_edges(xs, ys, vs, faces, ea, eb, fwd, bwd, orient, weight, live, cols, acc, height,
                   width):
        """Scan-convert one projected mesh (pixels xs, ys (V,); vs (V,) vertex in front of the
        near plane) into ``acc`` ((height + 1, width) int32, all 0 on entry): edge weights
        added at their column crossings. orient (F + 1,), weight (E,), live (E,), cols (E, 2)
        are work arrays. Returns the touched columns [c_min, c_max) and rows [r_min, r_max]
        (r_max -1: nothing drawn)."""
        n_cross = contour_edges(xs, ys, vs, faces, ea, eb, fwd, bwd, orient, weight, live, cols,
                                width)
        c_min = width
        c_max = 0
        r_min = height + 1
        r_max = -1
        for i_cross in range(n_cross):
            w, fxa, fya, slope = edge_line(live[i_cross], xs, ys, ea, eb, weight)
            j0 = cols[i_cross, 0]
            j1 = cols[i_cross, 1]
            c_min = min(c_min, j0)
            c_max = max(c_max, j1)
            for j in range(j0, j1):
                r = crossing_row(j, fxa, fya, slope, height)
                acc[r, j] += w
                r_min = min(r_min, r)
                r_max = max(r_max, r)
        return c_min, c_max, r_min, r_max

    @njit(cache=True, parallel=True)
    def _rasterize(x, y, vis, faces, ea, eb, fwd, bwd, height, width, nthreads, out):
        """x, y (N, V) pixels, vis (N, V) -> out (N, height, width) bool silhouettes."""
        N = x.shape[0]
        F = faces.shape[0]
        E = ea.shape[0]
        for t in prange(nthreads):
            orient, acc, run, live, weight, cols = scan_buffers(F, E, height, width)
            for n in range(t, N, nthreads):
                mask = out[n]
                mask[:, :] = False
                c_min, c_max, r_min, r_max = scan_edges(x[n], y[n], vis[n], faces, ea, eb, fwd,
                                                        bwd, orient, weight, live, cols, acc,
                                                        height, width)
                if r_max < 0:
                    continue
                for j in range(c_min, c_max):
                    run[j] = 0
                r = r_min
                while r < height:
                    busy = False
                    for j in range(c_min, c_max):
                        v = run[j] + acc[r, j]
                        acc[r, j] = 0
                        run[j] = v
                        mask[r, j] = v != 0
                        busy |= v != 0
                    r += 1
                    if r > r_max and not busy:       # below the last crossing, all 0
                        break
                for rr in range(max(r, r_min), r_max + 1):    # a crossing on row ``height``
                    for j in range(c_min, c_max):
                        acc[rr, j] = 0


if HAVE_NUMBA:

    @njit(cache=True)
    def _rasterize_boxes(x, y, vis, faces, ea, eb, fwd, bwd, height, width, acc, run, out, boxes):
        """:func:`_rasterize`'s silhouettes, one thread, into masks that are kept between calls:
        out (N, height, width) bool holds the last call's masks, each False outside boxes[n]
        (row0, row1, col0, col1: the rows and columns that call wrote); only that box is
        cleared before the new mask is drawn, and boxes[n] becomes the new one. acc
        ((height + 1, width) int32, all 0) is left all 0 again; run (width,) int32 is work.
        The same masks as :func:`_rasterize` without its per-call clear of every pixel."""
        N = x.shape[0]
        F = faces.shape[0]
        E = ea.shape[0]
        orient = np.zeros(F + 1, np.int32)
        live = np.empty(E, np.int32)
        weight = np.empty(E, np.int32)
        cols = np.empty((E, 2), np.int32)
        for n in range(N):
            mask = out[n]
            for r in range(boxes[n, 0], boxes[n, 1]):
                mask[r, boxes[n, 2]:boxes[n, 3]] = False
            boxes[n, 0] = boxes[n, 1] = boxes[n, 2] = boxes[n, 3] = 0
            c_min, c_max, r_min, r_max = scan_edges(x[n], y[n], vis[n], faces, ea, eb, fwd,
                                                    bwd, orient, weight, live, cols, acc,
                                                    height, width)
            if r_max < 0:
                continue
            width_n = c_max - c_min
            live_run = run[c_min:c_max]
            live_run[:] = 0
            r = r_min
            # the row pass on 1D slices indexed from 0 (no negative-index wraparound test per
            # pixel: LLVM vectorises it), the same integer sums as :func:`_rasterize`
            while r < height:
                row_acc = acc[r, c_min:c_max]
                row_mask = mask[r, c_min:c_max]
                busy = 0
                for j in range(width_n):
                    v = live_run[j] + row_acc[j]
                    row_acc[j] = 0
                    live_run[j] = v
                    row_mask[j] = v != 0
                    busy |= v
                r += 1
                if r > r_max and busy == 0:      # below the last crossing, all 0
                    break
            for rr in range(max(r, r_min), r_max + 1):    # a crossing on row ``height``
                acc[rr, c_min:c_max] = 0
            boxes[n, 0], boxes[n, 1], boxes[n, 2], boxes[n, 3] = r_min, r, c_min, c_max


class KeptMasks:
    """Silhouettes drawn again and again at one size (the local step: the same views every
    iteration): the masks, the accumulation image and each mask's drawn box kept between
    calls, so that a call clears and scans only the boxes (:func:`_rasterize_boxes`). One
    per user, never shared between threads (a call overwrites the masks another thread is
    reading): :class:`~mocap.local.contour.ContourMatcher` keeps one per thread."""

    def __init__(self, count: int, height: int, width: int):
        self.masks = np.zeros((count, height, width), bool)
        self.acc = np.zeros((height + 1, width), np.int32)
        self.run = np.zeros(width, np.int32)
        self.boxes = np.zeros((count, 4), np.int64)

    def draw(self, x: np.ndarray, y: np.ndarray, vis: np.ndarray, faces: np.ndarray,
             edge_arrays) -> np.ndarray:
        """The silhouettes (N, height, width) bool of N projected meshes (x, y, vis (N, V), as
        :func:`rasterize_compiled`); the array is overwritten by the next call."""
        _, height, width = self.masks.shape
        _rasterize_boxes(x, y, vis, faces, *edge_arrays, height, width, self.acc, self.run,
                         self.masks, self.boxes)
        return self.masks


def rasterize_compiled(x: np.ndarray, y: np.ndarray, vis: np.ndarray, faces: np.ndarray, edge_arrays,
                       height: int, width: int, out: np.ndarray, threads: int = 1) -> None:
    """Silhouettes of N projected meshes into ``out`` (N, height, width) bool (C-contiguous).

    x, y: (N, V) pixel coordinates (float32 or float64); vis: (N, V) bool, False culls the
    vertex's faces; faces (F, 3) and edge_arrays (a, b, forward, backward) in the narrow
    unsigned index types of :func:`edge_kernel_arrays`.
    """
    _rasterize(x, y, vis, faces, *edge_arrays, int(height), int(width),
               max(1, min(int(threads), len(x))), out)


def edge_kernel_arrays(faces: np.ndarray, edges, num_vertices: int) -> tuple[np.ndarray, tuple]:
    """The faces and the edge table (:class:`~mocap.render._scanline.EdgeTable`) in the
    narrowest unsigned index type (the kernels stream them for every image; unsigned: numba
    skips the negative-index wraparound on every gather), both face tables padded to one
    width K with F, the always-0 orientation slot."""
    big = max(int(num_vertices), len(faces) + 1)
    index = np.uint16 if big < 2**16 else np.uint32 if big < 2**32 else np.uint64
    k = max(edges.forward.shape[1], edges.backward.shape[1])
    sides = [np.pad(t, ((0, 0), (0, k - t.shape[1])), constant_values=len(faces))
             for t in (edges.forward, edges.backward)]
    return (np.ascontiguousarray(faces, dtype=index),
            tuple(np.ascontiguousarray(a, dtype=index) for a in (edges.a, edges.b, *sides)))
