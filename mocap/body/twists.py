"""Exponential maps of so(3) and se(3): the twist algebra of the kinematic chain.

Pure numpy, any number of leading batch dimensions (``*``). Conventions follow Murray, Li &
Sastry, "A Mathematical Introduction to Robotic Manipulation" (1994), which Zhang et al. 2013
(Eq. 3-4) and Bregler/Malik/Rosenhahn use: a twist is ``xi = (v, omega)`` with ``v`` the
linear and ``omega`` the angular part, ``hat(xi) = [[hat(omega), v], [0, 0]]`` and the rigid
motion ``exp(hat(xi))``. A revolute joint with unit axis ``omega`` through point ``q`` has the
twist ``(-omega x q, omega)``; rotating by ``theta`` is ``exp(theta * hat(xi))``.
"""

from __future__ import annotations

import numpy as np

_SMALL = 1e-8


def hat(omega: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix of a vector.

    omega: (*, 3) -> (*, 3, 3) with ``hat(omega) @ x == cross(omega, x)``.
    """
    omega = np.asarray(omega)
    out = np.zeros(omega.shape[:-1] + (3, 3), dtype=omega.dtype)
    x, y, z = omega[..., 0], omega[..., 1], omega[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def twist_hat(xi: np.ndarray) -> np.ndarray:
    """4x4 matrix form of a twist. xi: (*, 6) as (v, omega) -> (*, 4, 4)."""
    xi = np.asarray(xi)
    out = np.zeros(xi.shape[:-1] + (4, 4), dtype=xi.dtype)
    out[..., :3, :3] = hat(xi[..., 3:])
    out[..., :3, 3] = xi[..., :3]
    return out


def _series(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficients a = sin t / t, b = (1 - cos t) / t^2, c = (t - sin t) / t^3 with
    Taylor expansions near zero, so that every map below is exact at theta = 0."""
    t2 = theta * theta
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0, (safe - np.sin(safe)) / (safe**3))
    return a, b, c


