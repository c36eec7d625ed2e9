"""The silhouette energy E_S (Eq. 11) fused into one compiled pass per particle-view (numba).

Per particle-view the kernel

0. finishes the projection of the mesh's camera coordinates (divide by depth, distortion,
   intrinsics: :func:`mocap.cameras.project`'s arithmetic, the same pixels bit for bit) into
   per-thread buffers, so no (P, C, V, 2) pixel array is written and re-read;
1. orients the projected triangles and weights the mesh edges exactly like the scanline
   rasterizer (:mod:`mocap.render._scanline`: nonzero winding of the contour edges, same
   float arithmetic, same pixel-centre rule, same depth culling), scan-converts the edges
   into an accumulation image and sums it down the rows; while summing it adds the observed
   distance transform under every covered pixel (term 1 of the chamfer) and marks the
   covered pixels inside the observed silhouette's grown box;
2. takes the 5x5 chamfer distance transform of that box (OpenCV's ``DIST_L2`` /
   ``DIST_MASK_5`` algorithm: Borgefors weights 1, 1.4, 2.1969 in 16-bit fixed point, two
   passes) and sums it over the observed silhouette's pixels (term 2),

so no mask of (P, C, h, w) is ever stored and no Python loop runs per particle. The result
equals :func:`mocap.energy.silhouette.chamfer_energy` on the scanline masks up to float
summation order (tested), i.e. the energy of the numpy path, which stays as the fallback
where numba cannot be imported (said once, as a warning).

Particle-views are spread over numba's threads (``prange``); :func:`mocap.threads.thread_budget`
sets how many.
"""

from __future__ import annotations

import numpy as np

from mocap.compiled import HAVE_NUMBA, njit, numba, prange  # noqa: F401  (numba: its config)
from mocap.energy.fallback import warn_once
from mocap.render import get_rasterizer

if HAVE_NUMBA:
    from mocap.render._compiled import scan_buffers, scan_edges

_HV, _DIAG, _LONG = 65536, 91750, 143976        # cvRound(65536 * (1, 1.4f, 2.1969f))
_INIT = 2**30       # 'far' (OpenCV: INT_MAX); any value > every real distance * 65536


def numba_available() -> bool:
    """True when the compiled kernel can be used; warns once when it cannot."""
    if HAVE_NUMBA:
        return True
    warn_once("silhouette", "the silhouette energy runs on the slower numpy path (pip install numba)")
    return False


