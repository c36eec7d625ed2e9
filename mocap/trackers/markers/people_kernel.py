"""Compiled per-landmark energies of several people's particles (``marker_people``'s batch):
:meth:`mocap.energy.markers.MarkerEnergy.landmark_costs` (compiled path) of T people at once,
with its arithmetic, operation for operation, so the same bits.

The single-person kernel (:func:`mocap.energy.marker_kernel.view_costs_fused`) loops particle
by particle. Here the particles are the innermost loop: for one person, landmark and view a
holding one candidate (the usual case: a track sees its own skeleton, one keypoint per
landmark and view) the candidate, its epipolar lines and weight are the same for every
particle, so each step is one loop over the particles that the compiler turns into vector
instructions (same IEEE operations, the same results). A view with several candidates (each
particle picks its nearest) runs the particle-by-particle loop of the single-person kernel
(:func:`mocap.energy.marker_kernel.view_costs_into`, inlined).
"""

from __future__ import annotations

import numpy as np

from mocap.compiled import njit
from mocap.energy.marker_kernel import _se3_exp, view_costs_into


@njit(cache=True, error_model="numpy")
def people_landmark_costs(parents, dof_joint, axes, rest_joints, chi, lm_joint, rest, R, t, Kc, obs_xy,
                          valid, lines, epipoles, tau2, near, weight, coherent, predicted, weak, coh_scale,
                          radius2):
    """Per-landmark energies (T, P, L) of T people's particles chi (T, P, D): person n's
    landmarks by :func:`landmarks_by_particle` (axes[n], rest_joints[n], rest[n]); each view's cost
    as :func:`mocap.energy.marker_kernel.view_costs_fused` computes it from obs_xy[n]
    (L, C, K, 2), valid[n], lines[n] (L, C, K, C, 3), weight[n] (L, C, K); the views' costs
    summed in order and divided by L x C; plus, where coherent[n], the coherence term
    coh_scale min(|X - predicted[n]|^2 / radius2, 1) of the landmarks weak[n] (L,)."""
    T, P = chi.shape[0], chi.shape[1]
    L, C = lm_joint.shape[0], R.shape[0]
    K = obs_xy.shape[3]
    lc = float(L * C)
    out = np.empty((T, P, L))
    ux, uy = np.empty((C, P)), np.empty((C, P))
    front = np.empty((C, P), np.bool_)
    nfront = np.empty(P, np.int64)
    dx, dy, d2, epi, total = np.empty(P), np.empty(P), np.empty(P), np.empty(P), np.empty(P)
    u1, front1 = np.empty((C, 2)), np.empty(C, np.bool_)                   # several candidates' work arrays
    cost1, kept1 = np.empty((P, 1, C)), np.zeros((P, 1, C), np.bool_)
    for n in range(T):
        X = landmarks_by_particle(parents, dof_joint, axes[n], rest_joints[n], chi[n], lm_joint, rest[n])
        for lm in range(L):
            xs, ys, zs = X[lm, 0], X[lm, 1], X[lm, 2]
            for p in range(P):
                nfront[p] = 0
            for c in range(C):
                r00, r01, r02, t0 = R[c, 0, 0], R[c, 0, 1], R[c, 0, 2], t[c, 0]
                r10, r11, r12, t1 = R[c, 1, 0], R[c, 1, 1], R[c, 1, 2], t[c, 1]
                r20, r21, r22, t2 = R[c, 2, 0], R[c, 2, 1], R[c, 2, 2], t[c, 2]
                k00, k01, k02, k11, k12 = Kc[c, 0, 0], Kc[c, 0, 1], Kc[c, 0, 2], Kc[c, 1, 1], Kc[c, 1, 2]
                for p in range(P):
                    x0, x1, x2 = xs[p], ys[p], zs[p]
                    cx = r00 * x0 + r01 * x1 + r02 * x2 + t0
                    cy = r10 * x0 + r11 * x1 + r12 * x2 + t1
                    cz = r20 * x0 + r21 * x1 + r22 * x2 + t2
                    f = cz > near
                    front[c, p] = f
                    nfront[p] += 1 if f else 0
                    xn, yn = cx / cz, cy / cz
                    ux[c, p] = k00 * xn + k01 * yn + k02
                    uy[c, p] = k11 * yn + k12
            for a in range(C):
                count, k0 = 0, 0
                for k in range(K):
                    if valid[n, lm, a, k]:
                        count += 1
                        k0 = k
                if count == 0:                                  # no candidate: a miss
                    for p in range(P):
                        total[p] = tau2 if a == 0 else total[p] + tau2
                    continue
                if count > 1:                                   # each particle's nearest candidate
                    view_costs_into(X.transpose(2, 0, 1), 0, P, lm, lm + 1, a, a + 1, R, t, Kc, near,
                                    obs_xy[n], valid[n], lines[n], epipoles, tau2, weight[n], u1, front1,
                                    cost1, kept1)
                    for p in range(P):
                        cost = cost1[p, 0, a]
                        total[p] = cost if a == 0 else total[p] + cost
                    continue
                ox, oy = obs_xy[n, lm, a, k0, 0], obs_xy[n, lm, a, k0, 1]
                for p in range(P):
                    ddx = ox - ux[a, p]
                    ddy = oy - uy[a, p]
                    dx[p], dy[p] = ddx, ddy
                    d2[p] = ddx * ddx + ddy * ddy
                    epi[p] = 0.0
                for b in range(C):
                    if b == a:
                        continue
                    ln = lines[n, lm, a, k0, b]
                    l0, l1, l2 = ln[0], ln[1], ln[2]
                    e0, e1, e2 = epipoles[a, b, 0], epipoles[a, b, 1], epipoles[a, b, 2]
                    for p in range(P):
                        db = l0 * ux[b, p] + l1 * uy[b, p] + l2
                        wx = e2 * ux[a, p] - e0
                        wy = e2 * uy[a, p] - e1
                        cr = dx[p] * wy - dy[p] * wx
                        term = db * db + cr * cr / (wx * wx + wy * wy + 1e-12)
                        epi[p] = epi[p] + term if front[b, p] else epi[p]
                w = weight[n, lm, a, k0]
                for p in range(P):
                    m = nfront[p] - 1
                    if m < 1:
                        m = 1
                    cval = 0.5 * d2[p] + 0.25 * epi[p] / m
                    cval = cval if (np.isfinite(cval) and cval < tau2) else tau2
                    cost = w * cval + (1.0 - w) * tau2 if (d2[p] < tau2 and front[a, p]) else tau2
                    total[p] = cost if a == 0 else total[p] + cost
            for p in range(P):
                v = total[p] / lc
                if coherent[n] and weak[n, lm]:
                    d0 = X[lm, 0, p] - predicted[n, lm, 0]
                    d1 = X[lm, 1, p] - predicted[n, lm, 1]
                    dz = X[lm, 2, p] - predicted[n, lm, 2]
                    r = (d0 * d0 + d1 * d1 + dz * dz) / radius2
                    if r > 1.0:
                        r = 1.0
                    v = v + coh_scale * r
                out[n, p, lm] = v
    return out


