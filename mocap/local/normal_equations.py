"""The normal equations of Eq. 9, H = A^T W A and g = A^T W e0, accumulated without forming
A (compiled, numba).

Row block i of A (3 x D, see :func:`mocap.local.solver.linear_system`) is A_i = -[d_i]x J_i,
and every column of the point Jacobian J_i is the velocity at X_i of a twist (v, w):
v + w x X_i (the global translation e_a: (e_a, 0); the global rotation e_a: (0, e_a); a
revolute DOF j about axis w_j through q_j that moves the point's limb: (q_j x w_j, w_j); 0 for
the other DOFs). So J_i = G(X_i) Xi_k, G(X) = [I, -[X]x] (3 x 6) and Xi_k (6 x D) the twists of
limb k = limb of i, and

    H = sum_k Xi_k^T M_k Xi_k,  M_k = sum_{i on k} w_i B_i^T B_i,  B_i = -[d_i]x G(X_i) (3 x 6)
    g = sum_k Xi_k^T b_k,       b_k = sum_{i on k} w_i B_i^T e0_i

(:func:`_limb_moments`, then :func:`_chain_limbs`): 21 + 6 sums per correspondence instead of
the (6 + active)^2 / 2 of the per-correspondence blocks, and O(limbs x D^2) to chain them. The
twists are written about a point o_k of the limb (its first correspondence's point: G(X) Xi =
G(X - o) S_o Xi, S_o moving v to v + w x o), so that M_k's moments are of lever arms of a
limb's size, not of the distance to the world origin. Same H and g as the matrix path up to
float summation order (tested against it and against :func:`_accumulate`, the per-correspondence
kernel this replaced); numpy stays the fallback where numba cannot be imported.
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

    @njit(cache=True, inline="always")
    def _line_error(x0, x1, x2, d0, d1, d2, m, i, e):
        """e (3,) = X x d - m[i], the Plücker point-line error of the point X = (x0, x1, x2)
        and the line (d, m[i]); returns |e|^2."""
        e[0] = x1 * d2 - x2 * d1 - m[i, 0]
        e[1] = x2 * d0 - x0 * d2 - m[i, 1]
        e[2] = x0 * d1 - x1 * d0 - m[i, 2]
        return e[0] * e[0] + e[1] * e[1] + e[2] * e[2]

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
            sq += wi * _line_error(x0, x1, x2, d0, d1, d2, m, i, e)
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


if HAVE_NUMBA:

    @njit(cache=True)
    def _limb_moments(X, d, m, wt, limbs, origin, seen, M, b):
        """Per limb k: M[k] (6, 6) upper triangle and b[k] (6,) += the sums over its
        correspondences of w B^T B and w B^T e0, B = -[d]x [I, -[X - o_k]x] (3 x 6), o_k =
        origin[k], set to the first correspondence's point where seen[k] is False; returns
        sum w |e0|^2."""
        B = np.empty((3, 6))
        e = np.empty(3)
        sq = 0.0
        for i in range(X.shape[0]):
            wi = wt[i]
            k = limbs[i]
            x0, x1, x2 = X[i, 0], X[i, 1], X[i, 2]
            d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
            sq += wi * _line_error(x0, x1, x2, d0, d1, d2, m, i, e)
            if not seen[k]:
                seen[k] = True
                origin[k, 0], origin[k, 1], origin[k, 2] = x0, x1, x2
            y0, y1, y2 = x0 - origin[k, 0], x1 - origin[k, 1], x2 - origin[k, 2]
            dY = d0 * y0 + d1 * y1 + d2 * y2
            B[0, 0], B[0, 1], B[0, 2] = 0.0, d2, -d1
            B[1, 0], B[1, 1], B[1, 2] = -d2, 0.0, d0
            B[2, 0], B[2, 1], B[2, 2] = d1, -d0, 0.0
            B[0, 3], B[0, 4], B[0, 5] = y0 * d0 - dY, y0 * d1, y0 * d2
            B[1, 3], B[1, 4], B[1, 5] = y1 * d0, y1 * d1 - dY, y1 * d2
            B[2, 3], B[2, 4], B[2, 5] = y2 * d0, y2 * d1, y2 * d2 - dY
            for s in range(6):
                b[k, s] += wi * (B[0, s] * e[0] + B[1, s] * e[1] + B[2, s] * e[2])
                for t in range(s, 6):
                    M[k, s, t] += wi * (B[0, s] * B[0, t] + B[1, s] * B[1, t] + B[2, s] * B[2, t])
        return sq

    @njit(cache=True)
    def _chain_limbs(M, b, origin, seen, index, count, q, w, free, H, g):
        """H (D, D) += Xi_k^T M_k Xi_k and g += Xi_k^T b_k over the limbs with
        correspondences (seen), Xi_k's free columns the twists about origin[k] of the global
        DOFs and of the revolute DOFs that move limb k (index, count)."""
        D = H.shape[0]
        cols = np.empty(D, np.int64)
        Xi = np.empty((6, D))
        T = np.empty((6, D))
        Mk = np.empty((6, 6))
        for k in range(M.shape[0]):
            if not seen[k]:
                continue
            o0, o1, o2 = origin[k, 0], origin[k, 1], origin[k, 2]
            for s in range(6):
                Mk[s, s] = M[k, s, s]
                for t in range(s + 1, 6):
                    Mk[s, t] = M[k, s, t]
                    Mk[t, s] = M[k, s, t]
            n = 0
            for c in range(6):
                if not free[c]:
                    continue
                cols[n] = c
                for r in range(6):
                    Xi[r, n] = 0.0
                if c < 3:
                    Xi[c, n] = 1.0
                else:          # rotation about e_a through the world origin: v' = e_a x o
                    a = c - 3
                    Xi[3 + a, n] = 1.0
                    if a == 0:
                        Xi[1, n], Xi[2, n] = -o2, o1
                    elif a == 1:
                        Xi[0, n], Xi[2, n] = o2, -o0
                    else:
                        Xi[0, n], Xi[1, n] = -o1, o0
                n += 1
            for t in range(count[k]):
                j = index[k, t]
                c = 6 + j
                if not free[c]:
                    continue
                cols[n] = c
                r0, r1, r2 = o0 - q[j, 0], o1 - q[j, 1], o2 - q[j, 2]    # w_j x (o - q_j)
                Xi[0, n] = w[j, 1] * r2 - w[j, 2] * r1
                Xi[1, n] = w[j, 2] * r0 - w[j, 0] * r2
                Xi[2, n] = w[j, 0] * r1 - w[j, 1] * r0
                Xi[3, n], Xi[4, n], Xi[5, n] = w[j, 0], w[j, 1], w[j, 2]
                n += 1
            for s in range(n):
                for r in range(6):
                    v = 0.0
                    for u in range(6):
                        v += Mk[r, u] * Xi[u, s]
                    T[r, s] = v
            for s in range(n):
                cs = cols[s]
                v = 0.0
                for r in range(6):
                    v += Xi[r, s] * b[k, r]
                g[cs] += v
                for t in range(s, n):
                    v = 0.0
                    for r in range(6):
                        v += Xi[r, s] * T[r, t]
                    ct = cols[t]
                    if ct >= cs:
                        H[cs, ct] += v
                    else:
                        H[ct, cs] += v
        for s in range(D):                       # mirror the upper triangle
            for t in range(s + 1, D):
                H[t, s] = H[s, t]


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
    outside it are 0): per-limb moments chained through the tree (:func:`_limb_moments`,
    :func:`_chain_limbs`)."""
    D = 6 + len(q)
    index, count = active
    J = len(count)
    H, g = np.zeros((D, D)), np.zeros(D)
    M, b = np.zeros((J, 6, 6)), np.zeros((J, 6))
    origin, seen = np.zeros((J, 3)), np.zeros(J, np.bool_)
    q = np.ascontiguousarray(q, np.float64)
    w = np.ascontiguousarray(w, np.float64)
    sq = _limb_moments(np.ascontiguousarray(X, np.float64), np.ascontiguousarray(d, np.float64),
                       np.ascontiguousarray(m, np.float64), np.ascontiguousarray(wt, np.float64),
                       np.ascontiguousarray(limbs, np.int64), origin, seen, M, b)
    _chain_limbs(M, b, origin, seen, index, count, q, w, np.ascontiguousarray(free, np.bool_), H, g)
    return H, g, float(sq)


def accumulate_per_correspondence(X, d, m, wt, limbs, active, q, w, free
                                  ) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`accumulate` by the per-correspondence blocks (:func:`_accumulate`, the kernel
    before the per-limb moments; tests compare the two)."""
    D = 6 + len(q)
    index, count = active
    H, g = np.zeros((D, D)), np.zeros(D)
    sq = _accumulate(np.ascontiguousarray(X, np.float64), np.ascontiguousarray(d, np.float64),
                     np.ascontiguousarray(m, np.float64), np.ascontiguousarray(wt, np.float64),
                     np.ascontiguousarray(limbs, np.int64), index, count,
                     np.ascontiguousarray(q, np.float64), np.ascontiguousarray(w, np.float64),
                     np.ascontiguousarray(free, np.bool_), H, g)
    return H, g, float(sq)
