"""The global twist chi[:6] of particles handled on SE(3), not as a vector.

A twist's rotation part is a rotation vector; near a rotation of pi (a subject facing the
opposite way to the rest pose) two nearly equal poses can have rotation vectors of length
~pi pointing in opposite directions, so averaging, differencing or measuring the spread of
twists coordinate by coordinate fails exactly there (a walk in a circle crosses it every lap).
These functions work on the rigid transforms instead:

* :func:`root_mean`: weighted mean pose (chordal mean of the rotations, projected back onto
  SO(3) by SVD; mean of the posed root point);
* :func:`root_spread`: per-axis spread of the posed root point (m) and of the rotations about
  their mean (rad), for the diffusion of the annealing;
* :func:`interpolate_root`, :func:`predict_root`: geodesic interpolation and constant-velocity
  extrapolation of the root;
* :func:`perturb_root`: the root-local diffusion of the annealing (a rotation about the
  posed root point and a translation, composed on the left).

The per-particle maps (exp, log, the relative rotations of the spread, the perturbation)
run compiled with numba, one loop over the particles built on the one-at-a-time kernels
of :mod:`mocap.body.twists` (its numpy formulas, branches and series), where the numpy
versions spend their
time in the overhead of ~30 small array operations per call (the annealing calls them
several times per layer). Results equal the numpy path to rounding (the last bits of sin,
cos, arccos and of 3x3 products summed in another order; tests/body/test_root_motion.py);
``compiled=False``, or numba missing, runs numpy.
"""

from __future__ import annotations

import numpy as np

from mocap.body.twists import se3_exp, se3_log, so3_exp, so3_log
from mocap.compiled import HAVE_NUMBA, njit  # compiled per-particle maps; numpy is the fallback


def _use_compiled(compiled: bool | None) -> bool:
    return HAVE_NUMBA and (compiled is None or bool(compiled))


