"""Compiled (numba) hot path of the marker likelihood: forward kinematics of the landmarks
and the per-view costs of :func:`mocap.energy.markers.view_costs`, fused into loops over
particles x landmarks x views with no temporaries (the numpy versions allocate arrays of
(P, L, C, C, 3) per evaluation, which dominates at the tracker's small sizes).

Both functions compute exactly what their numpy references compute
(:func:`mocap.body.kinematics.chain_transforms` + :meth:`LandmarkSet.from_transforms`, and
:func:`mocap.energy.markers.view_costs`), in float64; tests/markers/test_marker_kernel.py
checks them against those. Compiled once per machine (``cache=True``); single-threaded, so
the thread budget of the process is untouched.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _mat4_mul(A, B, out):
    for i in range(3):
        for j in range(4):
            s = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]
            if j == 3:
                s += A[i, 3]
            out[i, j] = s
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True)
def _se3_exp(xi, out):
    """exp(hat(xi)) of a twist (v, omega) into out (4, 4) (mocap.body.twists.se3_exp)."""
    wx, wy, wz = xi[3], xi[4], xi[5]
    t2 = wx * wx + wy * wy + wz * wz
    th = np.sqrt(t2)
    if th < 1e-4:
        a = 1.0 - t2 / 6.0
        b = 0.5 - t2 / 24.0
        c = 1.0 / 6.0 - t2 / 120.0
    else:
        a = np.sin(th) / th
        b = (1.0 - np.cos(th)) / t2
        c = (th - np.sin(th)) / (t2 * th)
    K = np.empty((3, 3))
    K[0, 0], K[0, 1], K[0, 2] = 0.0, -wz, wy
    K[1, 0], K[1, 1], K[1, 2] = wz, 0.0, -wx
    K[2, 0], K[2, 1], K[2, 2] = -wy, wx, 0.0
    for i in range(3):
        for j in range(3):
            k2 = K[i, 0] * K[0, j] + K[i, 1] * K[1, j] + K[i, 2] * K[2, j]
            eye = 1.0 if i == j else 0.0
            out[i, j] = eye + a * K[i, j] + b * k2
    for i in range(3):
        s = 0.0
        for j in range(3):
            k2 = K[i, 0] * K[0, j] + K[i, 1] * K[1, j] + K[i, 2] * K[2, j]
            eye = 1.0 if i == j else 0.0
            s += (eye + b * K[i, j] + c * k2) * xi[j]
        out[i, 3] = s
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True)
def _revolute(axis, point, theta, out):
    """[[R, (I - R) q], [0, 1]] of a rotation by theta about axis through point."""
    x, y, z = axis[0], axis[1], axis[2]
    s, c = np.sin(theta), np.cos(theta)
    C = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + x * x * C, x * y * C - z * s, x * z * C + y * s
    out[1, 0], out[1, 1], out[1, 2] = y * x * C + z * s, c + y * y * C, y * z * C - x * s
    out[2, 0], out[2, 1], out[2, 2] = z * x * C - y * s, z * y * C + x * s, c + z * z * C
    for i in range(3):
        out[i, 3] = point[i] - (out[i, 0] * point[0] + out[i, 1] * point[1] + out[i, 2] * point[2])
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True)
def landmark_points(parents, dof_joint, axes, rest_joints, chi, lm_joint, rest_points):
    """Posed landmarks (P, L, 3) float64.

    parents: (J,) int (parents before children, -1 root); dof_joint: (D,) int; axes: (D, 3)
    unit rest axes; rest_joints: (J, 3); chi: (P, 6 + D) (root twist, angles); lm_joint:
    (L,) int the joint carrying each landmark; rest_points: (L, 3).
    """
    P = chi.shape[0]
    J = parents.shape[0]
    D = dof_joint.shape[0]
    L = lm_joint.shape[0]
    out = np.empty((P, L, 3))
    G = np.empty((J, 4, 4))
    local = np.empty((4, 4))
    E = np.empty((4, 4))
    tmp = np.empty((4, 4))
    root = np.empty((4, 4))
    has = np.zeros(J, np.bool_)
    for p in range(P):
        _se3_exp(chi[p, :6], root)
        for j in range(J):
            first = True
            for d in range(D):
                if dof_joint[d] != j:
                    continue
                _revolute(axes[d], rest_joints[j], chi[p, 6 + d], E)
                if first:
                    local[:, :] = E
                    first = False
                else:
                    _mat4_mul(local, E, tmp)
                    local[:, :] = tmp
            has[j] = not first
            base = root if parents[j] < 0 else G[parents[j]]
            if has[j]:
                _mat4_mul(base, local, G[j])
            else:
                G[j, :, :] = base
        for lm in range(L):
            g = G[lm_joint[lm]]
            for i in range(3):
                out[p, lm, i] = (g[i, 0] * rest_points[lm, 0] + g[i, 1] * rest_points[lm, 1]
                                 + g[i, 2] * rest_points[lm, 2] + g[i, 3])
    return out


@njit(cache=True, error_model="numpy")
def project_points(X, R, t, Kc, u, z):
    """Undistorted projection of landmarks X: (N, L, 3) world into pixels u (N, L, C, 2) and
    depths z (N, L, C), with the arithmetic of :func:`view_costs_fused` (and of
    :func:`mocap.energy.markers.pinhole_project` to rounding); a zero depth gives inf / nan
    as numpy does."""
    N, L, C = X.shape[0], X.shape[1], R.shape[0]
    for n in range(N):
        for lm in range(L):
            x0, x1, x2 = X[n, lm, 0], X[n, lm, 1], X[n, lm, 2]
            for c in range(C):
                cx = R[c, 0, 0] * x0 + R[c, 0, 1] * x1 + R[c, 0, 2] * x2 + t[c, 0]
                cy = R[c, 1, 0] * x0 + R[c, 1, 1] * x1 + R[c, 1, 2] * x2 + t[c, 1]
                cz = R[c, 2, 0] * x0 + R[c, 2, 1] * x1 + R[c, 2, 2] * x2 + t[c, 2]
                xn, yn = cx / cz, cy / cz
                u[n, lm, c, 0] = Kc[c, 0, 0] * xn + Kc[c, 0, 1] * yn + Kc[c, 0, 2]
                u[n, lm, c, 1] = Kc[c, 1, 1] * yn + Kc[c, 1, 2]
                z[n, lm, c] = cz


@njit(cache=True)
def nearest_candidates(u, front, obs_xy, valid, confidence, gate2, z, conf, ok):
    """Per landmark and view the valid candidate nearest to the projection u (L, C, 2)
    (squared distance dx^2 + dy^2, the first of equals, a NaN distance first as numpy's
    argmin takes it; candidate 0 when none is valid): its pixels z (L, C, 2), confidence
    conf (L, C), and ok (L, C) = nearer than sqrt(gate2) and front (L, C). The loop of
    :func:`mocap.energy.markers.associate`, same values."""
    L, C, K = valid.shape
    for lm in range(L):
        for c in range(C):
            best, kb, nan = np.inf, 0, False
            for k in range(K):
                if not valid[lm, c, k]:
                    continue
                dx = obs_xy[lm, c, k, 0] - u[lm, c, 0]
                dy = obs_xy[lm, c, k, 1] - u[lm, c, 1]
                d2 = dx * dx + dy * dy
                if np.isnan(d2):
                    if not nan:
                        best, kb, nan = d2, k, True
                elif not nan and d2 < best:
                    best, kb = d2, k
            z[lm, c, 0] = obs_xy[lm, c, kb, 0]
            z[lm, c, 1] = obs_xy[lm, c, kb, 1]
            conf[lm, c] = confidence[lm, c, kb]
            ok[lm, c] = (best < gate2) and front[lm, c]


@njit(cache=True, inline="always")
def project_landmark(x0, x1, x2, R, t, Kc, near, u, front):
    """One landmark (x0, x1, x2) world into every view: pixels u (C, 2) and front (C,) = depth
    > near; returns how many views see it in front."""
    nfront = 0
    for c in range(R.shape[0]):
        cx = R[c, 0, 0] * x0 + R[c, 0, 1] * x1 + R[c, 0, 2] * x2 + t[c, 0]
        cy = R[c, 1, 0] * x0 + R[c, 1, 1] * x1 + R[c, 1, 2] * x2 + t[c, 1]
        cz = R[c, 2, 0] * x0 + R[c, 2, 1] * x1 + R[c, 2, 2] * x2 + t[c, 2]
        front[c] = cz > near
        if front[c]:
            nfront += 1
        xn, yn = cx / cz, cy / cz
        u[c, 0] = Kc[c, 0, 0] * xn + Kc[c, 0, 1] * yn + Kc[c, 0, 2]
        u[c, 1] = Kc[c, 1, 1] * yn + Kc[c, 1, 2]
    return nfront


@njit(cache=True, inline="always")
def view_costs_into(X, p0, p1, lm0, lm1, a0, a1, R, t, Kc, near, obs_xy, valid, lines, epipoles, tau2, weight,
                    u, front, cost, kept):
    """The costs of views a0..a1-1 of landmarks lm0..lm1-1 of particles p0..p1-1 (landmarks X
    (P, L, 3) world, any strides; the other arguments as :func:`view_costs_fused`'s) into
    cost[p - p0, lm - lm0, a], and kept[p - p0, lm - lm0, a] set True where the nearest valid
    candidate (the first of equals) lies within the gate and the landmark in front of view a
    (left as it is elsewhere); u (C, 2), front (C,): work arrays. The per-view cost of
    :func:`view_costs_fused` and of ``people_kernel``'s views with several candidates, inlined
    into both (each compiles it with its own error model). One call covers whole loops: a call
    per landmark and view made the single-person kernel 3x slower, one per particle 3-10 %
    (the arrays' reference counts at each call)."""
    C = R.shape[0]
    K = obs_xy.shape[2]
    for p in range(p0, p1):
        for lm in range(lm0, lm1):
            nfront = project_landmark(X[p, lm, 0], X[p, lm, 1], X[p, lm, 2], R, t, Kc, near, u, front)
            for a in range(a0, a1):
                best, kb = np.inf, -1
                for k in range(K):
                    if valid[lm, a, k]:
                        dx = obs_xy[lm, a, k, 0] - u[a, 0]
                        dy = obs_xy[lm, a, k, 1] - u[a, 1]
                        d2 = dx * dx + dy * dy
                        if d2 < best:
                            best, kb = d2, k
                if kb < 0 or not (best < tau2) or not front[a]:
                    cost[p - p0, lm - lm0, a] = tau2
                    continue
                kept[p - p0, lm - lm0, a] = True
                dx = obs_xy[lm, a, kb, 0] - u[a, 0]
                dy = obs_xy[lm, a, kb, 1] - u[a, 1]
                epi = 0.0
                for b in range(C):
                    if b == a or not front[b]:
                        continue
                    ln = lines[lm, a, kb, b]
                    db = ln[0] * u[b, 0] + ln[1] * u[b, 1] + ln[2]
                    e = epipoles[a, b]
                    wx = e[2] * u[a, 0] - e[0]
                    wy = e[2] * u[a, 1] - e[1]
                    cr = dx * wy - dy * wx
                    epi += db * db + cr * cr / (wx * wx + wy * wy + 1e-12)
                n = nfront - 1              # (view a is one of the nfront)
                if n < 1:
                    n = 1
                cval = 0.5 * best + 0.25 * epi / n
                cval = cval if (np.isfinite(cval) and cval < tau2) else tau2
                w = weight[lm, a, kb]
                cost[p - p0, lm - lm0, a] = w * cval + (1.0 - w) * tau2


@njit(cache=True)
def view_costs_fused(X, R, t, Kc, obs_xy, valid, lines, epipoles, tau2, near, weight):
    """Per-view costs (P, L, C) and kept (P, L, C) of :func:`mocap.energy.markers.view_costs`
    from landmarks X: (P, L, 3) world; R: (C, 3, 3), t: (C, 3), Kc: (C, 3, 3) the pinhole
    cameras; obs_xy: (L, C, K, 2), valid: (L, C, K); lines: (L, C, K, C, 3) unit-normal
    epipolar lines; epipoles: (C, C, 3); tau2: gate^2; near: minimum depth; weight:
    (L, C, K) the kept candidate's weight w in w min(c, tau2) + (1 - w) tau2."""
    P, L = X.shape[0], X.shape[1]
    C = R.shape[0]
    cost = np.empty((P, L, C))
    kept = np.zeros((P, L, C), np.bool_)
    view_costs_into(X, 0, P, 0, L, 0, C, R, t, Kc, near, obs_xy, valid, lines, epipoles, tau2, weight,
                    np.empty((C, 2)), np.empty(C, np.bool_), cost, kept)
    return cost, kept
