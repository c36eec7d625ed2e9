"""The silhouette energy E_S (Eq. 11) fused into one compiled pass per particle-view (numba).

Per particle-view the kernel

0. finishes the projection of the mesh's camera coordinates (divide by depth, distortion,
   intrinsics: :func:`mocap.cameras.project`'s arithmetic, the same pixels bit for bit) into
   per-thread buffers, so no (P, C, V, 2) pixel array is written and re-read;
1. orients the projected triangles and weights the mesh edges exactly like the scanline
   rasterizer (:mod:`mocap.render._scanline`: nonzero winding of the contour edges, same
   float arithmetic, same pixel-centre rule, same depth culling) and computes the edges'
   column crossings; instead of scattering them into an image and summing it down the rows,
   it sorts them by column and row (two counting sorts) and walks each column's winding
   number: the covered pixels come as runs of rows. Term 1 of the chamfer (the observed
   distance transform under the model) is then a difference of two column prefix sums per
   run (computed once per target), exact in float64; the runs inside the observed
   silhouette's grown box are term 2's seeds;
2. takes the 5x5 chamfer distance transform (OpenCV's ``DIST_L2`` / ``DIST_MASK_5``
   algorithm: Borgefors weights 1, 1.4, 2.1969 in 16-bit fixed point, two passes) of the
   bounding box of those seeds and the observed pixels, transposed so that each run is a
   run of one row, and sums it over the observed silhouette's pixels (term 2),

so no mask of (P, C, h, w) is ever stored and no Python loop runs per particle. The result
is Eq. 11 summed pixel by pixel on the scanline masks bit for bit (tested), and equals
:func:`mocap.energy.silhouette.chamfer_energy` up to float summation order (tested), i.e.
the energy of the numpy path, which stays as the fallback where numba cannot be imported
(said once, as a warning).

Particle-views are spread over numba's threads (``prange``); :func:`mocap.threads.thread_budget`
sets how many.
"""

from __future__ import annotations

import numpy as np

from mocap.compiled import HAVE_NUMBA, njit, numba, prange  # noqa: F401  (numba: its config)
from mocap.energy.fallback import warn_once
from mocap.render import get_rasterizer

if HAVE_NUMBA:
    from mocap.render._compiled import contour_edges, crossing_row, edge_line

_HV, _DIAG, _LONG = 65536, 91750, 143976        # cvRound(65536 * (1, 1.4f, 2.1969f))
_INIT = 2**30       # 'far' (OpenCV: INT_MAX); any value > every real distance * 65536
_H32, _D32, _L32 = np.int32(_HV), np.int32(_DIAG), np.int32(_LONG)   # int32 sums: no overflow


def numba_available() -> bool:
    """True when the compiled kernel can be used; warns once when it cannot."""
    if HAVE_NUMBA:
        return True
    warn_once("silhouette", "the silhouette energy runs on the slower numpy path (pip install numba)")
    return False