if HAVE_NUMBA:
    from mocap.body.twists import mul3_into, se3_exp_one, se3_log_one, so3_exp_one, so3_log_one

    @njit(cache=True)
    def _frames_nb(xi, root, R, p):
        """Rotations R (P, 3, 3) and posed root points p (P, 3) of twists xi (P, 6)."""
        K = np.empty((3, 3))
        K2 = np.empty((3, 3))
        t = np.empty(3)
        for n in range(xi.shape[0]):
            se3_exp_one(xi[n], R[n], t, K, K2)
            for i in range(3):
                p[n, i] = R[n, i, 0] * root[0] + R[n, i, 1] * root[1] + R[n, i, 2] * root[2] + t[i]

    @njit(cache=True)
    def _spread_nb(Rm, R, p, out):
        """out (6,): the std of the posed root points p (P, 3) (numpy's two-pass std) and the
        root mean square of so3_log(Rm^T R_n) per axis, R (P, 3, 3)."""
        P = R.shape[0]
        rel = np.empty((3, 3))
        w = np.empty(3)
        for i in range(6):
            out[i] = 0.0
        for i in range(3):
            m = 0.0
            for n in range(P):
                m += p[n, i]
            m /= P
            for n in range(P):
                d = p[n, i] - m
                out[i] += d * d
            out[i] = np.sqrt(out[i] / P)
        for n in range(P):
            for i in range(3):
                for j in range(3):
                    rel[i, j] = Rm[0, i] * R[n, 0, j] + Rm[1, i] * R[n, 1, j] + Rm[2, i] * R[n, 2, j]
            so3_log_one(rel, w)
            for i in range(3):
                out[3 + i] += w[i] * w[i]
        for i in range(3):
            out[3 + i] = np.sqrt(out[3 + i] / P)

    @njit(cache=True)
    def _root_spread_nb(xi, root, out):
        """:func:`root_spread` in one compiled call: frames, chordal mean rotation (SVD
        projection of the mean of the R_n, summed in numpy's order), spreads."""
        P = xi.shape[0]
        R, p = np.empty((P, 3, 3)), np.empty((P, 3))
        _frames_nb(xi, root, R, p)
        M = np.zeros((3, 3))
        for n in range(P):
            for i in range(3):
                for j in range(3):
                    M[i, j] += R[n, i, j]
        M /= P
        U, _, Vt = np.linalg.svd(M)
        d = np.linalg.det(U @ Vt)
        for i in range(3):
            U[i, 2] *= d
        _spread_nb(U @ Vt, R, p, out)

    @njit(cache=True)
    def _root_mean_nb(xi, weights, root, out):
        """:func:`root_mean` in one compiled call: SVD projection of sum w_n R_n, weighted
        mean of the posed root points, log of the mean pose into out (6,)."""
        P = xi.shape[0]
        R, p = np.empty((P, 3, 3)), np.empty((P, 3))
        _frames_nb(xi, root, R, p)
        M = np.zeros((3, 3))
        pm = np.zeros(3)
        for n in range(P):
            for i in range(3):
                pm[i] += weights[n] * p[n, i]
                for j in range(3):
                    M[i, j] += weights[n] * R[n, i, j]
        U, _, Vt = np.linalg.svd(M)
        d = np.linalg.det(U @ Vt)
        for i in range(3):
            U[i, 2] *= d
        Rm = U @ Vt
        t = np.empty(3)
        for i in range(3):
            t[i] = pm[i] - (Rm[i, 0] * root[0] + Rm[i, 1] * root[1] + Rm[i, 2] * root[2])
        K, K2, w = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
        se3_log_one(Rm, t, out, w, K, K2)

    @njit(cache=True)
    def _step_nb(start, end, step, Rs, ts):
        """T_start = exp(start) into (Rs, ts) and step = log(T_end T_start^-1) (6,)."""
        K, K2 = np.empty((3, 3)), np.empty((3, 3))
        Re, te, w = np.empty((3, 3)), np.empty(3), np.empty(3)
        M, Mt = np.empty((3, 3)), np.empty(3)
        se3_exp_one(start, Rs, ts, K, K2)
        se3_exp_one(end, Re, te, K, K2)
        for i in range(3):                       # T_end T_start^-1 = [Re Rs^T, te - Re Rs^T ts]
            for j in range(3):
                M[i, j] = Re[i, 0] * Rs[j, 0] + Re[i, 1] * Rs[j, 1] + Re[i, 2] * Rs[j, 2]
        for i in range(3):
            Mt[i] = te[i] - (M[i, 0] * ts[0] + M[i, 1] * ts[1] + M[i, 2] * ts[2])
        se3_log_one(M, Mt, step, w, K, K2)

    @njit(cache=True)
    def _perturb_root_nb(xi, noise, root, out):
        """log(Delta_n exp(xi_n)) (P, 6): Delta_n rotates by noise[n, 3:] about the posed root
        point and translates by noise[n, :3] (see :func:`perturb_root`)."""
        R, dR, M = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
        K, K2 = np.empty((3, 3)), np.empty((3, 3))
        t, p, Mt, w = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        for n in range(xi.shape[0]):
            se3_exp_one(xi[n], R, t, K, K2)
            for i in range(3):
                p[i] = R[i, 0] * root[0] + R[i, 1] * root[1] + R[i, 2] * root[2] + t[i]
            so3_exp_one(noise[n, 3], noise[n, 4], noise[n, 5], dR, K, K2)
            mul3_into(dR, R, M)
            for i in range(3):
                # delta t = p - dR p + noise_v; M t = dR t + delta t
                dp = dR[i, 0] * p[0] + dR[i, 1] * p[1] + dR[i, 2] * p[2]
                Mt[i] = dR[i, 0] * t[0] + dR[i, 1] * t[1] + dR[i, 2] * t[2] + (p[i] - dp + noise[n, i])
            se3_log_one(M, Mt, out[n], w, K, K2)

    @njit(cache=True)
    def _interpolate_nb(step, Rs, ts, u, out):
        """log(exp(u_n step) T_start) (N, 6), T_start = (Rs, ts)."""
        E, M = np.empty((3, 3)), np.empty((3, 3))
        K, K2 = np.empty((3, 3)), np.empty((3, 3))
        t, Mt, w, xi = np.empty(3), np.empty(3), np.empty(3), np.empty(6)
        for n in range(u.shape[0]):
            for i in range(6):
                xi[i] = u[n] * step[i]
            se3_exp_one(xi, E, t, K, K2)
            mul3_into(E, Rs, M)
            for i in range(3):
                Mt[i] = E[i, 0] * ts[0] + E[i, 1] * ts[1] + E[i, 2] * ts[2] + t[i]
            se3_log_one(M, Mt, out[n], w, K, K2)


def _transforms(xi: np.ndarray) -> np.ndarray:
    return se3_exp(np.atleast_2d(np.asarray(xi, np.float64)))


