"""The annealed particle filter (APF): the annealing core every annealed search of this package
runs (Deutscher & Reid 2005, "Articulated body motion capture by stochastic search", IJCV
61(2)); its settings are :class:`mocap.trackers.tracker_settings.APFSettings`.

One frame of search, :func:`anneal`: L layers of P particles. In layer m the particles are
weighted by w ∝ exp(-beta_m E), with beta_m found by bisection (:func:`find_betas`) so that
the survival rate alpha_m = (sum w)^2 / (P sum w^2) (the effective sample size over P)
equals the target; the set is resampled (systematic resampling) and diffused by
``propagate`` with a per-DOF std that follows the spread of the resampled set
(:func:`particle_spread`), scaled by ``diffusion`` and shrunk by ``shrink`` each layer (with
a floor). Only the ``free`` DOFs move; the rest stay at the centre. The estimate is the
weighted mean of the last layer (the global twist averaged on SE(3) when a root point is
given) or the lowest-energy particle seen.

What the callers pass in:
- the silhouette trackers (:func:`run_apf`): the reflected Gaussian
  :func:`perturb`, with the global twist perturbed about the posed root point;
- the hybrid tracker: the same with a free-DOF mask (the misaligned limbs);
- the marker tracker (:func:`mocap.trackers.markers.crossover.run_annealing`): the Gaussian
  truncated to the joint limits and crossover between body parts (``groups``: when the
  energy returns per-landmark costs (P, L), each group's DOFs are resampled by the energy of
  that group's landmarks alone, Deutscher & Reid 2005, Sec. 5);
- the initialisation searches (silhouette pose and shape, annealed inverse kinematics).

All randomness comes from the generator passed in. Each layer is reported as a frozen
:class:`LayerTrace`, the frame as an :class:`AnnealTrace`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.root_motion import interpolate_root, perturb_root, root_mean, root_spread
from mocap.compiled import HAVE_NUMBA, njit  # compiled bisection of the betas; numpy is the fallback
from mocap.trackers.tracker_settings import APFSettings

EnergyFn = Callable[[np.ndarray], np.ndarray]
#: (particles (P, D), std (D,), limits (D, 2), rng, root_point (3,) or None) -> particles (P, D)
Propagate = Callable[[np.ndarray, np.ndarray, np.ndarray, np.random.Generator, "np.ndarray | None"],
                     np.ndarray]

BETA_ITERATIONS = 30       # bisection steps in log10 beta over 24 decades: 2e-8 decades


@dataclass(frozen=True)
class LayerTrace:
    """One annealing layer: energies of its particles, the beta found, the survival rate and
    effective sample size reached, the mean per-DOF spread of the free DOFs (m / rad), and
    the particles (P, D) when kept."""

    energy_min: float
    energy_mean: float
    beta: float
    survival: float
    ess: float
    spread: float
    particles: np.ndarray | None = None


@dataclass(frozen=True)
class AnnealTrace:
    """One frame of annealed search: its layers and the number of energy evaluations."""

    layers: tuple[LayerTrace, ...] = ()
    evaluations: int = 0

    # column views (lists over layers), as the old per-layer lists read
    @property
    def energy_min(self) -> list[float]:
        return [layer.energy_min for layer in self.layers]

    @property
    def energy_mean(self) -> list[float]:
        return [layer.energy_mean for layer in self.layers]

    @property
    def beta(self) -> list[float]:
        return [layer.beta for layer in self.layers]

    @property
    def survival(self) -> list[float]:
        return [layer.survival for layer in self.layers]

    @property
    def ess(self) -> list[float]:
        return [layer.ess for layer in self.layers]

    @property
    def spread(self) -> list[float]:
        return [layer.spread for layer in self.layers]

    @property
    def particles(self) -> list[np.ndarray]:
        return [layer.particles for layer in self.layers if layer.particles is not None]


#: the old name of :class:`AnnealTrace`
APFDiagnostics = AnnealTrace


@dataclass(frozen=True)
class PartGroup:
    """For crossover: DOF indices (into chi) and the columns of the per-landmark energy
    (the landmarks) that weigh them."""

    dofs: np.ndarray
    landmarks: np.ndarray


# -- building blocks -------------------------------------------------------------------------
def survival_rate(weights: np.ndarray) -> float:
    """alpha = (sum w)^2 / (P sum w^2) in [1/P, 1]."""
    w = np.asarray(weights, np.float64)
    return float(w.sum() ** 2 / (len(w) * (w**2).sum()))


def annealing_weights(energy: np.ndarray, beta: float) -> np.ndarray:
    """Normalised weights exp(-beta (E - min E)) (P,)."""
    w = np.exp(-beta * (energy - energy.min()))
    return w / w.sum()


def _find_betas_numpy(energies: np.ndarray, target: float, iterations: int = BETA_ITERATIONS) -> np.ndarray:
    """betas (G,) >= 0 for G energy sets (G, P) at once, each with survival rate = target
    (bisection in log10 of the beta scaled by the energy spread): the numpy reference of
    :func:`find_betas`.

    The rate falls monotonically from 1 (beta = 0) to 1/m (m = number of minima); when all
    energies of a set are equal any beta gives 1, and 0 is returned.
    """
    x, spread, flat = _normalised(energies)
    P = x.shape[1]

    def rate(log_beta):
        w = np.exp(-(10.0 ** log_beta)[:, None] * x)
        return w.sum(axis=1) ** 2 / (P * (w * w).sum(axis=1))

    lo, hi = np.full(len(x), -12.0), np.full(len(x), 12.0)
    saturated = rate(hi) > target
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        above = rate(mid) > target
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    beta = np.where(saturated, 10.0**12, 10.0 ** (0.5 * (lo + hi))) / np.where(flat, 1.0, spread)
    return np.where(flat, 0.0, beta)


if HAVE_NUMBA:

    @njit(cache=True)
    def _rate_nb(x, g, beta):
        """Survival rate of row g of x at beta: (sum w)^2 / (P sum w^2), w = exp(-beta x)."""
        s1 = 0.0
        s2 = 0.0
        for p in range(x.shape[1]):
            w = np.exp(-beta * x[g, p])
            s1 += w
            s2 += w * w
        return s1 * s1 / (x.shape[1] * s2)

    @njit(cache=True)
    def _column_std_nb(x, out):
        """numpy's x.std(axis=0) of a C-ordered (P, D >= 2) array, in its order of
        summation (rows added one after another; D = 1 would be summed pairwise): the same
        bits."""
        P, D = x.shape
        for d in range(D):
            out[d] = 0.0
        for p in range(P):
            for d in range(D):
                out[d] += x[p, d]
        for d in range(D):
            out[d] /= P
        var = np.zeros(D)
        for p in range(P):
            for d in range(D):
                e = x[p, d] - out[d]
                var[d] += e * e
        for d in range(D):
            out[d] = np.sqrt(var[d] / P)

    @njit(cache=True)
    def _bisect_nb(x, target, iterations, out):
        """The bisection of :func:`_find_betas_numpy`, row by row: out[g] = beta (scaled) of
        row g of x (G, P) (energies minus their minimum over their spread)."""
        for g in range(x.shape[0]):
            lo, hi = -12.0, 12.0
            saturated = _rate_nb(x, g, 10.0**hi) > target
            for _ in range(iterations):
                mid = 0.5 * (lo + hi)
                if _rate_nb(x, g, 10.0**mid) > target:
                    lo = mid
                else:
                    hi = mid
            out[g] = 10.0**12 if saturated else 10.0 ** (0.5 * (lo + hi))


def _normalised(energies: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, spread, flat): energies (G, P) minus their row minimum, over their row spread."""
    e = np.asarray(energies, np.float64)
    e = e - e.min(axis=1, keepdims=True)
    spread = e.max(axis=1)
    if not np.all(np.isfinite(spread)):
        raise FloatingPointError("energies must be finite")
    flat = spread <= 1e-12
    return e / np.where(flat, 1.0, spread)[:, None], spread, flat