if HAVE_NUMBA:

    @njit(cache=True)
    def _far_ring(tmp, bh, bw):
        """The padding ring of a (bh + 4, bw + 4) image in tmp: its two outer rows and
        columns on each side far (``_INIT``)."""
        for j in range(bw + 4):
            tmp[0, j] = _INIT
            tmp[1, j] = _INIT
            tmp[bh + 2, j] = _INIT
            tmp[bh + 3, j] = _INIT
        for i in range(2, bh + 2):
            tmp[i, 0] = _INIT
            tmp[i, 1] = _INIT
            tmp[i, bw + 2] = _INIT
            tmp[i, bw + 3] = _INIT

    @njit(cache=True, fastmath={"reassoc"})
    def _chamfer_term2(tmp, bh, bw, spans, n_spans, obs_r, obs_c, i0, j0):
        """Two-pass 5x5 chamfer transform (OpenCV's distanceTransform_5x5) of the seeds in a
        padded (bh + 4, bw + 4) image (tmp: work array at least that large, its contents
        ignored; the transform is left there), far pixels ``_INIT``; returns the sum of the
        distances at the observed pixels (obs_r - i0, obs_c - j0): the image is a window of
        the box whose corner is box pixel (i0, j0). The seeds are runs, spans[:n_spans]
        (row, first column, end column) in the padded image's coordinates (rows 2..bh + 1,
        columns 2..bw + 1), sorted by row: set into the forward pass's candidates, so only the
        padding ring is written beforehand (:func:`_far_ring`; not here: with those writes in
        this function LLVM compiled its passes 2x slower).

        Each pass is split per row into the neighbours of the two rows already done (no
        dependency along the row: LLVM vectorises it into ``cand``) and the serial
        left/right neighbour; the minimum of the same 8 terms, so the transform is the
        same integer image as the one-loop form (tested), 2-2.5x faster. ``cand`` is
        allocated here, not passed in: LLVM only vectorises when it can prove that ``cand``
        and ``tmp`` do not overlap. The serial part is the recurrence
        ``r[j] = min(c[j], r[j - 1] + HV)`` (c: the row's candidate, 0 at a seed; backward:
        the pixel's own value too, which leaves every value <= HV as it is), run as a prefix
        minimum of ``c[j] - j * HV`` (``r[j] = j * HV + min_k<=j (c[k] - k * HV)``, exact in
        integers; every value stays below 2**31: far ones below ``_INIT + (bh + bw + 4) *
        _LONG``): the chain per pixel is a minimum instead of an add, a test and a minimum
        (1.1x faster term 2). The sum may be reassociated (``reassoc``: several partial sums,
        no latency chain of float adds over the observed pixels): it is exact in float64 in any
        order, its terms being multiples of 2**-16 and the sum below 2**30."""
        cand = np.empty(bw + 4, np.int32)
        hv = np.int32(_HV)
        s = 0
        for i in range(2, bh + 2):                       # forward pass
            up2 = tmp[i - 2]
            up1 = tmp[i - 1]
            row = tmp[i]
            for j in range(2, bw + 2):
                a = min(min(up2[j - 1], up2[j + 1]), min(up1[j - 2], up1[j + 2]))
                b = min(up1[j - 1], up1[j + 1])
                cv = min(min(np.int32(a + _L32), np.int32(b + _D32)), np.int32(up1[j] + _H32))
                cand[j] = np.int32(cv - np.int32(j) * hv)
            while s < n_spans and spans[s, 0] == i:      # the seeds: 0
                for j in range(spans[s, 1], spans[s, 2]):
                    cand[j] = -j * hv
                s += 1
            m = row[1] - hv
            ramp = hv
            for j in range(2, bw + 2):
                m = min(m, cand[j])
                ramp += hv
                row[j] = m + ramp
        for i in range(bh + 1, 1, -1):                   # backward pass
            dn2 = tmp[i + 2]
            dn1 = tmp[i + 1]
            row = tmp[i]
            for j in range(2, bw + 2):
                a = min(min(dn2[j - 1], dn2[j + 1]), min(dn1[j - 2], dn1[j + 2]))
                b = min(dn1[j - 1], dn1[j + 1])
                cv = min(min(min(np.int32(a + _L32), np.int32(b + _D32)), np.int32(dn1[j] + _H32)),
                         row[j])
                cand[j] = np.int32(cv + np.int32(j) * hv)
            m = row[bw + 2] + (bw + 2) * hv
            ramp = (bw + 2) * hv
            for j in range(bw + 1, 1, -1):
                m = min(m, cand[j])
                ramp -= hv
                row[j] = m - ramp
        total = 0.0
        for k in range(len(obs_r)):
            total += np.float32(tmp[obs_r[k] + 2 - i0, obs_c[k] + 2 - j0]) * np.float32(1.0 / 65536.0)
        return total

    @njit(cache=True)
    def _column_prefix_sums(dt, out):
        """dt (C, h, w) float32 -> out (C, h + 1, w) float64: out[c, r, j] = sum of dt[c, :r, j],
        row by row; exact for distance transforms (see :func:`_fused_energy`)."""
        C, h, w = dt.shape
        for c in range(C):
            for j in range(w):
                out[c, 0, j] = 0.0
            for r in range(h):
                for j in range(w):
                    out[c, r + 1, j] = out[c, r, j] + np.float64(dt[c, r, j])

    @njit(cache=True, inline="always")
    def project_view(X, cam, dist, has_dist, has_skew, xs, ys, vs):
        """Camera coordinates X (3, V) of one view -> pixels xs, ys (V,) and vs (V,) = z > near,
        with the float operations of :func:`mocap.cameras.project` in X's dtype and in its
        order (no FMA contraction without fastmath), so the same pixels bit for bit
        (tested). cam: (fx, skew, cx, fy, cy, 1, 2, near) and dist (k1, k2, p1, p2, k3) in
        X's dtype; has_dist / has_skew: whether the rig has any distortion / skew (project
        takes those terms for every view then). Pixels of vertices behind the near plane are
        0 (never read: their faces are culled). Returns how many vertices in front have a
        pixel that is not finite."""
        fx, sk, cx, fy, cy, one, two, near = (cam[0], cam[1], cam[2], cam[3], cam[4], cam[5],
                                               cam[6], cam[7])
        k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
        bad = 0
        for v in range(X.shape[1]):
            z = X[2, v]
            front = z > near
            vs[v] = front
            if not front:
                xs[v] = 0
                ys[v] = 0
                continue
            iz = one / z
            x = X[0, v] * iz
            y = X[1, v] * iz
            if has_dist:
                x2 = x * x
                y2 = y * y
                xy = x * y
                r2 = x2 + y2
                radial = one + r2 * (k1 + r2 * (k2 + r2 * k3))
                xd = x * radial + two * p1 * xy + p2 * (r2 + two * x2)
                y = y * radial + p1 * (r2 + two * y2) + two * p2 * xy
                x = xd
            u = fx * x + cx
            if has_skew:
                u = u + sk * y
            w = fy * y + cy
            if not (np.isfinite(u) and np.isfinite(w)):
                bad += 1
                u = 0
                w = 0
            xs[v] = u
            ys[v] = w
        return bad

    @njit(cache=True, inline="always")
    def _crossing_buffers(cap):
        """Work arrays for ``cap`` column crossings: rows, columns and weights in the two
        counting sorts' orders (row1, col1, wt1, row2, col2, wt2) and the covered runs (spans,
        (cap, 3))."""
        return (np.empty(cap, np.int32), np.empty(cap, np.int32), np.empty(cap, np.int32),
                np.empty(cap, np.int32), np.empty(cap, np.int32), np.empty(cap, np.int32),
                np.empty((cap, 3), np.int64))

    @njit(cache=True, parallel=True)
    def _fused_energy(X, cam, dist, has_dist, has_skew, faces, ea, eb, fwd, bwd, colsum, boxes,
                      valid, area, obs_r, obs_c, obs_start, obs_box, num_views, height, width,
                      penalty, nthreads, out, bad):
        """X: (P, C, 3, V) camera coordinates of the P * C particle-views, projected here
        (:func:`project_view`; cam (C, 8), dist (C, 5), has_dist, has_skew its parameters);
        bad (nthreads,): vertices in front with a pixel not finite; faces (F, 3); ea, eb (E,) edge
        vertices; fwd, bwd (E, K) faces on either side (both padded with F to one K); colsum
        (C, h + 1, w) float64 column prefix sums of the observed distance transforms
        (colsum[c, r, j] = sum of dt[c, :r, j]); boxes (C, 4) x0 y0 x1 y1; valid (C,); area (C,);
        obs_r, obs_c: observed pixels (box coordinates) of view c in
        obs_start[c]:obs_start[c + 1], column by column; obs_box (C, 4): their row and column
        ranges (r0, r1, c0, c1) in the box. out: (P * C,) energies (NaN for invalid views)."""
        n_part = X.shape[0]
        N = n_part * num_views
        V = X.shape[3]
        F = faces.shape[0]
        E = ea.shape[0]
        bh_max = 1
        bw_max = 1
        for c in range(num_views):
            bh_max = max(bh_max, boxes[c, 3] - boxes[c, 1])
            bw_max = max(bw_max, boxes[c, 2] - boxes[c, 0])
        for t in prange(nthreads):
            orient = np.zeros(F + 1, np.int32)
            live = np.empty(E, np.int32)
            weight = np.empty(E, np.int32)
            cols = np.empty((E, 2), np.int32)
            pos = np.zeros(width + 1, np.int64)
            rpos = np.empty(height + 2, np.int64)
            cap = 4 * E
            row1, col1, wt1, row2, col2, wt2, spans = _crossing_buffers(cap)
            xs = np.empty(V, X.dtype)
            ys = np.empty(V, X.dtype)
            vs = np.empty(V, np.bool_)
            win = np.empty((bw_max + 4, bh_max + 4), np.int32)     # transposed: box columns
            # view-major order: a thread runs the particles of one view in a row, so that
            # view's prefix sums stay in cache
            for k in range(t, N, nthreads):
                c = k // n_part
                p = k - c * n_part
                n = p * num_views + c
                if not valid[c]:
                    out[n] = np.nan
                    continue
                bad[t] += project_view(X[p, c], cam[c], dist[c], has_dist, has_skew, xs, ys, vs)
                n_cross = contour_edges(xs, ys, vs, faces, ea, eb, fwd, bwd, orient, weight, live,
                                        cols, width)
                # the crossings sorted by column, then by row within each column: two stable
                # counting sorts (by row, then by column; pos[j]: column j's next slot), no
                # comparison sort (an insertion sort per column was 1.6x slower: mispredicted)
                c_min = width
                c_max = 0
                for i in range(n_cross):
                    c_min = min(c_min, cols[i, 0])
                    c_max = max(c_max, cols[i, 1])
                for j in range(c_min, c_max + 1):
                    pos[j] = 0
                for i in range(n_cross):
                    pos[cols[i, 0]] += 1
                    pos[cols[i, 1]] -= 1
                step = 0
                total = 0
                for j in range(c_min, c_max):
                    step += pos[j]                 # crossings in column j
                    pos[j] = total
                    total += step
                if total > cap:
                    cap = 2 * total
                    row1, col1, wt1, row2, col2, wt2, spans = _crossing_buffers(cap)
                for r in range(height + 2):
                    rpos[r] = 0
                q = 0
                for i in range(n_cross):
                    w, fxa, fya, slope = edge_line(live[i], xs, ys, ea, eb, weight)
                    for j in range(cols[i, 0], cols[i, 1]):
                        r = crossing_row(j, fxa, fya, slope, height)
                        row1[q] = r
                        col1[q] = j
                        wt1[q] = w
                        rpos[r + 1] += 1
                        q += 1
                for r in range(1, height + 2):
                    rpos[r] += rpos[r - 1]         # row r's first slot
                for q in range(total):
                    r = row1[q]
                    d = rpos[r]
                    rpos[r] = d + 1
                    row2[d] = r
                    col2[d] = col1[q]
                    wt2[d] = wt1[q]
                for q in range(total):
                    j = col2[q]
                    d = pos[j]
                    pos[j] = d + 1
                    row1[d] = row2[q]
                    wt1[d] = wt2[q]
                # each column's covered rows: where the winding number (the crossings' weights
                # summed down the column) is not 0, runs [ra, rb). Term 1 per run from the
                # prefix sums, exact: the terms are float32 distances, 0 or >= 1 (exact
                # Euclidean transforms of pixel centres: multiples of 2**-23), so every prefix
                # sum, difference and partial sum below 2**30 is exact in float64 and the sum
                # is the pixel-by-pixel one bit for bit. The runs inside the box are term 2's
                # seeds (box coordinates) and give their bounding box.
                x0, y0, x1b, y1b = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
                t1 = 0.0
                model_area = 0
                seeds = 0
                n_spans = 0
                s_r0 = height
                s_r1 = 0
                s_c0 = width
                s_c1 = 0
                q0 = 0
                for j in range(c_min, c_max):
                    q1 = pos[j]
                    wnd = 0
                    ra = 0
                    for q in range(q0, q1 + 1):
                        if q < q1:
                            r = row1[q]
                            if wnd == 0:
                                ra = r
                            wnd += wt1[q]
                            if wnd != 0:
                                continue
                            rb = r
                        elif wnd != 0:
                            rb = height                # covered to the image's bottom
                        else:
                            break
                        if rb > ra:
                            t1 += colsum[c, rb, j] - colsum[c, ra, j]
                            model_area += rb - ra
                            sa = max(ra, y0)
                            sb = min(rb, y1b)
                            if x0 <= j < x1b and sa < sb:
                                spans[n_spans, 0] = j - x0
                                spans[n_spans, 1] = sa - y0
                                spans[n_spans, 2] = sb - y0
                                n_spans += 1
                                seeds += sb - sa
                                s_r0 = min(s_r0, sa - y0)
                                s_r1 = max(s_r1, sb - y0)
                                s_c0 = min(s_c0, j - x0)
                                s_c1 = j - x0 + 1
                    q0 = q1
                e1 = t1 / model_area if model_area > 0 else penalty
                if seeds == 0:
                    e2 = penalty
                else:
                    # term 2 on the window of the observed pixels and the seeds, transposed
                    # (rows: box columns): a shortest chamfer path steps monotonically from a
                    # seed to a pixel, so it stays in their bounding box, and the 5x5 mask is
                    # symmetric under transposition: read at the observed pixels the
                    # transform is the whole box's (tested). Transposed, each run of seeds is
                    # a run of one window row.
                    i0 = min(obs_box[c, 0], s_r0)
                    i1 = max(obs_box[c, 1], s_r1)
                    j0 = min(obs_box[c, 2], s_c0)
                    j1 = max(obs_box[c, 3], s_c1)
                    for s in range(n_spans):            # window coordinates
                        spans[s, 0] += 2 - j0
                        spans[s, 1] += 2 - i0
                        spans[s, 2] += 2 - i0
                    s0, s1 = obs_start[c], obs_start[c + 1]
                    _far_ring(win, j1 - j0, i1 - i0)
                    e2 = _chamfer_term2(win, j1 - j0, i1 - i0, spans, n_spans, obs_c[s0:s1],
                                        obs_r[s0:s1], j0, i0) / area[c]
                out[n] = e1 + e2


