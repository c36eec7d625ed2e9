"""Kinematically constrained propagation (Canton-Ferrer et al. 2010, Sec. 3.5): particles are
diffused by a truncated multivariate Gaussian whose support is the box of joint limits.

With a diagonal covariance (the per-DOF diffusion of the annealed particle filter) the
truncated multivariate Gaussian factorises into independent truncated univariate Gaussians,
which :func:`truncated_normal` samples exactly by inverting the CDF (no rejection, no
reflection). For a full covariance, :func:`gibbs_truncated_normal` runs the Gibbs sampler
of Kotecha & Djuric 1999 (the paper's ref. [27]), each coordinate drawn from its
truncated conditional.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr, ndtri

from mocap.body.root_motion import perturb_root
from mocap.trackers.apf import reflect_into


def truncated_normal(mean: np.ndarray, std: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                     rng: np.random.Generator) -> np.ndarray:
    """Samples of N(mean, std^2) truncated to [lo, hi], elementwise (broadcast shapes).

    mean must lie inside [lo, hi] (then the CDF interval contains 0.5 and the inverse CDF
    is accurate); std == 0 returns mean; infinite bounds are allowed.
    """
    mean, std = np.asarray(mean, np.float64), np.asarray(std, np.float64)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    shape = np.broadcast_shapes(mean.shape, std.shape)
    moving = std > 0
    still = not moving.all()                 # usually every std > 0: no masking, same values
    safe = np.where(moving, std, 1.0) if still else std
    with np.errstate(invalid="ignore"):
        a, b = ndtr((lo - mean) / safe), ndtr((hi - mean) / safe)
    u = a + rng.random(shape) * (b - a)
    x = np.clip(mean + safe * ndtri(np.clip(u, 1e-300, 1.0 - 1e-16)), lo, hi)
    return np.where(moving, x, mean) if still else x


def gibbs_truncated_normal(mean: np.ndarray, cov: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                           rng: np.random.Generator, start: np.ndarray | None = None,
                           sweeps: int = 5) -> np.ndarray:
    """Samples (P, D) of N(mean (P, D), cov (D, D)) truncated to the box [lo, hi] (D,),
    by ``sweeps`` Gibbs sweeps from ``start`` (default: mean, which must be inside).

    Coordinate i is drawn from its conditional N(m_i + S_i,-i S_-i,-i^-1 (x_-i - m_-i),
    S_ii - S_i,-i S_-i,-i^-1 S_-i,i) truncated to [lo_i, hi_i]. Singular directions
    (zero variance) stay at their start.
    """
    mean = np.atleast_2d(np.asarray(mean, np.float64))
    x = np.array(mean if start is None else start, np.float64)
    P, D = x.shape
    prec = np.linalg.pinv(np.asarray(cov, np.float64))
    for _ in range(sweeps):
        for i in range(D):
            q = prec[i, i]
            if q <= 0:
                continue
            # conditional of a Gaussian from its precision: var = 1/Q_ii,
            # mean = m_i - (1/Q_ii) sum_{j != i} Q_ij (x_j - m_j)
            dev = x - mean
            cm = mean[:, i] - (dev @ prec[i] - q * dev[:, i]) / q
            x[:, i] = truncated_normal(cm, np.sqrt(1.0 / q), lo[i], hi[i], rng)
    return x


def propagate_truncated(x: np.ndarray, std: np.ndarray, limits: np.ndarray, rng: np.random.Generator,
                        root_point: np.ndarray | None = None) -> np.ndarray:
    """Diffuse particles (P, D) with per-DOF std (D,): the joint angles x[:, 6:] by the
    Gaussian truncated to ``limits`` (D, 2) (exact, :func:`truncated_normal`); the global
    twist x[:, :6] (unbounded) by the local root perturbation of
    :func:`mocap.trackers.apf.perturb` (translation and rotation about the posed root point).
    """
    std = np.asarray(std, np.float64)
    root_std = np.where(np.arange(len(std)) < 6, std, 0.0)
    out = np.array(x, np.float64)
    if np.any(root_std):
        # perturb(x, root_std, ...)[:, :6], without its work on the columns overwritten below:
        # the same normals drawn (all D columns: the generator's stream is unchanged)
        noise = rng.normal(size=x.shape) * root_std
        if root_point is not None:
            out[:, :6] = perturb_root(out[:, :6], noise[:, :6], root_point)
        else:
            out[:, :6] += noise[:, :6]
        out[:, :6] = reflect_into(out[:, :6], limits[:6])
    out[:, 6:] = truncated_normal(x[:, 6:], std[6:], limits[6:, 0], limits[6:, 1], rng)
    return out