if HAVE_NUMBA:

    @njit(cache=True, fastmath={"reassoc"})
    def _chamfer_term2(tmp, bh, bw, obs_r, obs_c, i0, j0):
        """Two-pass 5x5 chamfer transform (OpenCV's distanceTransform_5x5) of the seeds
        (tmp == 0) in the padded (bh + 4, bw + 4) image, far pixels ``_INIT``; returns the sum
        of the distances at the observed pixels (obs_r - i0, obs_c - j0): tmp holds a window
        of the box whose corner is box pixel (i0, j0).

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
        for i in range(2, bh + 2):                       # forward pass
            up2 = tmp[i - 2]
            up1 = tmp[i - 1]
            row = tmp[i]
            for j in range(2, bw + 2):
                a = min(min(up2[j - 1], up2[j + 1]), min(up1[j - 2], up1[j + 2]))
                b = min(up1[j - 1], up1[j + 1])
                cv = min(min(a + _LONG, b + _DIAG), up1[j] + _HV)
                cand[j] = (cv if row[j] != 0 else 0) - j * hv
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
                cv = min(min(min(a + _LONG, b + _DIAG), dn1[j] + _HV), row[j])
                cand[j] = cv + j * hv
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

    @njit(cache=True, fastmath={"reassoc"})
    def _sum_row(run, dt, c, r, j0, j1):
        """The sum of dt[c, r, j0:j1] under the covered pixels (run != 0) and their count.

        Not inlined at numba's IR level (``inline="always"``): there the caller's flags
        replace this function's, the sum lost its ``reassoc`` and stayed a serial loop; as
        a call LLVM inlines it with the flag and vectorises the sum (1.3x faster rows). The
        reassociated sum is the in-order one bit for bit: the terms are float32 distances,
        0 or >= 1 (exact Euclidean transforms of pixel centres: multiples of 2**-23), so
        every partial sum below 2**30 is exact in float64."""
        total = 0.0
        count = 0
        for j in range(j0, j1):
            inside = run[j] != 0
            total += np.float64(dt[c, r, j]) if inside else 0.0
            count += inside
        return total, count

    @njit(cache=True, fastmath={"reassoc"})
    def _sum_seed_row(run, dt, c, r, j0, j1, win, i, shift):
        """:func:`_sum_row` that also writes the seeds of the model distance transform:
        win[i, j - shift] = 0 where the model covers column j, far otherwise."""
        total = 0.0
        count = 0
        for j in range(j0, j1):
            inside = run[j] != 0
            total += np.float64(dt[c, r, j]) if inside else 0.0
            count += inside
            win[i, j - shift] = 0 if inside else _INIT
        return total, count

    @njit(cache=True, inline="always")
    def _add_row(acc, r, run, j0, j1):
        """Next row r of the scan: run[j] += acc[r, j], acc[r] cleared for the next
        particle-view (arrays and indices passed, not row views: building a view per row
        cost more than the row)."""
        for j in range(j0, j1):
            run[j] += acc[r, j]
            acc[r, j] = 0

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

    @njit(cache=True, parallel=True)
    def _fused_energy(X, cam, dist, has_dist, has_skew, faces, ea, eb, fwd, bwd, dt, boxes, valid,
                      area, obs_r, obs_c, obs_start, obs_box, num_views, height, width, penalty,
                      nthreads, out, bad):
        """X: (P, C, 3, V) camera coordinates of the P * C particle-views, projected here
        (:func:`project_view`; cam (C, 8), dist (C, 5), has_dist, has_skew its parameters);
        bad (nthreads,): vertices in front with a pixel not finite; faces (F, 3); ea, eb (E,) edge
        vertices; fwd, bwd (E, K) faces on either side (both padded with F to one K); dt
        (C, h, w) float32 observed distance transforms; boxes (C, 4) x0 y0 x1 y1; valid (C,); area (C,);
        obs_r, obs_c: observed pixels (box coordinates) of view c in
        obs_start[c]:obs_start[c + 1]; obs_box (C, 4): their row and column ranges (r0, r1,
        c0, c1) in the box. out: (P * C,) energies (NaN for invalid views)."""
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
            orient, acc, run, live, flag, cols = scan_buffers(F, E, height, width)
            xs = np.empty(V, X.dtype)
            ys = np.empty(V, X.dtype)
            vs = np.empty(V, np.bool_)
            win = np.empty((bh_max + 4, bw_max + 4), np.int32)
            # view-major order: a thread runs the particles of one view in a row, so that
            # view's distance transform (250 KB at 256 px) stays in cache
            for k in range(t, N, nthreads):
                c = k // n_part
                p = k - c * n_part
                n = p * num_views + c
                if not valid[c]:
                    out[n] = np.nan
                    continue
                bad[t] += project_view(X[p, c], cam[c], dist[c], has_dist, has_skew, xs, ys, vs)
                c_min, c_max, r_min, r_max = scan_edges(xs, ys, vs, faces, ea, eb, fwd, bwd,
                                                        orient, flag, live, cols, acc, height,
                                                        width)
                x0, y0, x1b, y1b = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
                bh = y1b - y0
                bw = x1b - x0
                t1 = 0.0
                model_area = 0
                seeds = 0
                r_end = 0
                # term 2's window (box coordinates): the observed pixels and the model's
                # bounding box in the box. A shortest chamfer path steps monotonically from a
                # seed to a pixel, so it stays in their bounding box: read at the observed
                # pixels the window's transform is the whole box's (tested), at 0.5-0.7x the
                # area. Its corner and columns are known before the rows are summed, its last
                # row after: the rows are seeded straight into it (padding ring included: far,
                # no seed lies outside the window), so that the passes run on whole rows from
                # column 2 (they vectorise so)
                i0 = min(obs_box[c, 0], max(r_min - y0, 0))
                j0 = min(obs_box[c, 2], max(c_min - x0, 0))
                j1 = max(obs_box[c, 3], min(c_max - x0, bw))
                ww = j1 - j0 + 4
                if r_max >= 0:
                    for j in range(c_min, c_max):
                        run[j] = 0
                    # the model's columns left of, in and right of the box (a partition)
                    ba = min(max(c_min, x0), c_max)
                    bb = max(min(c_max, x1b), ba)
                    shift = x0 + j0 - 2          # image column -> window column
                    wa = min(max(ba - shift, 0), ww)
                    wb = max(min(bb - shift, ww), wa)
                    r = r_min
                    while r < height:
                        if r <= r_max:
                            _add_row(acc, r, run, c_min, c_max)
                        else:
                            # below the last crossing the column sums stay: stop when all are 0
                            busy = False
                            for j in range(c_min, c_max):
                                if run[j] != 0:
                                    busy = True
                                    break
                            if not busy:
                                break
                        if y0 <= r < y1b:
                            wi = r - y0 - i0 + 2
                            for j in range(wa):
                                win[wi, j] = _INIT
                            for j in range(wb, ww):
                                win[wi, j] = _INIT
                            s1, k1 = _sum_seed_row(run, dt, c, r, ba, bb, win, wi, shift)
                            seeds += k1
                            if c_min < ba:
                                s2, k2 = _sum_row(run, dt, c, r, c_min, ba)
                                s1 += s2
                                k1 += k2
                            if bb < c_max:
                                s2, k2 = _sum_row(run, dt, c, r, bb, c_max)
                                s1 += s2
                                k1 += k2
                        else:
                            s1, k1 = _sum_row(run, dt, c, r, c_min, c_max)
                        t1 += s1
                        model_area += k1
                        r += 1
                    r_end = r
                    # _add_row cleared the rows it read; clear a crossing on row ``height``
                    for rr in range(max(r, r_min), r_max + 1):
                        for j in range(c_min, c_max):
                            acc[rr, j] = 0
                e1 = t1 / model_area if model_area > 0 else penalty
                if seeds == 0:
                    e2 = penalty
                else:
                    i1 = max(obs_box[c, 1], min(r_end - y0, bh))
                    # the window's rows the scan did not seed: far
                    for i in range(max(r_min - y0, 0) - i0 + 2):
                        for j in range(ww):
                            win[i, j] = _INIT
                    for i in range(min(r_end - y0, bh) - i0 + 2, i1 - i0 + 4):
                        for j in range(ww):
                            win[i, j] = _INIT
                    s0, s1 = obs_start[c], obs_start[c + 1]
                    e2 = _chamfer_term2(win, i1 - i0, j1 - j0, obs_r[s0:s1], obs_c[s0:s1],
                                        i0, j0) / area[c]
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

    def _observed(self, target) -> tuple[np.ndarray, ...]:
        """Observed pixels of every view in box coordinates (rows, cols, start offsets) and
        their row / column ranges (C, 4), cached for the current target."""
        key = id(target)
        if self._obs_key != key:
            rows, cols, start = [], [], [0]
            obs_box = np.zeros((len(target.masks), 4), np.int64)
            for c in range(len(target.masks)):
                x0, y0, x1, y1 = (int(v) for v in target.boxes[c])
                r, q = np.nonzero(target.masks[c, y0:y1, x0:x1]) if target.valid[c] else ((), ())
                rows.append(np.asarray(r, np.int64))
                cols.append(np.asarray(q, np.int64))
                start.append(start[-1] + len(r))
                if len(r):
                    obs_box[c] = (r.min(), r.max() + 1, q.min(), q.max() + 1)
            self._obs = (np.concatenate(rows), np.concatenate(cols), np.asarray(start, np.int64),
                         obs_box)
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
        obs_r, obs_c, obs_start, obs_box = self._observed(target)
        out = np.empty(P * C)
        n = numba.get_num_threads() if threads is None else int(threads)
        nthreads = max(1, min(n, P * C))
        bad = np.zeros(nthreads, np.int64)
        _fused_energy(X, cam, dist, bool(np.any(rig.dist)), bool(np.any(K[:, 0, 1])), self.faces,
                      *self.edge_arrays, target.dt, target.boxes.astype(np.int64), target.valid,
                      target.area.astype(np.float64), obs_r, obs_c, obs_start, obs_box, C, h, w,
                      float(np.hypot(h, w)), nthreads, out, bad)
        if bad.sum():
            raise ValueError(f"pixels contain NaN or inf at {int(bad.sum())} vertices in front "
                             "of the camera")
        return out.reshape(P, C)
