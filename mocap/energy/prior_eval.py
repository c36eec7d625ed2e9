"""Held-out log-likelihood of pose densities: how probable a density finds poses of
motion types it never saw.

Every density here is a proper probability density over the same n DOFs (radians), so their
log-likelihoods compare. The Parzen prior's energy (:mod:`mocap.energy.prior`, Eq. 16) keeps
the paper's normalisation ``1 / (sqrt(2 pi) sigma T)``, written for one dimension, which is
not a density in n > 1 dimensions (a constant there, harmless inside the APF). For
comparisons we use the n-D Gaussian kernel density

    log p(x) = logsumexp_t( -1/2 sum_d ((x_d - s_td) / h_d)^2 ) - log T - sum_d log h_d - n/2 log(2 pi)

with h_d = sigma for the paper's isotropic kernel, per-DOF h_d for the bandwidth rules
(Scott 1992: h_d = s_d T^(-1/(n+4)); Silverman 1986: h_d = (4 / (n+2))^(1/(n+4)) s_d
T^(-1/(n+4)), s_d the DOF's standard deviation), or a scale on either chosen by the
leave-one-clip-out likelihood on the training set (neighbouring frames of a clip are nearly
the same pose, so leaving out a single sample would pick a far too narrow kernel).
Reported per DOF: mean log p / n (nats per DOF).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from scipy.special import logsumexp

from mocap.energy.prior import ParzenPrior

LOG_2PI = float(np.log(2 * np.pi))


def kde_log_density(x: np.ndarray, samples: np.ndarray, bandwidth: float | np.ndarray,
                    x_groups: np.ndarray | None = None, sample_groups: np.ndarray | None = None,
                    chunk: int = 2048) -> np.ndarray:
    """n-D Gaussian kernel density, log p. x: (N, n); samples: (T, n); bandwidth: scalar or (n,)
    (> 0). With groups (N,) and (T,): each x_i leaves out the samples of its own group
    (leave-one-group-out). -> (N,)."""
    x, samples = np.asarray(x, np.float64), np.asarray(samples, np.float64)
    h = np.broadcast_to(np.asarray(bandwidth, np.float64), (samples.shape[1],))
    if np.any(h <= 0):
        raise ValueError(f"bandwidth must be > 0, got {h.min()}")
    xs, ss = x / h, samples / h
    s2 = (ss**2).sum(axis=1)
    out = np.empty(len(x))
    for a in range(0, len(x), chunk):
        q = xs[a:a + chunk]
        d2 = np.maximum((q**2).sum(axis=1)[:, None] + s2[None] - 2.0 * q @ ss.T, 0.0)   # (c, T)
        logk = -0.5 * d2
        count = np.full(len(q), float(len(ss)))
        if x_groups is not None:
            same = np.asarray(x_groups)[a:a + chunk, None] == np.asarray(sample_groups)[None]
            logk[same] = -np.inf
            count -= same.sum(axis=1)
        out[a:a + chunk] = logsumexp(logk, axis=1) - np.log(count)
    return out - np.log(h).sum() - 0.5 * len(h) * LOG_2PI


def parzen_log_density(prior: ParzenPrior, x: np.ndarray) -> np.ndarray:
    """The paper's prior as an n-D density (isotropic kernel, its sigma). x: (N, n) -> (N,)."""
    return kde_log_density(x, prior.samples, prior.sigma)


def scott_bandwidth(samples: np.ndarray) -> np.ndarray:
    """Scott's rule per DOF. samples: (T, n) -> (n,)."""
    T, n = samples.shape
    return samples.std(axis=0, ddof=1) * T ** (-1.0 / (n + 4))


def silverman_bandwidth(samples: np.ndarray) -> np.ndarray:
    """Silverman's rule of thumb per DOF. samples: (T, n) -> (n,)."""
    T, n = samples.shape
    return (4.0 / (n + 2)) ** (1.0 / (n + 4)) * samples.std(axis=0, ddof=1) * T ** (-1.0 / (n + 4))


def select_bandwidth_scale(samples: np.ndarray, groups: np.ndarray, base: float | np.ndarray,
                           scales: np.ndarray, queries: int = 2000, floor: float = 0.0,
                           rng: np.random.Generator | None = None) -> tuple[float, np.ndarray]:
    """The scale c of ``h = max(c * base, floor)`` with the highest leave-one-group-out mean
    log-likelihood on (up to ``queries`` of) the training samples. samples: (T, n); groups: (T,)
    clip ids. Returns (c, mean log-likelihood per scale (S,))."""
    rng = rng or np.random.default_rng(0)
    pick = np.arange(len(samples))
    if len(samples) > queries:
        pick = np.sort(rng.choice(len(samples), queries, replace=False))
    keep = np.array([np.any(groups != groups[i]) for i in pick])
    pick = pick[keep]
    ll = np.array([kde_log_density(samples[pick], samples, min_bandwidth(c * np.asarray(base), floor),
                                   groups[pick], groups).mean() for c in scales])
    return float(scales[int(np.argmax(ll))]), ll


def min_bandwidth(bandwidth: np.ndarray, floor: float) -> np.ndarray:
    """Per-DOF bandwidths no narrower than ``floor`` (a DOF that barely moves in training)."""
    return np.maximum(np.asarray(bandwidth, np.float64), floor)


def uniform_log_density(limits: np.ndarray) -> float:
    """log of the uniform density within joint limits (n, 2) (radians)."""
    return float(-np.log(np.diff(np.asarray(limits, np.float64), axis=1)).sum())


def defensive_log_density(log_p: np.ndarray, log_u: float, eps: float) -> np.ndarray:
    """log((1 - eps) p + eps u): a density mixed with a broad one (uniform within the limits)
    so that no pose is far less probable than under ``u``. log_p: (N,) -> (N,)."""
    if not 0.0 < eps < 1.0:
        raise ValueError(f"eps={eps}: must be in (0, 1)")
    return np.logaddexp(np.log1p(-eps) + np.asarray(log_p), np.log(eps) + log_u)


def heldout_table(densities: Mapping[str, Callable[[np.ndarray], np.ndarray]],
                  poses_by_type: Mapping[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """Mean log-likelihood per DOF (nats) of each density on each motion type's held-out poses.
    densities: name -> log p, (N, n) -> (N,); poses_by_type: type -> (N, n) (the same n DOFs for
    all). -> {type: {density: mean log p / n}}, plus the row "all" over every pose pooled."""
    out: dict[str, dict[str, float]] = {}
    pooled = {name: [] for name in densities}
    for motion, poses in poses_by_type.items():
        n = poses.shape[1]
        out[motion] = {}
        for name, log_p in densities.items():
            lp = log_p(poses)
            pooled[name].append(lp)
            out[motion][name] = float(lp.mean() / n)
    n = next(iter(poses_by_type.values())).shape[1]
    out["all"] = {name: float(np.concatenate(v).mean() / n) for name, v in pooled.items()}
    return out
