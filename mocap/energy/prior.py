"""The pose prior E_P = E_prior + E_learned (Zhang et al. 2013, Eq. 13-16).

E_prior (Eq. 14): sum_i max^2(0, chi_i^min - chi_i, chi_i - chi_i^max) / sigma^2 over the
joint angles: 0 inside the anatomical limits, quadratic outside.

E_learned (Eq. 15-16): -log of a Parzen-Rosenblatt density with a Gaussian kernel over T
training poses (joint angles only: the global twist says where the body is, not how it is
posed), with the kernel width sigma = the maximum nearest-neighbour distance among the
training samples, as the paper learns it:

    p(chi) = 1 / (sqrt(2 pi) sigma T) * sum_j exp(-||chi - chi_j||^2 / (2 sigma^2))

(the paper's normalisation, written for one dimension, is kept: a constant does not change
the particle weights). Evaluated with log-sum-exp, so far-away poses give large finite
energies, never inf or NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import logsumexp

PRIOR_FORMAT = "mocap-pose-prior-v1"


def joint_limit_energy(angles: np.ndarray, limits: np.ndarray, sigma: float) -> np.ndarray:
    """Eq. 14. angles: (P, n) radians; limits: (n, 2) -> (P,)."""
    over = np.maximum(0.0, np.maximum(limits[:, 0] - angles, angles - limits[:, 1]))
    return (over**2).sum(axis=1) / sigma**2


def max_nearest_neighbour_distance(samples: np.ndarray) -> float:
    """The largest distance from a sample to its nearest other sample. samples: (T, n)."""
    if len(samples) < 2:
        raise ValueError("the Parzen prior needs at least 2 training samples")
    d, _ = cKDTree(samples).query(samples, k=2)
    return float(d[:, 1].max())


@dataclass(frozen=True)
class ParzenPrior:
    """Training poses (T, n) over the named DOFs and the kernel width sigma."""

    samples: np.ndarray
    dof_names: tuple[str, ...]
    sigma: float
    source: str = ""

    @staticmethod
    def fit(samples: np.ndarray, dof_names: tuple[str, ...], source: str = "") -> ParzenPrior:
        samples = np.asarray(samples, np.float64)
        if samples.ndim != 2 or samples.shape[1] != len(dof_names):
            raise ValueError(f"samples must be (T, {len(dof_names)}), got {samples.shape}")
        if not np.all(np.isfinite(samples)):
            raise ValueError("prior training samples contain NaN or inf")
        return ParzenPrior(samples, tuple(dof_names), max_nearest_neighbour_distance(samples),
                           source)

    def energy(self, angles: np.ndarray) -> np.ndarray:
        """E_learned = -log p (Eq. 15-16). angles: (P, n) in ``dof_names`` order -> (P,)."""
        angles = np.asarray(angles, np.float64)
        d2 = ((angles[:, None, :] - self.samples[None]) ** 2).sum(axis=2)      # (P, T)
        T = len(self.samples)
        log_p = logsumexp(-d2 / (2 * self.sigma**2), axis=1) - np.log(np.sqrt(2 * np.pi) * self.sigma * T)
        return -log_p

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, format=np.array(PRIOR_FORMAT), samples=self.samples,
                 dof_names=np.array(self.dof_names), sigma=np.array(self.sigma),
                 source=np.array(self.source))
        tmp.replace(path)
        return path

    @staticmethod
    def load(path: str | Path) -> ParzenPrior:
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"pose prior file not found: {path} (build it with "
                                    "experiments/train_prior.py)")
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z.get("format", "")) != PRIOR_FORMAT:
                    raise ValueError(f"{path}: not a pose prior file (format {PRIOR_FORMAT!r})")
                samples, names = z["samples"], tuple(str(n) for n in z["dof_names"])
                sigma, source = float(z["sigma"]), str(z["source"])
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"{path}: unreadable pose prior ({exc})") from exc
        return ParzenPrior(samples, names, sigma, source)


class PosePrior:
    """E_P of a body's poses: weights and switches for the two terms (for ablations)."""

    def __init__(self, dof_names: tuple[str, ...], limits: np.ndarray, parzen: ParzenPrior | None,
                 limit_sigma: float = 0.1, limit_weight: float = 1.0, learned_weight: float = 1.0):
        self.limits = np.asarray(limits)[6:]
        self.limit_sigma, self.limit_weight, self.learned_weight = limit_sigma, limit_weight, learned_weight
        self.parzen = parzen
        if parzen is not None and learned_weight:
            missing = [n for n in parzen.dof_names if n not in dof_names]
            if missing:
                raise ValueError(f"the pose prior ({parzen.source or 'file'}) uses DOFs the body "
                                 f"lacks: {', '.join(missing)}")
            self.index = np.array([dof_names.index(n) for n in parzen.dof_names])

    def terms(self, chi: np.ndarray) -> dict[str, np.ndarray]:
        """{'prior': E_prior (P,), 'learned': E_learned (P,)} (weighted; zeros when off)."""
        chi = np.asarray(chi, np.float64)
        out = {"prior": np.zeros(len(chi)), "learned": np.zeros(len(chi))}
        if self.limit_weight:
            out["prior"] = self.limit_weight * joint_limit_energy(chi[:, 6:], self.limits,
                                                                  self.limit_sigma)
        if self.parzen is not None and self.learned_weight:
            out["learned"] = self.learned_weight * self.parzen.energy(chi[:, self.index])
        return out

    def __call__(self, chi: np.ndarray) -> np.ndarray:
        t = self.terms(chi)
        return t["prior"] + t["learned"]


def default_prior_path(body_name: str) -> Path:
    """The prior shipped with mocap for a body configuration."""
    from importlib import resources

    return Path(str(resources.files("mocap.energy") / "assets" / f"pose_prior_{body_name}.npz"))