@njit(cache=True, error_model="numpy")
def _mul_rows(A, B, out):
    """out = A B for affine transforms stored as their top rows (3, 4, P), particle by
    particle with :func:`mocap.energy.marker_kernel._mat4_mul`'s arithmetic."""
    P = A.shape[2]
    for i in range(3):
        for j in range(4):
            for p in range(P):
                v = A[i, 0, p] * B[0, j, p] + A[i, 1, p] * B[1, j, p] + A[i, 2, p] * B[2, j, p]
                out[i, j, p] = v + A[i, 3, p] if j == 3 else v


@njit(cache=True, error_model="numpy")
def landmarks_by_particle(parents, dof_joint, axes, rest_joints, chi, lm_joint, rest_points):
    """:func:`mocap.energy.marker_kernel.landmark_points` with the particles innermost: the
    landmarks (L, 3, P) of poses chi (P, 6 + D), the same numbers (each joint's revolute
    transforms and products computed for all particles in one loop each)."""
    P = chi.shape[0]
    J, D, L = parents.shape[0], dof_joint.shape[0], lm_joint.shape[0]
    G = np.empty((J, 3, 4, P))
    root = np.empty((3, 4, P))
    one = np.empty((4, 4))
    for p in range(P):
        _se3_exp(chi[p, :6], one)
        for i in range(3):
            for j in range(4):
                root[i, j, p] = one[i, j]
    local, E, tmp = np.empty((3, 4, P)), np.empty((3, 4, P)), np.empty((3, 4, P))
    sn, cs = np.empty(P), np.empty(P)
    for jt in range(J):
        first = True
        q0, q1, q2 = rest_joints[jt, 0], rest_joints[jt, 1], rest_joints[jt, 2]
        for d in range(D):
            if dof_joint[d] != jt:
                continue
            for p in range(P):
                sn[p] = np.sin(chi[p, 6 + d])
                cs[p] = np.cos(chi[p, 6 + d])
            x, y, z = axes[d, 0], axes[d, 1], axes[d, 2]
            M = local if first else E
            for p in range(P):                  # _revolute
                s, c = sn[p], cs[p]
                C = 1.0 - c
                m00, m01, m02 = c + x * x * C, x * y * C - z * s, x * z * C + y * s
                m10, m11, m12 = y * x * C + z * s, c + y * y * C, y * z * C - x * s
                m20, m21, m22 = z * x * C - y * s, z * y * C + x * s, c + z * z * C
                M[0, 0, p], M[0, 1, p], M[0, 2, p] = m00, m01, m02
                M[1, 0, p], M[1, 1, p], M[1, 2, p] = m10, m11, m12
                M[2, 0, p], M[2, 1, p], M[2, 2, p] = m20, m21, m22
                M[0, 3, p] = q0 - (m00 * q0 + m01 * q1 + m02 * q2)
                M[1, 3, p] = q1 - (m10 * q0 + m11 * q1 + m12 * q2)
                M[2, 3, p] = q2 - (m20 * q0 + m21 * q1 + m22 * q2)
            if first:
                first = False
            else:
                _mul_rows(local, E, tmp)
                local, tmp = tmp, local
        base = root if parents[jt] < 0 else G[parents[jt]]
        if first:
            G[jt] = base
        else:
            _mul_rows(base, local, G[jt])
    out = np.empty((L, 3, P))
    for lm in range(L):
        g = G[lm_joint[lm]]
        r0, r1, r2 = rest_points[lm, 0], rest_points[lm, 1], rest_points[lm, 2]
        for i in range(3):
            for p in range(P):
                out[lm, i, p] = g[i, 0, p] * r0 + g[i, 1, p] * r1 + g[i, 2, p] * r2 + g[i, 3, p]
    return out
