"""The normal equations of Eq. 9, H = A^T W A and g = A^T W e0, accumulated per
correspondence without forming A (compiled, numba).

Row block i of A (3 x D, see :func:`mocap.local.solver.linear_system`) is nonzero only on
the global twist's 6 columns and on the revolute DOFs that move the point's limb (its
ancestors): 6 + a few of the D columns. The kernel builds those columns of the block from
the point, the ray direction and the DOF axes, and adds their outer products to H, so each
correspondence costs O(active^2) instead of the (3N, D) matrix and its (D, 3N) @ (3N, D)
product. Same H and g as the matrix path up to float summation order (tested); numpy stays
the fallback where numba cannot be imported.
"""

from __future__ import annotations

import numpy as np

from mocap.compiled import HAVE_NUMBA, njit
from mocap.energy.fallback import warn_once


def active_dofs(moves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per limb the revolute DOFs that move it: moves (J, Dj) 0/1 -> (index (J, Dj) padded
    with -1, count (J,))."""
    J, Dj = moves.shape
    index = np.full((J, Dj), -1, np.int64)
    count = np.zeros(J, np.int64)
    for k in range(J):
        ids = np.flatnonzero(moves[k] > 0)
        index[k, :len(ids)] = ids
        count[k] = len(ids)
    return index, count


if HAVE_NUMBA:

    @njit(cache=True)
    def _accumulate(X, d, m, wt, limbs, index, count, q, w, free, H, g):
        """H (D, D) and g (D,) += the correspondences' blocks; returns sum w |e0|^2."""
        D = H.shape[0]
        cols = np.empty(D, np.int64)
        A = np.empty((3, D))
        e = np.empty(3)
        sq = 0.0
        for i in range(X.shape[0]):
            wi = wt[i]
            x0, x1, x2 = X[i, 0], X[i, 1], X[i, 2]
            d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
            e[0] = x1 * d2 - x2 * d1 - m[i, 0]
            e[1] = x2 * d0 - x0 * d2 - m[i, 1]
            e[2] = x0 * d1 - x1 * d0 - m[i, 2]
            sq += wi * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
            dX = d0 * x0 + d1 * x1 + d2 * x2
            # global twist: dv block -[d]x, dw block X d^T - (d.X) I
            A[0, 0], A[0, 1], A[0, 2] = 0.0, d2, -d1
            A[1, 0], A[1, 1], A[1, 2] = -d2, 0.0, d0
            A[2, 0], A[2, 1], A[2, 2] = d1, -d0, 0.0
            A[0, 3], A[0, 4], A[0, 5] = x0 * d0 - dX, x0 * d1, x0 * d2
            A[1, 3], A[1, 4], A[1, 5] = x1 * d0, x1 * d1 - dX, x1 * d2
            A[2, 3], A[2, 4], A[2, 5] = x2 * d0, x2 * d1, x2 * d2 - dX
            n = 0
            for c in range(6):
                if free[c]:
                    cols[n] = c
                    A[0, n], A[1, n], A[2, n] = A[0, c], A[1, c], A[2, c]
                    n += 1
            k = limbs[i]
            for t in range(count[k]):
                j = index[k, t]
                c = 6 + j
                if not free[c]:
                    continue
                a = dX - (d0 * q[j, 0] + d1 * q[j, 1] + d2 * q[j, 2])       # d.(X - q_j)
                b = d0 * w[j, 0] + d1 * w[j, 1] + d2 * w[j, 2]              # d.w_j
                cols[n] = c
                A[0, n] = (x0 - q[j, 0]) * b - w[j, 0] * a
                A[1, n] = (x1 - q[j, 1]) * b - w[j, 1] * a
                A[2, n] = (x2 - q[j, 2]) * b - w[j, 2] * a
                n += 1
            for s in range(n):
                cs = cols[s]
                g[cs] += wi * (A[0, s] * e[0] + A[1, s] * e[1] + A[2, s] * e[2])
                for t in range(s, n):
                    v = wi * (A[0, s] * A[0, t] + A[1, s] * A[1, t] + A[2, s] * A[2, t])
                    H[cs, cols[t]] += v
        for s in range(D):                       # mirror the upper triangle
            for t in range(s + 1, D):
                H[t, s] = H[s, t]
        return sq


def compiled_available() -> bool:
    if HAVE_NUMBA:
        return True
    warn_once("normal_equations", "the local tracker's normal equations run on the slower numpy "
              "path (pip install numba)")
    return False


def accumulate(X, d, m, wt, limbs, active, q, w, free) -> tuple[np.ndarray, np.ndarray, float]:
    """H (D, D), g (D,) and sum_i w_i |e0_i|^2 for correspondences (X, d, m) (N, 3) with
    weights (N,) on limbs (N,), DOF axes w (Dj, 3) through q (Dj, 3), the DOFs moving each
    limb ``active`` (from :func:`active_dofs`) and the free-DOF mask (D,) (columns of A
    outside it are 0)."""
    D = 6 + len(q)
    index, count = active
    H, g = np.zeros((D, D)), np.zeros(D)
    sq = _accumulate(np.ascontiguousarray(X, np.float64), np.ascontiguousarray(d, np.float64),
                     np.ascontiguousarray(m, np.float64), np.ascontiguousarray(wt, np.float64),
                     np.ascontiguousarray(limbs, np.int64), index, count,
                     np.ascontiguousarray(q, np.float64), np.ascontiguousarray(w, np.float64),
                     np.ascontiguousarray(free, np.bool_), H, g)
    return H, g, float(sq)
