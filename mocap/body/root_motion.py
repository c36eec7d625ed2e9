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
  extrapolation of the root.
"""

from __future__ import annotations

import numpy as np

from mocap.body.twists import se3_exp, se3_log, so3_log


def _transforms(xi: np.ndarray) -> np.ndarray:
    return se3_exp(np.atleast_2d(np.asarray(xi, np.float64)))


def _mean_rotation(R: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """SO(3) projection (SVD) of sum_i w_i R_i, R: (P, 3, 3)."""
    U, _, Vt = np.linalg.svd(np.einsum("p,pij->ij", weights, R))
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def root_mean(xi: np.ndarray, weights: np.ndarray, root_point: np.ndarray) -> np.ndarray:
    """Weighted mean of twists xi (P, 6) with weights (P,) summing to 1 -> (6,).

    The rotation is the SO(3) projection of sum w_i R_i, the root point (3,) (rest
    position of the root joint) is moved to the weighted mean of its posed positions."""
    T = _transforms(xi)
    R, t = T[:, :3, :3], T[:, :3, 3]
    Rm = _mean_rotation(R, weights)
    p = weights @ (R @ root_point + t)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = Rm, p - Rm @ root_point
    return se3_log(out[None])[0]


def root_spread(xi: np.ndarray, root_point: np.ndarray) -> np.ndarray:
    """(6,) std of the posed root point (m, 3) and of the rotations about their (unweighted)
    mean, as rotation vectors R_mean^T R_i (rad, 3)."""
    T = _transforms(xi)
    R, t = T[:, :3, :3], T[:, :3, 3]
    p = R @ root_point + t
    Rm = _mean_rotation(R, np.full(len(R), 1.0 / len(R)))
    rel = so3_log(np.einsum("ji,pjk->pik", Rm, R))
    return np.concatenate([p.std(axis=0), np.sqrt((rel**2).mean(axis=0))])


def interpolate_root(start: np.ndarray, end: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Twists (N, 6) on the geodesic exp(u log(T_end T_start^-1)) T_start for u (N,)."""
    Ts, Te = _transforms(start)[0], _transforms(end)[0]
    step = se3_log((Te @ np.linalg.inv(Ts))[None])[0]
    return se3_log(se3_exp(np.asarray(u, np.float64)[:, None] * step) @ Ts)


def predict_root(previous: np.ndarray, last: np.ndarray, damping: float) -> np.ndarray:
    """Constant-velocity prediction on SE(3): the last motion T_last T_prev^-1, scaled by
    ``damping``, applied once more to the last pose -> twist (6,)."""
    return interpolate_root(previous, last, np.array([1.0 + damping]))[0]
