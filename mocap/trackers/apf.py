"""The annealed particle filter (Deutscher & Reid 2005, "Articulated body motion capture by
stochastic search", IJCV 61(2)), as both papers use it.

Per frame, L layers of P particles. In layer m the particles are weighted by
w ∝ exp(-beta_m E), with beta_m chosen by bisection so that the survival rate
alpha_m = (sum w)^2 / (P sum w^2) (the effective sample size over P, Deutscher & Reid's
particle survival rate) equals a target alpha (0.5 by default); the set is resampled
(systematic resampling) and diffused by a Gaussian whose per-DOF standard deviation follows
the spread of the resampled set, scaled by ``diffusion`` and shrunk by ``shrink`` each layer
(with a floor), and reflected into the joint limits. The estimate is the weighted mean of the
last layer. All randomness comes from the generator passed in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mocap.body.root_motion import interpolate_root, root_mean, root_spread
from mocap.body.twists import se3_exp, se3_log, so3_exp

EnergyFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class APFSettings:
    particles: int = 100
    layers: int = 15
    survival: float = 0.5          # target survival rate alpha
    diffusion: float = 1.0         # diffusion std = diffusion * spread of the resampled set
    shrink: float = 0.85           # ... times shrink^m in layer m
    min_std_fraction: float = 0.05  # floor: this fraction of the initial std (times shrink^m)
    estimate: str = "mean"          # "mean": weighted mean of the last layer; "best": the
                                    # lowest-energy particle seen in any layer

    def __post_init__(self) -> None:
        if self.particles < 2 or self.layers < 1:
            raise ValueError("the APF needs at least 2 particles and 1 layer")
        if self.estimate not in ("mean", "best"):
            raise ValueError(f"estimate must be 'mean' or 'best', got {self.estimate!r}")
        if not 0.0 < self.survival < 1.0:
            raise ValueError(f"survival rate must be in (0, 1), got {self.survival}")


@dataclass
class APFDiagnostics:
    """Per-layer records of one frame (lists of length L)."""

    energy_min: list[float] = field(default_factory=list)
    energy_mean: list[float] = field(default_factory=list)
    beta: list[float] = field(default_factory=list)
    survival: list[float] = field(default_factory=list)
    ess: list[float] = field(default_factory=list)
    spread: list[float] = field(default_factory=list)      # mean per-DOF std of the particles
    evaluations: int = 0
    particles: list[np.ndarray] = field(default_factory=list)  # (P, D) per layer if kept


def survival_rate(weights: np.ndarray) -> float:
    """alpha = (sum w)^2 / (P sum w^2) in [1/P, 1]."""
    w = np.asarray(weights, np.float64)
    return float(w.sum() ** 2 / (len(w) * (w**2).sum()))


def annealing_weights(energy: np.ndarray, beta: float) -> np.ndarray:
    """Normalised weights exp(-beta (E - min E)) (P,)."""
    w = np.exp(-beta * (energy - energy.min()))
    return w / w.sum()


def find_beta(energy: np.ndarray, target: float, iterations: int = 60) -> float:
    """beta >= 0 with survival_rate(exp(-beta E)) = target (bisection in log beta).

    The rate falls monotonically from 1 (beta = 0) to 1/m (m = number of minima); when all
    energies are equal any beta gives 1, and 0 is returned.
    """
    e = np.asarray(energy, np.float64)
    spread = e.max() - e.min()
    if not np.isfinite(spread):
        raise FloatingPointError("energies must be finite")
    if spread <= 1e-12:
        return 0.0
    x = (e - e.min()) / spread                 # beta in units of 1/spread
    lo, hi = -12.0, 12.0                       # log10 of the scaled beta
    if survival_rate(np.exp(-(10**hi) * x)) > target:
        return 10**hi / spread
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if survival_rate(np.exp(-(10**mid) * x)) > target:
            lo = mid
        else:
            hi = mid
    return 10 ** (0.5 * (lo + hi)) / spread


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices (P,) drawn by systematic resampling: unbiased, low variance."""
    P = len(weights)
    positions = (rng.random() + np.arange(P)) / P
    cum = np.cumsum(weights)
    cum[-1] = 1.0
    return np.searchsorted(cum, positions)