class FusedSilhouetteEnergy:
    """Per-view chamfer energies of projected meshes, compiled (see the module docstring).

    faces: (F, 3) int vertex ids; num_vertices: V.
    """

    def __init__(self, faces: np.ndarray, num_vertices: int):
        if not HAVE_NUMBA:
            raise RuntimeError("the fused silhouette energy needs numba")
        # the cached rasterizer of this topology holds them, built once
        self.faces, self.edge_arrays = get_rasterizer(faces, num_vertices).kernel_arrays
        self.num_vertices = int(num_vertices)
        self._obs_key = None
        self._colsum = np.empty((0, 0, 0))

    def _observed(self, target) -> tuple[np.ndarray, ...]:
        """Observed pixels of every view in box coordinates, column by column (rows, cols,
        start offsets), their row / column ranges (C, 4) and the column prefix sums of the
        observed distance transforms (C, h + 1, w) float64 (exact: see the kernel), cached
        for the current target."""
        key = id(target)
        if self._obs_key != key:
            rows, cols, start = [], [], [0]
            obs_box = np.zeros((len(target.masks), 4), np.int64)
            for c in range(len(target.masks)):
                x0, y0, x1, y1 = (int(v) for v in target.boxes[c])
                q, r = np.nonzero(target.masks[c, y0:y1, x0:x1].T) if target.valid[c] else ((), ())
                rows.append(np.asarray(r, np.int64))
                cols.append(np.asarray(q, np.int64))
                start.append(start[-1] + len(r))
                if len(r):
                    obs_box[c] = (r.min(), r.max() + 1, q.min(), q.max() + 1)
            C, h, w = target.dt.shape
            if self._colsum.shape != (C, h + 1, w):
                self._colsum = np.empty((C, h + 1, w))      # reused: a fresh one page-faults
            colsum = self._colsum
            _column_prefix_sums(target.dt, colsum)
            self._obs = (np.concatenate(rows), np.concatenate(cols), np.asarray(start, np.int64),
                         obs_box, colsum)
            self._obs_key = key
            self._obs_target = target            # keep it alive while its id is the key
        return self._obs

    def __call__(self, camera: np.ndarray, rig, target, near: float = 0.05,
                 threads: int | None = None) -> np.ndarray:
        """camera: (P, C, 3, V) camera coordinates of the mesh's vertices in the views of
        ``rig`` (:func:`mocap.cameras.camera_coordinates`; the internal-resolution rig);
        target: :class:`~mocap.energy.silhouette.SilhouetteTarget` -> (P, C) float64 energies
        (NaN for views the target ignores). The projection's last steps (divide by depth,
        distortion, intrinsics) run in the kernel, per particle-view."""
        X = np.ascontiguousarray(camera)
        if X.ndim != 4 or X.shape[2] != 3 or X.shape[1] != len(rig):
            raise ValueError(f"camera coordinates must be (P, {len(rig)}, 3, V), got {X.shape}")
        P, C, _, V = X.shape
        if V != self.num_vertices:
            raise ValueError(f"camera coordinates of {V} vertices, the mesh has {self.num_vertices}")
        h, w = target.size
        dtype = X.dtype
        K = rig.K
        cam = np.empty((C, 8), dtype)
        cam[:, :5] = np.stack([K[:, 0, 0], K[:, 0, 1], K[:, 0, 2], K[:, 1, 1], K[:, 1, 2]], 1)
        cam[:, 5:] = (1.0, 2.0, near)
        dist = np.ascontiguousarray(rig.dist, dtype=dtype)
        obs_r, obs_c, obs_start, obs_box, colsum = self._observed(target)
        out = np.empty(P * C)
        n = numba.get_num_threads() if threads is None else int(threads)
        nthreads = max(1, min(n, P * C))
        bad = np.zeros(nthreads, np.int64)
        _fused_energy(X, cam, dist, bool(np.any(rig.dist)), bool(np.any(K[:, 0, 1])), self.faces,
                      *self.edge_arrays, colsum, target.boxes.astype(np.int64), target.valid,
                      target.area.astype(np.float64), obs_r, obs_c, obs_start, obs_box, C, h, w,
                      float(np.hypot(h, w)), nthreads, out, bad)
        if bad.sum():
            raise ValueError(f"pixels contain NaN or inf at {int(bad.sum())} vertices in front "
                             "of the camera")
        return out.reshape(P, C)