def _mean_rotation(R: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """SO(3) projection (SVD) of sum_i w_i R_i, R: (P, 3, 3)."""
    U, _, Vt = np.linalg.svd(np.einsum("p,pij->ij", weights, R))
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def root_mean(xi: np.ndarray, weights: np.ndarray, root_point: np.ndarray,
              compiled: bool | None = None) -> np.ndarray:
    """Weighted mean of twists xi (P, 6) with weights (P,) summing to 1 -> (6,).

    The rotation is the SO(3) projection of sum w_i R_i, the root point (3,) (rest
    position of the root joint) is moved to the weighted mean of its posed positions."""
    if _use_compiled(compiled):
        out = np.empty(6)
        _root_mean_nb(np.ascontiguousarray(np.atleast_2d(xi), np.float64),
                      np.ascontiguousarray(weights, np.float64),
                      np.ascontiguousarray(root_point, np.float64), out)
        return out
    T = _transforms(xi)
    R, t = T[:, :3, :3], T[:, :3, 3]
    Rm = _mean_rotation(R, weights)
    p = weights @ (R @ root_point + t)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = Rm, p - Rm @ root_point
    return se3_log(out[None])[0]


def root_frames(xi: np.ndarray, root_point: np.ndarray,
                compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rotations R (P, 3, 3) and posed root points R root_point + t (P, 3) of twists xi (P, 6)."""
    xi = np.atleast_2d(np.asarray(xi, np.float64))
    if _use_compiled(compiled):
        R, p = np.empty((len(xi), 3, 3)), np.empty((len(xi), 3))
        _frames_nb(np.ascontiguousarray(xi), np.ascontiguousarray(root_point, np.float64), R, p)
        return R, p
    T = _transforms(xi)
    R, t = T[:, :3, :3], T[:, :3, 3]
    return R, R @ root_point + t


def root_spread(xi: np.ndarray, root_point: np.ndarray, compiled: bool | None = None) -> np.ndarray:
    """(6,) std of the posed root point (m, 3) and of the rotations about their (unweighted)
    mean, as rotation vectors R_mean^T R_i (rad, 3)."""
    if _use_compiled(compiled):
        out = np.empty(6)
        _root_spread_nb(np.ascontiguousarray(np.atleast_2d(xi), np.float64),
                        np.ascontiguousarray(root_point, np.float64), out)
        return out
    R, p = root_frames(xi, root_point, compiled)
    Rm = _mean_rotation(R, np.full(len(R), 1.0 / len(R)))
    rel = so3_log(np.einsum("ji,pjk->pik", Rm, R))
    return np.concatenate([p.std(axis=0), np.sqrt((rel**2).mean(axis=0))])


def perturb_root(xi: np.ndarray, noise: np.ndarray, root_point: np.ndarray,
                 compiled: bool | None = None) -> np.ndarray:
    """Twists (P, 6) of Delta_i exp(xi_i): Delta_i rotates by the rotation vector
    noise[i, 3:6] about the posed root point p_i = R_i root_point + t_i and translates by
    noise[i, :3] (the root-local diffusion of :func:`mocap.trackers.apf.perturb`)."""
    xi = np.atleast_2d(np.asarray(xi, np.float64))
    noise = np.asarray(noise, np.float64)
    if _use_compiled(compiled):
        out = np.empty((len(xi), 6))
        _perturb_root_nb(np.ascontiguousarray(xi), np.ascontiguousarray(noise),
                         np.ascontiguousarray(root_point, np.float64), out)
        return out
    P = len(xi)
    T = se3_exp(xi)
    p = (T[:, :3, :3] @ root_point) + T[:, :3, 3]
    dR = so3_exp(noise[:, 3:6])
    delta = np.zeros((P, 4, 4))
    delta[:, :3, :3] = dR
    delta[:, :3, 3] = p - (dR @ p[..., None])[..., 0] + noise[:, :3]
    delta[:, 3, 3] = 1.0
    return se3_log(delta @ T)


def interpolate_root(start: np.ndarray, end: np.ndarray, u: np.ndarray,
                     compiled: bool | None = None) -> np.ndarray:
    """Twists (N, 6) on the geodesic exp(u log(T_end T_start^-1)) T_start for u (N,)."""
    u = np.atleast_1d(np.asarray(u, np.float64))
    if _use_compiled(compiled):
        step, Rs, ts, out = np.empty(6), np.empty((3, 3)), np.empty(3), np.empty((len(u), 6))
        _step_nb(np.asarray(start, np.float64).reshape(6), np.asarray(end, np.float64).reshape(6),
                 step, Rs, ts)
        _interpolate_nb(step, Rs, ts, u, out)
        return out
    Ts, Te = _transforms(start)[0], _transforms(end)[0]
    step = se3_log((Te @ np.linalg.inv(Ts))[None])[0]
    return se3_log(se3_exp(u[:, None] * step) @ Ts)


def predict_root(previous: np.ndarray, last: np.ndarray, damping: float,
                 compiled: bool | None = None) -> np.ndarray:
    """Constant-velocity prediction on SE(3): the last motion T_last T_prev^-1, scaled by
    ``damping``, applied once more to the last pose -> twist (6,)."""
    return interpolate_root(previous, last, np.array([1.0 + damping]), compiled)[0]