def find_betas(energies: np.ndarray, target: float, iterations: int = BETA_ITERATIONS,
               compiled: bool | None = None) -> np.ndarray:
    """betas (G,) >= 0 for G energy sets (G, P) at once, each with survival rate = target
    (bisection in log10 of the beta scaled by the energy spread).

    The rate falls monotonically from 1 (beta = 0) to 1/m (m = number of minima); when all
    energies of a set are equal any beta gives 1, and 0 is returned.

    With numba (``compiled`` None or True) the bisection runs compiled, a loop over the
    sets with no temporaries: the same midpoints and comparisons as the numpy reference
    :func:`_find_betas_numpy` (30 vectorised round trips, the cost at the trackers' sizes),
    only the rate's exp and sums rounded differently (last bits); a comparison can then
    differ only where the rate at a midpoint is within rounding of the target, i.e. where
    the crossing is at that midpoint, so both betas are within the bisection's precision
    (24 / 2^iterations decades) of it (tests/trackers/test_apf.py checks them within two
    steps). ``compiled=False`` runs the numpy reference.
    """
    if compiled is None:
        compiled = HAVE_NUMBA
    if not compiled or not HAVE_NUMBA:
        return _find_betas_numpy(energies, target, iterations)
    x, spread, flat = _normalised(energies)
    beta = np.empty(len(x))
    _bisect_nb(x, float(target), int(iterations), beta)
    beta = beta / np.where(flat, 1.0, spread)
    return np.where(flat, 0.0, beta)


