"""A Gaussian mixture density fitted by expectation-maximisation (numpy only).

    p(x) = sum_k w_k N(x; mu_k, Sigma_k)

with full or diagonal covariances, each regularised by ``reg`` on its diagonal (so a DOF that
barely moves in the training poses cannot make the density a delta). Initialised by k-means++
seeding (Arthur & Vassilvitskii 2007) and a few Lloyd iterations, then EM (Dempster et al.
1977; Bishop 2006, section 9.2.2) in the log domain until the mean log-likelihood gains less
than ``tol`` per iteration. Used as a comparison density for the pose prior
(:mod:`mocap.energy.prior_eval`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

COVARIANCES = ("full", "diag")


@dataclass(frozen=True)
class GaussianMixture:
    """weights (K,) summing to 1, means (K, n), covariances (K, n, n) (diagonal ones stored full)."""

    weights: np.ndarray
    means: np.ndarray
    covariances: np.ndarray

    def component_log_densities(self, x: np.ndarray) -> np.ndarray:
        """log w_k + log N(x_i; mu_k, Sigma_k). x: (N, n) -> (N, K)."""
        x = np.asarray(x, np.float64)
        n = x.shape[1]
        out = np.empty((len(x), len(self.weights)))
        for k, (mu, cov) in enumerate(zip(self.means, self.covariances, strict=True)):
            L = np.linalg.cholesky(cov)
            z = np.linalg.solve(L, (x - mu).T)                           # (n, N)
            log_det = 2.0 * np.log(np.diag(L)).sum()
            out[:, k] = np.log(self.weights[k]) - 0.5 * ((z**2).sum(axis=0) + log_det + n * np.log(2 * np.pi))
        return out

    def log_density(self, x: np.ndarray) -> np.ndarray:
        """log p(x). x: (N, n) -> (N,)."""
        return logsumexp(self.component_log_densities(x), axis=1)


def _kmeans_init(x: np.ndarray, k: int, rng: np.random.Generator, lloyd: int = 10) -> np.ndarray:
    """k-means++ seeds refined by ``lloyd`` Lloyd iterations. x: (N, n) -> centres (k, n)."""
    centres = [x[rng.integers(len(x))]]
    d2 = ((x - centres[0]) ** 2).sum(axis=1)
    for _ in range(1, k):
        p = d2 / d2.sum() if d2.sum() > 0 else np.full(len(x), 1.0 / len(x))
        centres.append(x[rng.choice(len(x), p=p)])
        d2 = np.minimum(d2, ((x - centres[-1]) ** 2).sum(axis=1))
    c = np.array(centres)
    for _ in range(lloyd):
        label = (((x[:, None, :] - c[None]) ** 2).sum(axis=2)).argmin(axis=1)
        for j in range(k):
            if np.any(label == j):
                c[j] = x[label == j].mean(axis=0)
    return c


def _m_step(x: np.ndarray, resp: np.ndarray, covariance: str, reg: float) -> GaussianMixture:
    nk = resp.sum(axis=0) + 1e-12                                           # (K,)
    means = resp.T @ x / nk[:, None]
    n = x.shape[1]
    covs = np.empty((len(nk), n, n))
    for k in range(len(nk)):
        d = x - means[k]
        if covariance == "full":
            covs[k] = (resp[:, k, None] * d).T @ d / nk[k] + reg * np.eye(n)
        else:
            covs[k] = np.diag((resp[:, k, None] * d**2).sum(axis=0) / nk[k] + reg)
    return GaussianMixture(nk / nk.sum(), means, covs)


def fit_gmm(x: np.ndarray, k: int, rng: np.random.Generator, covariance: str = "full",
            reg: float = 1e-4, iterations: int = 300, tol: float = 1e-7
            ) -> tuple[GaussianMixture, np.ndarray]:
    """Fit a K-component mixture to x (N, n) by EM. reg: added to every covariance's diagonal
    (units of x squared). Returns the mixture and the mean log-likelihood per iteration."""
    x = np.asarray(x, np.float64)
    if covariance not in COVARIANCES:
        raise ValueError(f"covariance={covariance!r}: allowed {', '.join(COVARIANCES)}")
    if x.ndim != 2 or len(x) < k or k < 1:
        raise ValueError(f"fit_gmm needs x (N, n) with N >= k >= 1, got {x.shape} and k={k}")
    if reg <= 0:
        raise ValueError(f"reg={reg}: must be > 0")
    centres = _kmeans_init(x, k, rng)
    label = (((x[:, None, :] - centres[None]) ** 2).sum(axis=2)).argmin(axis=1)
    resp = np.eye(k)[label]
    gmm = _m_step(x, resp, covariance, reg)
    trace = []
    for _ in range(iterations):
        logp = gmm.component_log_densities(x)                                # E step
        norm = logsumexp(logp, axis=1)
        trace.append(norm.mean())
        if len(trace) > 1 and trace[-1] - trace[-2] < tol:
            break
        gmm = _m_step(x, np.exp(logp - norm[:, None]), covariance, reg)     # M step
    return gmm, np.array(trace)
