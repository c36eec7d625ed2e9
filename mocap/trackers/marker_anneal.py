"""One frame of annealed search with a pluggable propagation step.

The same algorithm as :func:`mocap.trackers.apf.run_apf` (Deutscher & Reid 2005: survival-rate
annealing, systematic resampling, diffusion following the spread of the resampled set), but
the diffusion is a callable, by default the truncated Gaussian of Canton-Ferrer et al. 2010,
Sec. 3.5 (:func:`mocap.trackers.marker_propagation.propagate_truncated`), instead of the
reflected one. With ``propagate=mocap.trackers.apf.perturb`` and no groups it is
``run_apf``'s algorithm, except that the global twist is interpolated, measured and averaged
on SE(3) (:mod:`mocap.body.root_motion`), which ``run_apf`` does coordinate-wise and
which fails for rotations near pi.

Optional crossover between body parts (the soft partitioning / crossover of Deutscher &
Reid 2005, Sec. 5): when the energy returns per-landmark costs (P, L) and ``groups`` lists
disjoint sets of DOFs with the landmarks they move (e.g. one arm), every layer resamples the
whole particles by their total energy and then, independently, each group's DOFs by the
energy of that group's landmarks alone (with its own survival-rate annealing). A particle
whose left arm fits well can then pass that arm on even if its legs fit badly: the search
stays one annealed filter but no longer needs a particle that is good everywhere at once.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.root_motion import interpolate_root, root_mean, root_spread
from mocap.trackers.apf import (
    APFDiagnostics,
    APFSettings,
    EnergyFn,
    annealing_weights,
    survival_rate,
    systematic_resample,
)
from mocap.trackers.marker_propagation import propagate_truncated

Propagate = Callable[[np.ndarray, np.ndarray, np.ndarray, np.random.Generator, "np.ndarray | None"],
                     np.ndarray]


@dataclass(frozen=True)
class PartGroup:
    """DOF indices (into chi) and landmark indices (columns of the per-landmark energy)."""

    dofs: np.ndarray
    landmarks: np.ndarray


def part_groups(dof_moves: np.ndarray) -> list[PartGroup]:
    """Groups for crossover from ``dof_moves`` (D, L) bool (DOF d moves landmark l): the
    non-root DOFs (index >= 6) joined when they move a common landmark (connected
    components), each with the landmarks its DOFs move."""
    D = dof_moves.shape[0]
    label = np.arange(D)
    changed = True
    while changed:                               # union by shared landmarks, to a fixed point
        changed = False
        for a in range(6, D):
            for b in range(a + 1, D):
                if label[a] != label[b] and np.any(dof_moves[a] & dof_moves[b]):
                    label[label == label[b]] = label[a]
                    changed = True
    groups = []
    for g in np.unique(label[6:]):
        dofs = np.flatnonzero(label == g)
        dofs = dofs[dofs >= 6]
        groups.append(PartGroup(dofs, np.flatnonzero(dof_moves[dofs].any(axis=0))))
    return groups


def run_annealing(energy: EnergyFn, center: np.ndarray, init_std: np.ndarray, limits: np.ndarray,
                  settings: APFSettings, rng: np.random.Generator, keep_particles: bool = False,
                  previous: np.ndarray | None = None, root_point: np.ndarray | None = None,
                  propagate: Propagate = propagate_truncated,
                  groups: Sequence[PartGroup] = ()) -> tuple[np.ndarray, APFDiagnostics]:
    """energy: (P, D) -> (P,) energies, or (P, L) per-landmark costs (summed; needed for
    ``groups``, the crossover of the module docstring). With ``root_point`` the global twist
    is interpolated, measured and averaged on SE(3) (:mod:`mocap.body.root_motion`).
    center: (D,) predicted pose (clipped into ``limits`` (D, 2)); init_std: (D,) first-layer
    diffusion; previous: (D,) last estimate (the first layer spreads between it and center);
    root_point: (3,) rest root joint, for the local root diffusion.
    Returns (estimate (D,), diagnostics); energy evaluations = particles x layers."""
    center = np.clip(np.asarray(center, np.float64), limits[:, 0], limits[:, 1])
    std0 = np.asarray(init_std, np.float64)
    P = settings.particles
    x = np.tile(center, (P, 1))
    if previous is not None:
        previous = np.asarray(previous, np.float64)
        u = rng.random(P)
        x = x - (1.0 - u[:, None]) * (center - previous)
        if root_point is not None:
            x[:, :6] = interpolate_root(previous[:6], center[:6], u)
        x = np.clip(x, limits[:, 0], limits[:, 1])
    x = propagate(x, std0, limits, rng, root_point)
    diag = APFDiagnostics()
    best_x, best_e = center, np.inf
    for m in range(settings.layers):
        costs = np.asarray(energy(x), np.float64)
        E = costs.sum(axis=1) if costs.ndim == 2 else costs
        diag.evaluations += P
        k = int(np.argmin(E))
        if E[k] < best_e:
            best_x, best_e = x[k].copy(), float(E[k])
        parts = part_weights(costs, groups, settings.survival) if costs.ndim == 2 else []
        beta = float(find_betas(E[None], settings.survival)[0]) if not parts else parts[0][2]
        w = annealing_weights(E, beta) if not parts else parts[0][1]
        diag.energy_min.append(float(E.min()))
        diag.energy_mean.append(float(E @ w))
        diag.beta.append(beta)
        diag.survival.append(survival_rate(w))
        diag.ess.append(float(1.0 / (w**2).sum()))
        diag.spread.append(float(x[:, 6:].std(axis=0).mean()))        # joint angles, rad
        if keep_particles:
            diag.particles.append(x.copy())
        if m == settings.layers - 1:
            break
        new = x[systematic_resample(parts[1][1] if parts else w, rng)]
        for dofs, wg, _ in parts[2:]:
            new[:, dofs] = x[systematic_resample(wg, rng)[rng.permutation(P)][:, None], dofs]
        x = new
        scale = settings.shrink ** (m + 1)
        spread = spread_of(x, root_point)
        std = np.maximum(settings.diffusion * spread, settings.min_std_fraction * std0) * scale
        x = propagate(x, std, limits, rng, root_point)
    if settings.estimate == "best":
        return best_x, diag
    wb = parts[1][1] if parts else w
    est = wb @ x
    if root_point is not None:
        est[:6] = root_mean(x[:, :6], wb, root_point)
    for dofs, wg, _ in parts[2:]:
        est[dofs] = wg @ x[:, dofs]
    return est, diag


def spread_of(x: np.ndarray, root_point: np.ndarray | None) -> np.ndarray:
    """Per-DOF spread (D,) of particles (P, D); with ``root_point`` the global twist's part is
    measured on SE(3) (:func:`mocap.body.root_motion.root_spread`)."""
    std = x.std(axis=0)
    if root_point is not None:
        std[:6] = root_spread(x[:, :6], root_point)
    return std


def find_betas(energies: np.ndarray, target: float, iterations: int = 18) -> np.ndarray:
    """:func:`mocap.trackers.apf.find_beta` for several energy sets at once: (G, P) -> (G,)
    betas with survival rate = target (bisection in log10 of the scaled beta)."""
    e = np.asarray(energies, np.float64)
    e = e - e.min(axis=1, keepdims=True)
    spread = e.max(axis=1)
    if not np.all(np.isfinite(spread)):
        raise FloatingPointError("energies must be finite")
    flat = spread <= 1e-12
    x = e / np.where(flat, 1.0, spread)[:, None]
    P = e.shape[1]

    def rate(log_beta):
        w = np.exp(-(10.0 ** log_beta)[:, None] * x)
        return w.sum(axis=1) ** 2 / (P * (w * w).sum(axis=1))

    lo, hi = np.full(len(e), -12.0), np.full(len(e), 12.0)
    saturated = rate(hi) > target
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        above = rate(mid) > target
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    beta = np.where(saturated, 10.0**12, 10.0 ** (0.5 * (lo + hi))) / np.where(flat, 1.0, spread)
    return np.where(flat, 0.0, beta)


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