def find_beta(energy: np.ndarray, target: float, iterations: int = BETA_ITERATIONS) -> float:
    """beta >= 0 with survival_rate(exp(-beta E)) = target, for one energy set (P,)."""
    return float(find_betas(np.asarray(energy, np.float64)[None], target, iterations)[0])


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
        out[:, :6] = perturb_root(x[:, :6], noise[:, :6], root_point)
    return reflect_into(out, limits)


def particle_spread(x: np.ndarray, root_point: np.ndarray | None) -> np.ndarray:
    """Per-DOF std of particles (D,), the global part measured on SE(3) if a root point is
    given (rotation vectors wrap at pi: see :mod:`mocap.body.root_motion`)."""
    if HAVE_NUMBA and x.ndim == 2 and x.dtype == np.float64 and x.shape[1] >= 2:
        std = np.empty(x.shape[1])
        _column_std_nb(np.ascontiguousarray(x), std)
    else:
        std = x.std(axis=0)
    if root_point is not None:
        std[:6] = root_spread(x[:, :6], root_point)
    return std


def part_weights(costs: np.ndarray, groups: Sequence[PartGroup],
                 survival: float) -> list[tuple[np.ndarray | None, np.ndarray, float]]:
    """Annealed weights from per-landmark costs (P, L), one bisection for all:
    [(None, w_total, beta_total), (None, w_base, beta_base), (dofs_g, w_g, beta_g), ...].
    The base (root and ungrouped DOFs) is weighted by the landmarks no group moves (all
    landmarks if fewer than 3 are left), each group by its own landmarks. Empty without
    groups."""
    if not groups:
        return []
    base = np.ones(costs.shape[1], bool)
    for g in groups:
        base[g.landmarks] = False
    total = costs.sum(axis=1)
    Eb = costs[:, base].sum(axis=1) if base.sum() >= 3 else total
    E = np.stack([total, Eb] + [costs[:, g.landmarks].sum(axis=1) for g in groups])  # (G + 2, P)
    betas = find_betas(E, survival)
    W = np.exp(-betas[:, None] * (E - E.min(axis=1, keepdims=True)))
    W /= W.sum(axis=1, keepdims=True)
    dofs = [None, None] + [g.dofs for g in groups]
    return [(d, W[i], float(betas[i])) for i, d in enumerate(dofs)]


