"""The pose prior E_P = E_prior + E_learned (Zhang et al. 2013, Eq. 13-16).

E_prior (Eq. 14): sum_i max^2(0, chi_i^min - chi_i, chi_i - chi_i^max) / sigma^2 over the
joint angles: 0 inside the anatomical limits, quadratic outside.

E_learned (Eq. 15-16): -log of a Parzen-Rosenblatt density with a Gaussian kernel over T
training poses (joint angles only: the global twist says where the body is, not how it is
posed), with the kernel width sigma = the maximum nearest-neighbour distance among the
training samples, as the paper learns it:

    p(chi) = 1 / (sqrt(2 pi) sigma T) * sum_j exp(-||chi - chi_j||^2 / (2 sigma^2))

(the paper's normalisation, written for one dimension, is kept: a constant does not change
the particle weights; :mod:`mocap.energy.prior_eval` has the n-D normalised density for
comparisons of likelihoods). Evaluated with log-sum-exp, so far-away poses give large finite
energies, never inf or NaN.

Priors come from sources (:func:`prior_path`): ``procedural`` (poses of our procedural motion
library, ``pose_prior_<body>.npz``), ``real`` and ``real-paper-sigma`` (retargeted real motion
capture, ``pose_prior_real[_paper_sigma]_<body>.npz``, CC BY-NC 4.0 adapted material: its licence and
attribution travel in the file, :class:`PriorProvenance`, and in ``NOTICE-pose_prior_real.txt``
beside it; the two differ in sigma only).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import logsumexp

from mocap.safe_files import write_npz_atomic

PRIOR_FORMAT = "mocap-pose-prior-v2"
#: formats :meth:`ParzenPrior.load` reads: v1 (samples, DOF names, sigma, source) and v2 (v1 plus
#: the provenance as JSON under ``meta``)
READABLE_FORMATS = ("mocap-pose-prior-v1", PRIOR_FORMAT)
#: prior source -> asset file name in ``mocap/energy/assets`` ({body}: the body's name)
#: "real": sigma by leave-one-motion-type-out likelihood; "real-paper-sigma": sigma by the paper's
#: rule (max nearest-neighbour distance), the same samples (see docs/results/pose_prior.md)
PRIOR_SOURCES = {"procedural": "pose_prior_{body}.npz", "real": "pose_prior_real_{body}.npz",
                 "real-paper-sigma": "pose_prior_real_paper_sigma_{body}.npz"}
#: above this many samples the squared distances use ||a||^2 + ||s||^2 - 2 a.s (one matrix
#: product, ~5x faster at T = 2000); up to it the direct differences (exact; today's priors)
_EXPANSION_MIN_SAMPLES = 1000


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
class PriorProvenance:
    """Where a prior's samples come from (saved with it; empty for v1 files).

    licence: licence and attribution of the data the samples derive from ("" = our own);
    motion_types: the motion types trained on; held_out_types: those kept out (the split's);
    clips: how many clips; clips_sha256: SHA-256 of the sorted ``name sha256`` lines of the
    clips; pool: poses available before selection; selection: how the T samples were chosen;
    retarget: the retargeting version that made the poses; body: the body's name; sigma_rule:
    how sigma was chosen ("" = the paper's max nearest-neighbour distance)."""

    licence: str = ""
    motion_types: tuple[str, ...] = ()
    held_out_types: tuple[str, ...] = ()
    clips: int = 0
    clips_sha256: str = ""
    pool: int = 0
    selection: str = ""
    retarget: str = ""
    body: str = ""
    sigma_rule: str = ""

    def to_json(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_json(d: dict) -> PriorProvenance:
        known = {k: v for k, v in d.items() if k in PriorProvenance.__dataclass_fields__}
        for k in ("motion_types", "held_out_types"):
            known[k] = tuple(known.get(k, ()))
        return PriorProvenance(**known)


def logsumexp_rows(a: np.ndarray) -> np.ndarray:
    """scipy.special.logsumexp(a, axis=1) of a (P, T) float64 -> (P,), with scipy's arithmetic
    (the maxima taken out of the sum, log1p of the rest over their count: the same bits,
    tested) without its array-API dispatch. Rows with a non-finite maximum go to scipy."""
    a = np.asarray(a, np.float64)
    if a.ndim != 2 or a.shape[1] == 0:
        raise ValueError(f"a must be (P, T) with T > 0, got {a.shape}")
    a_max = a.max(axis=1, keepdims=True)
    if not np.isfinite(a_max).all():
        return logsumexp(a, axis=1)
    top = a == a_max
    m = top.sum(axis=1, keepdims=True, dtype=np.float64)
    s = np.exp(np.where(top, -np.inf, a) - a_max).sum(axis=1, keepdims=True)
    s = np.where(s == 0, s, s / m)
    return (np.log1p(s) + np.log(m) + a_max)[:, 0]


@dataclass(frozen=True)
class ParzenPrior:
    """Training poses (T, n) over the named DOFs, the kernel width sigma, a one-line source
    description and the provenance (licence, motion types, clips)."""

    samples: np.ndarray
    dof_names: tuple[str, ...]
    sigma: float
    source: str = ""
    provenance: PriorProvenance = field(default=PriorProvenance())

    @staticmethod
    def fit(samples: np.ndarray, dof_names: tuple[str, ...], source: str = "",
            provenance: PriorProvenance = PriorProvenance()) -> ParzenPrior:
        samples = np.asarray(samples, np.float64)
        if samples.ndim != 2 or samples.shape[1] != len(dof_names):
            raise ValueError(f"samples must be (T, {len(dof_names)}), got {samples.shape}")
        if not np.all(np.isfinite(samples)):
            raise ValueError("prior training samples contain NaN or inf")
        return ParzenPrior(samples, tuple(dof_names), max_nearest_neighbour_distance(samples),
                           source, provenance)

    @cached_property
    def _sample_norms(self) -> np.ndarray:
        return (self.samples**2).sum(axis=1)

    def squared_distances(self, angles: np.ndarray) -> np.ndarray:
        """||angles_p - samples_t||^2. angles: (P, n) -> (P, T)."""
        angles = np.asarray(angles, np.float64)
        if len(self.samples) < _EXPANSION_MIN_SAMPLES:
            return ((angles[:, None, :] - self.samples[None]) ** 2).sum(axis=2)
        d2 = (angles**2).sum(axis=1)[:, None] + self._sample_norms[None] - 2.0 * angles @ self.samples.T
        return np.maximum(d2, 0.0)

    def energy(self, angles: np.ndarray) -> np.ndarray:
        """E_learned = -log p (Eq. 15-16). angles: (P, n) in ``dof_names`` order -> (P,)."""
        d2 = self.squared_distances(angles)                                    # (P, T)
        T = len(self.samples)
        log_p = logsumexp_rows(-d2 / (2 * self.sigma**2)) - np.log(np.sqrt(2 * np.pi) * self.sigma * T)
        return -log_p

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"source": self.source, "samples": len(self.samples), "dofs": len(self.dof_names),
                "sigma": self.sigma, **self.provenance.to_json()}
        return write_npz_atomic(path, dict(
            format=np.array(PRIOR_FORMAT), samples=self.samples, dof_names=np.array(self.dof_names),
            sigma=np.array(self.sigma), source=np.array(self.source),
            meta=np.array(json.dumps(meta, ensure_ascii=False))), compress=False)

    @staticmethod
    def load(path: str | Path) -> ParzenPrior:
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"pose prior file not found: {path} (build the procedural "
                                    "prior with `mocap train-prior`, the real-motion one with "
                                    "experiments/prior_heldout.py --ship)")
        try:
            with np.load(path, allow_pickle=False) as z:
                fmt = str(z.get("format", ""))
                if fmt not in READABLE_FORMATS:
                    raise ValueError(f"{path}: not a pose prior file (format {fmt!r}, readable: "
                                     f"{', '.join(READABLE_FORMATS)})")
                samples, names = z["samples"], tuple(str(n) for n in z["dof_names"])
                sigma, source = float(z["sigma"]), str(z["source"])
                meta = json.loads(str(z["meta"])) if "meta" in z else {}
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"{path}: unreadable pose prior ({exc})") from exc
        if meta and (meta.get("samples") != len(samples) or meta.get("sigma") != sigma):
            raise ValueError(f"{path}: metadata disagree with the arrays (samples {meta.get('samples')} "
                             f"vs {len(samples)}, sigma {meta.get('sigma')} vs {sigma})")
        return ParzenPrior(samples, names, sigma, source, PriorProvenance.from_json(meta))


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


def prior_path(body_name: str, source: str) -> Path:
    """The prior shipped with mocap for a body configuration from a source (``PRIOR_SOURCES``:
    "procedural", "real"). The file may be absent (not shipped for that body):
    :meth:`ParzenPrior.load` says so."""
    from importlib import resources

    if source not in PRIOR_SOURCES:
        raise ValueError(f"unknown pose prior source {source!r}: available {', '.join(PRIOR_SOURCES)}")
    name = PRIOR_SOURCES[source].format(body=body_name)
    return Path(str(resources.files("mocap.energy") / "assets" / name))


def default_prior_path(body_name: str) -> Path:
    """The procedural prior shipped with mocap for a body configuration."""
    return prior_path(body_name, "procedural")