def reflect_into(x: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Reflect coordinates (P, D) at the limits (D, 2) (inf = unbounded), then clip: a
    reflected Gaussian that never leaves the box."""
    lo, hi = limits[:, 0], limits[:, 1]
    x = np.where(x > hi, 2 * hi - x, x)
    x = np.where(x < lo, 2 * lo - x, x)
    return np.clip(x, lo, hi)


def perturb(x: np.ndarray, std: np.ndarray, limits: np.ndarray, rng: np.random.Generator,
            root_point: np.ndarray | None = None) -> np.ndarray:
    """Gaussian diffusion of particles (P, D) with per-DOF std (D,), reflected into limits.

    With ``root_point`` (3,) (the rest position of the root joint), the global twist is
    perturbed locally: a translation of std[:3] metres and a rotation of std[3:6] radians
    about the posed root point, composed on the left (exp(xi') = Delta exp(xi)). Additive
    noise on twist coordinates would couple rotation and translation through the distance
    of the body from the world origin.
    """
    P, D = x.shape
    noise = rng.normal(size=(P, D)) * std
    out = x + noise
    if root_point is not None and np.any(std[:6]):
        T = se3_exp(x[:, :6])
        p = (T[:, :3, :3] @ root_point) + T[:, :3, 3]
        dR = so3_exp(noise[:, 3:6])
        delta = np.zeros((P, 4, 4))
        delta[:, :3, :3] = dR
        delta[:, :3, 3] = p - (dR @ p[..., None])[..., 0] + noise[:, :3]
        delta[:, 3, 3] = 1.0
        out[:, :6] = se3_log(delta @ T)
    return reflect_into(out, limits)


def particle_spread(x: np.ndarray, root_point: np.ndarray | None) -> np.ndarray:
    """Per-DOF std of particles (D,), the global part measured on SE(3) if a root point is
    given (rotation vectors wrap at pi: see :mod:`mocap.body.root_motion`)."""
    std = x.std(axis=0)
    if root_point is not None:
        std[:6] = root_spread(x[:, :6], root_point)
    return std


def run_apf(energy: EnergyFn, center: np.ndarray, init_std: np.ndarray, limits: np.ndarray,
            settings: APFSettings, rng: np.random.Generator, keep_particles: bool = False,
            free: np.ndarray | None = None, previous: np.ndarray | None = None,
            root_point: np.ndarray | None = None) -> tuple[np.ndarray, APFDiagnostics]:
    """One frame of annealed search.

    center: (D,) predicted pose; previous: (D,) the last estimate, optional: the first layer
    is then spread along the motion, each particle at previous + u (center - previous),
    u ~ U(0, 1), before diffusion (Zhang et al.: particles "constructed by a linear
    interpolation between the predicted pose and the estimated pose from the previous
    frame"); init_std: (D,) first-layer diffusion; limits: (D, 2); free: (D,) bool, DOFs
    searched (the others stay at ``center``); root_point: see :func:`perturb`.
    Returns (estimate (D,), diagnostics).
    """
    D = len(center)
    free = np.ones(D, bool) if free is None else np.asarray(free, bool)
    std0 = np.where(free, init_std, 0.0)
    P = settings.particles
    x = np.tile(np.asarray(center, np.float64), (P, 1))
    if previous is not None:
        u = rng.random((P, 1))
        step = np.where(free, np.asarray(center) - previous, 0.0)
        x = x - (1.0 - u) * step
        if root_point is not None and free[:6].any():
            x[:, :6] = interpolate_root(np.asarray(previous)[:6], np.asarray(center)[:6], u[:, 0])
    x = perturb(x, std0, limits, rng, root_point)
    diag = APFDiagnostics()
    w = np.full(P, 1.0 / P)
    best_x, best_e = np.asarray(center, np.float64), np.inf
    for m in range(settings.layers):
        E = energy(x)
        diag.evaluations += P
        k = int(np.argmin(E))
        if E[k] < best_e:
            best_x, best_e = x[k].copy(), float(E[k])
        beta = find_beta(E, settings.survival)
        w = annealing_weights(E, beta)
        diag.energy_min.append(float(E.min()))
        diag.energy_mean.append(float(E @ w))
        diag.beta.append(float(beta))
        diag.survival.append(survival_rate(w))
        diag.ess.append(float(1.0 / (w**2).sum()))
        diag.spread.append(float(x[:, free].std(axis=0).mean()) if free.any() else 0.0)
        if keep_particles:
            diag.particles.append(x.copy())
        if m == settings.layers - 1:
            break
        x = x[systematic_resample(w, rng)]
        scale = settings.shrink ** (m + 1)
        spread = particle_spread(x, root_point)
        std = np.maximum(settings.diffusion * spread, settings.min_std_fraction * std0) * scale
        x = perturb(x, np.where(free, std, 0.0), limits, rng, root_point)
    if settings.estimate == "best":
        return best_x, diag
    est = np.where(free, w @ x, center)
    if root_point is not None and free[:6].any():
        est[:6] = root_mean(x[:, :6], w, root_point)
    return est, diag