# -- the search ------------------------------------------------------------------------------
def anneal(energy: EnergyFn, center: np.ndarray, init_std: np.ndarray, limits: np.ndarray,
           settings: APFSettings, rng: np.random.Generator, *, propagate: Propagate = perturb,
           free: np.ndarray | None = None, previous: np.ndarray | None = None,
           root_point: np.ndarray | None = None, groups: Sequence[PartGroup] = (),
           keep_particles: bool = False) -> tuple[np.ndarray, AnnealTrace]:
    """One frame of annealed search.

    energy: particles (P, D) -> energies (P,), or per-landmark costs (P, L) (summed; needed
    for ``groups``). center: (D,) predicted pose, clipped into ``limits`` (D, 2);
    init_std: (D,) first-layer diffusion; free: (D,) bool, the DOFs searched (the others stay
    at ``center``; default all); previous: (D,) the last estimate, optional: the first layer
    is then spread along the motion, each particle at previous + u (center - previous),
    u ~ U(0, 1), the global twist interpolated on SE(3) when ``root_point`` is given (Zhang
    et al.: particles "constructed by a linear interpolation between the predicted pose and
    the estimated pose from the previous frame"); root_point: (3,) rest root joint, for the
    root-local diffusion and the SE(3) spread and mean of the global twist.
    Returns (estimate (D,), trace); energy evaluations = particles x layers.
    """
    center = np.clip(np.asarray(center, np.float64), limits[:, 0], limits[:, 1])
    D, P = len(center), settings.particles
    free = np.ones(D, bool) if free is None else np.asarray(free, bool)
    root_free = root_point is not None and bool(free[:6].any()) and D >= 6
    std0 = np.where(free, np.asarray(init_std, np.float64), 0.0)
    x = np.tile(center, (P, 1))
    if previous is not None:
        previous = np.asarray(previous, np.float64)
        u = rng.random(P)
        x = x - (1.0 - u[:, None]) * np.where(free, center - previous, 0.0)
        if root_free:
            x[:, :6] = interpolate_root(previous[:6], center[:6], u)
        x = np.clip(x, limits[:, 0], limits[:, 1])
    x = propagate(x, std0, limits, rng, root_point)
    layers: list[LayerTrace] = []
    best_x, best_e = center, np.inf
    parts: list = []
    for m in range(settings.layers):
        costs = np.asarray(energy(x), np.float64)
        E = costs.sum(axis=1) if costs.ndim == 2 else costs
        k = int(np.argmin(E))
        if E[k] < best_e:
            best_x, best_e = x[k].copy(), float(E[k])
        parts = part_weights(costs, groups, settings.survival) if costs.ndim == 2 else []
        if parts:
            w, beta = parts[0][1], parts[0][2]
        else:
            beta = find_beta(E, settings.survival)
            w = annealing_weights(E, beta)
        spread = particle_spread(x, root_point if root_free else None)[free]
        layers.append(LayerTrace(
            energy_min=float(E.min()), energy_mean=float(E @ w), beta=float(beta),
            survival=survival_rate(w), ess=float(1.0 / (w**2).sum()),
            spread=float(spread.mean()) if len(spread) else 0.0,
            particles=x.copy() if keep_particles else None))
        if m == settings.layers - 1:
            break
        new = x[systematic_resample(parts[1][1] if parts else w, rng)]
        for dofs, wg, _ in parts[2:]:
            new[:, dofs] = x[systematic_resample(wg, rng)[rng.permutation(P)][:, None], dofs]
        x = new
        scale = settings.shrink ** (m + 1)
        spread = particle_spread(x, root_point if root_free else None)
        std = np.maximum(settings.diffusion * spread, settings.min_std_fraction * std0) * scale
        x = propagate(x, np.where(free, std, 0.0), limits, rng, root_point)
    trace = AnnealTrace(tuple(layers), evaluations=P * len(layers))
    if settings.estimate == "best":
        return best_x, trace
    wb = parts[1][1] if parts else w
    est = np.where(free, wb @ x, center)
    if root_free:
        est[:6] = root_mean(x[:, :6], wb, root_point)
    for dofs, wg, _ in parts[2:]:
        est[dofs] = wg @ x[:, dofs]
    return est, trace


def run_apf(energy: EnergyFn, center: np.ndarray, init_std: np.ndarray, limits: np.ndarray,
            settings: APFSettings, rng: np.random.Generator, keep_particles: bool = False,
            free: np.ndarray | None = None, previous: np.ndarray | None = None,
            root_point: np.ndarray | None = None) -> tuple[np.ndarray, AnnealTrace]:
    """One frame of annealed search with the reflected Gaussian diffusion; the arguments are
    those of :func:`anneal`. Returns (estimate (D,), trace)."""
    return anneal(energy, center, init_std, limits, settings, rng, propagate=perturb, free=free,
                  previous=previous, root_point=root_point, keep_particles=keep_particles)