def so3_exp(omega: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues' formula).

    omega: (*, 3), angle = |omega| in radians -> (*, 3, 3).
    """
    omega = np.asarray(omega)
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    a, b, _ = _series(theta)
    K = hat(omega)
    eye = np.eye(3, dtype=omega.dtype)
    return (eye + a * K + b * (K @ K)).astype(omega.dtype, copy=False)


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of :func:`so3_exp`, angle in [0, pi]).

    R: (*, 3, 3) -> (*, 3).
    """
    R = np.asarray(R)
    lead = R.shape[:-2]
    Rf = R.reshape(-1, 3, 3)
    cos = np.clip((np.trace(Rf, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    w = np.stack([Rf[:, 2, 1] - Rf[:, 1, 2], Rf[:, 0, 2] - Rf[:, 2, 0], Rf[:, 1, 0] - Rf[:, 0, 1]], axis=-1)
    sin = np.sin(theta)
    near_pi = sin < 1e-6
    scale = np.where(theta < 1e-6, 0.5, theta / (2.0 * np.where(near_pi, 1.0, sin)))
    out = w * scale[:, None]
    big = np.flatnonzero(near_pi & (theta > 1.0))
    if len(big):
        # theta ~ pi: the axis from the symmetric part, R = 2 n n^T - I
        B = (Rf[big] + np.eye(3)) / 2.0
        col = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        n = B[np.arange(len(big)), :, col]
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        out[big] = n * theta[big][:, None]
    return out.reshape(lead + (3,)).astype(R.dtype, copy=False)


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """Rigid motion of a twist: exp(hat(xi)) in closed form.

    xi: (*, 6) as (v, omega) -> (*, 4, 4). Exact for pure translations (omega = 0 gives
    [[I, v], [0, 1]]).
    """
    xi = np.asarray(xi)
    v, omega = xi[..., :3], xi[..., 3:]
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    a, b, c = _series(theta)
    K = hat(omega)
    K2 = K @ K
    eye = np.eye(3, dtype=xi.dtype)
    out = np.zeros(xi.shape[:-1] + (4, 4), dtype=xi.dtype)
    out[..., :3, :3] = eye + a * K + b * K2
    V = eye + b * K + c * K2
    out[..., :3, 3] = (V @ v[..., None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def se3_log(T: np.ndarray) -> np.ndarray:
    """Twist of a rigid motion (inverse of :func:`se3_exp`). T: (*, 4, 4) -> (*, 6)."""
    T = np.asarray(T)
    omega = so3_log(T[..., :3, :3])
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    K = hat(omega)
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    # V^{-1} = I - K/2 + (1/t^2)(1 - (t sin t)/(2(1 - cos t))) K^2
    coef = np.where(small, 1.0 / 12.0,
                    (1.0 - safe * np.sin(safe) / (2.0 * (1.0 - np.cos(safe)))) / (safe * safe))
    Vinv = np.eye(3, dtype=T.dtype) - 0.5 * K + coef * (K @ K)
    v = (Vinv @ T[..., :3, 3:4])[..., 0]
    return np.concatenate([v, omega], axis=-1).astype(T.dtype, copy=False)


def revolute_twist(axis: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Unit twist of a revolute joint: rotation about ``axis`` through ``point``.

    axis: (*, 3) unit vectors; point: (*, 3) -> (*, 6) as (-axis x point, axis).
    """
    axis = np.asarray(axis)
    point = np.asarray(point)
    return np.concatenate([-np.cross(axis, point), np.broadcast_to(axis, point.shape)], axis=-1)


def revolute_exp(axis: np.ndarray, point: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """exp(theta * hat(xi)) for revolute twists, the fast path of :func:`se3_exp`.

    axis: (*, 3) unit; point: (*, 3); theta: (*,) radians -> (*, 4, 4) = [[R, (I - R) q], [0, 1]].
    """
    axis = np.asarray(axis)
    theta = np.asarray(theta)
    K = hat(axis)
    s = np.sin(theta)[..., None, None]
    c = np.cos(theta)[..., None, None]
    R = np.eye(3, dtype=theta.dtype) + s * K + (1.0 - c) * (K @ K)
    out = np.zeros(R.shape[:-2] + (4, 4), dtype=theta.dtype)
    out[..., :3, :3] = R
    out[..., :3, 3] = point - (R @ np.asarray(point)[..., None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def invert_rigid(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid motions. T: (*, 4, 4) -> (*, 4, 4)."""
    T = np.asarray(T)
    out = np.zeros_like(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -(Rt @ T[..., :3, 3:4])[..., 0]
    out[..., 3, 3] = 1.0
    return out


# --- compiled one-at-a-time versions (numba), for loops over particles ---------------------
# The same formulas, branches and series as the numpy functions above, for one twist or
# rotation, written into caller-provided arrays (no temporaries): the per-particle loops of
# mocap.body.root_motion call them. Equal to the numpy versions to rounding
# (tests/body/test_root_motion.py).

from mocap.compiled import HAVE_NUMBA, njit  # noqa: E402  (the compiled helpers below)

if HAVE_NUMBA:

    @njit(cache=True)
    def series_one(theta):
        """mocap.body.twists._series for one angle: a, b, c."""
        t2 = theta * theta
        if theta < 1e-4:
            return 1.0 - t2 / 6.0, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0
        s = np.sin(theta)
        return s / theta, (1.0 - np.cos(theta)) / (theta * theta), (theta - s) / (theta**3)

    @njit(cache=True)
    def hat_into(wx, wy, wz, K):
        K[0, 0], K[0, 1], K[0, 2] = 0.0, -wz, wy
        K[1, 0], K[1, 1], K[1, 2] = wz, 0.0, -wx
        K[2, 0], K[2, 1], K[2, 2] = -wy, wx, 0.0

    @njit(cache=True)
    def mul3_into(A, B, out):
        for i in range(3):
            for j in range(3):
                out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]

    @njit(cache=True)
    def se3_exp_one(xi, R, t, K, K2):
        """se3_exp of one twist (v, omega) into R (3, 3), t (3,) (K, K2: scratch 3x3)."""
        wx, wy, wz = xi[3], xi[4], xi[5]
        theta = np.sqrt(wx * wx + wy * wy + wz * wz)
        a, b, c = series_one(theta)
        hat_into(wx, wy, wz, K)
        mul3_into(K, K, K2)
        for i in range(3):
            t[i] = 0.0
        for i in range(3):
            for j in range(3):
                e = 1.0 if i == j else 0.0
                R[i, j] = e + a * K[i, j] + b * K2[i, j]
                t[i] += (e + b * K[i, j] + c * K2[i, j]) * xi[j]

    @njit(cache=True)
    def so3_exp_one(wx, wy, wz, R, K, K2):
        """so3_exp of one rotation vector into R (3, 3)."""
        theta = np.sqrt(wx * wx + wy * wy + wz * wz)
        a, b, _ = series_one(theta)
        hat_into(wx, wy, wz, K)
        mul3_into(K, K, K2)
        for i in range(3):
            for j in range(3):
                R[i, j] = (1.0 if i == j else 0.0) + a * K[i, j] + b * K2[i, j]

    @njit(cache=True)
    def so3_log_one(R, out):
        """so3_log of one rotation matrix into out (3,) (angle in [0, pi], the axis from the
        symmetric part near pi), as mocap.body.twists.so3_log."""
        cos = min(max((R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0, -1.0), 1.0)
        theta = np.arccos(cos)
        sin = np.sin(theta)
        near_pi = sin < 1e-6
        if theta < 1e-6:
            scale = 0.5
        else:
            scale = theta / (2.0 * (1.0 if near_pi else sin))
        out[0] = (R[2, 1] - R[1, 2]) * scale
        out[1] = (R[0, 2] - R[2, 0]) * scale
        out[2] = (R[1, 0] - R[0, 1]) * scale
        if near_pi and theta > 1.0:
            col = 0
            for k in range(1, 3):
                if (R[k, k] + 1.0) / 2.0 > (R[col, col] + 1.0) / 2.0:
                    col = k
            n0 = (R[0, col] + (1.0 if col == 0 else 0.0)) / 2.0
            n1 = (R[1, col] + (1.0 if col == 1 else 0.0)) / 2.0
            n2 = (R[2, col] + (1.0 if col == 2 else 0.0)) / 2.0
            norm = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            out[0], out[1], out[2] = n0 / norm * theta, n1 / norm * theta, n2 / norm * theta

    @njit(cache=True)
    def se3_log_one(R, t, out, w, K, K2):
        """se3_log of one rigid motion (R (3, 3), t (3,)) into out (6,) (w: scratch (3,))."""
        so3_log_one(R, w)
        theta = np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        if theta < 1e-4:
            coef = 1.0 / 12.0
        else:
            coef = (1.0 - theta * np.sin(theta) / (2.0 * (1.0 - np.cos(theta)))) / (theta * theta)
        hat_into(w[0], w[1], w[2], K)
        mul3_into(K, K, K2)
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += ((1.0 if i == j else 0.0) - 0.5 * K[i, j] + coef * K2[i, j]) * t[j]
            out[i] = s
            out[3 + i] = w[i]
