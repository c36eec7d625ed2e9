"""The per-person annealed searches of ``marker_people`` run together: every live track's
particles stacked into one batch (T people x P particles), one energy call for all of them
per layer, and the annealing's arithmetic (weights, resampling, propagation) done on the
whole batch at once. Each person keeps its own random generator, drawn in the order
:func:`mocap.trackers.apf.anneal` draws it, and every number is computed by the same
elementwise or row-wise operations as there, so each person's estimate is the one its own
search would give (bit for bit on one machine; tests/markers/test_people_batch.py).

- :class:`PeopleEnergy`: T marker energies (:class:`~mocap.energy.markers.MarkerEnergy`, one
  per person, same landmark set and cameras) as one function (T, P, D) -> (T, P, L), forward
  kinematics, view costs and the coherence term in one compiled call
  (:func:`~mocap.trackers.markers.people_kernel.people_landmark_costs`; each person's
  candidates padded to the largest count with invalid ones, which the kernel skips).
- :func:`anneal_people`: the annealed search of :func:`mocap.trackers.markers.crossover.run_annealing`
  (truncated-Gaussian propagation, crossover groups) for T people in lockstep.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.special import ndtr, ndtri

from mocap.body.root_motion import interpolate_root, perturb_root, root_mean
from mocap.compiled import HAVE_NUMBA, njit
from mocap.energy.markers import MarkerEnergy
from mocap.trackers.apf import (
    AnnealTrace,
    LayerTrace,
    PartGroup,
    find_betas,
    particle_spread,
    reflect_into,
)
from mocap.trackers.tracker_settings import APFSettings

if HAVE_NUMBA:
    from mocap.body.root_motion import _perturb_root_nb, _root_spread_nb
    from mocap.trackers.apf import _column_std_nb
    from mocap.trackers.markers.people_kernel import people_landmark_costs


class PeopleEnergy:
    """T people's marker energies as one batch: ``landmark_costs`` (T, P, D) -> (T, P, L),
    equal to ``energies[n].landmark_costs(chi[n])`` for each n. Compiled energies of one
    landmark set and rig share one kernel call; otherwise each person's energy is called."""

    def __init__(self, energies: Sequence[MarkerEnergy]):
        self.energies = list(energies)
        e0 = self.energies[0]
        self.fused = HAVE_NUMBA and all(
            e.compiled and len(e.landmarks) == len(e0.landmarks) and e.settings == e0.settings
            and e.obs.xy.shape[:2] == e0.obs.xy.shape[:2]
            and all(np.array_equal(a, b) for a, b in zip(e._cams, e0._cams, strict=True))
            and np.array_equal(e.tables.epipoles, e0.tables.epipoles) for e in self.energies)
        if not self.fused:
            return
        K = max(e.obs.xy.shape[2] for e in self.energies)
        L, C = e0.obs.xy.shape[:2]
        T = len(self.energies)
        self.obs_xy = np.zeros((T, L, C, K, 2))
        self.valid = np.zeros((T, L, C, K), bool)
        self.lines = np.zeros((T, L, C, K, C, 3))
        self.weight = np.ones((T, L, C, K))
        for n, e in enumerate(self.energies):
            k = e.obs.xy.shape[2]
            self.obs_xy[n, :, :, :k] = e.obs.xy
            self.valid[n, :, :, :k] = e.obs.valid
            self.lines[n, :, :, :k] = e._lines
            self.weight[n, :, :, :k] = e._weight
        parents, dof_joint, _, _, lm_joint, _ = e0._fk
        self.fk = (parents, dof_joint, np.stack([e._fk[2] for e in self.energies]),
                   np.stack([e._fk[3] for e in self.energies]), lm_joint,
                   np.stack([e._fk[5] for e in self.energies]))
        self.epipoles = np.ascontiguousarray(e0.tables.epipoles, np.float64)
        self.cams = e0._cams
        s = e0.settings
        # the coherence term of MarkerEnergy.costs_of_points, per person
        self.coherent = np.array([bool(s.coherence_weight and e.weak.any()) for e in self.energies])
        self.weak = np.stack([np.asarray(e.weak, bool) for e in self.energies])
        self.predicted = np.stack([np.zeros((L, 3)) if e.predicted is None
                                   else np.asarray(e.predicted, np.float64) for e in self.energies])
        self.coh_scale = float(s.coherence_weight * s.gate_px**2 / (L * C))

    def landmark_costs(self, chi: np.ndarray) -> np.ndarray:
        """(T, P, D) -> (T, P, L) per-landmark energy of each person's particles."""
        if not self.fused:
            return np.stack([e.landmark_costs(x) for e, x in zip(self.energies, chi, strict=True)])
        s = self.energies[0].settings
        parents, dof_joint, axes, rest_joints, lm_joint, rest = self.fk
        chi = np.ascontiguousarray(chi, np.float64)
        return people_landmark_costs(parents, dof_joint, axes, rest_joints, chi, lm_joint, rest, *self.cams,
                                      self.obs_xy, self.valid, self.lines, self.epipoles,
                                      float(s.gate_px) ** 2, float(s.near), self.weight, self.coherent,
                                      self.predicted, self.weak, self.coh_scale,
                                      float(s.coherence_radius**2))


def _truncated_normal(mean: np.ndarray, std: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                      uniforms: np.ndarray) -> np.ndarray:
    """:func:`mocap.trackers.markers.propagation.truncated_normal` with its uniforms given
    (the same values elementwise, for any batch shape)."""
    moving = std > 0
    still = not moving.all()
    safe = np.where(moving, std, 1.0) if still else std
    with np.errstate(invalid="ignore"):
        a, b = ndtr((lo - mean) / safe), ndtr((hi - mean) / safe)
    u = a + uniforms * (b - a)
    x = np.clip(mean + safe * ndtri(np.clip(u, 1e-300, 1.0 - 1e-16)), lo, hi)
    return np.where(moving, x, mean) if still else x


def _propagate(x: np.ndarray, std: np.ndarray, limits: np.ndarray, rngs: Sequence[np.random.Generator],
               root_points: np.ndarray) -> np.ndarray:
    """:func:`mocap.trackers.markers.propagation.propagate_truncated` of T people's particles
    x (T, P, D) with stds (T, D), person n drawing from rngs[n] about root_points[n]."""
    T, P, D = x.shape
    root_std = np.where(np.arange(D) < 6, std, 0.0)                 # (T, D)
    out = np.array(x, np.float64)
    moved = [n for n in range(T) if np.any(root_std[n])]
    if moved:
        noise = np.stack([rngs[n].normal(size=(P, D)) * root_std[n] for n in moved])
        xi, roots = out[moved, :, :6], np.stack([root_points[n] for n in moved])
        if HAVE_NUMBA:                              # perturb_root's compiled loop, every person at once
            root = np.empty((len(moved), P, 6))
            _perturb_roots_nb(np.ascontiguousarray(xi), np.ascontiguousarray(noise[:, :, :6]),
                              np.ascontiguousarray(roots, np.float64), root)
        else:
            root = np.stack([perturb_root(xi[i], noise[i, :, :6], roots[i]) for i in range(len(moved))])
        root = reflect_into(root.reshape(-1, 6), limits[:6])
        out[moved, :, :6] = root.reshape(len(moved), P, 6)
    uniforms = np.stack([rng.random((P, D - 6)) for rng in rngs])
    out[:, :, 6:] = _truncated_normal(x[:, :, 6:], std[:, None, 6:], limits[6:, 0], limits[6:, 1], uniforms)
    return out


if HAVE_NUMBA:

    @njit(cache=True)
    def _perturb_roots_nb(xi, noise, roots, out):
        """out[n] = :func:`mocap.body.root_motion.perturb_root` (xi[n], noise[n], roots[n]) for
        twists xi (T, P, 6), noise (T, P, 6), root points (T, 3)."""
        for n in range(xi.shape[0]):
            _perturb_root_nb(xi[n], noise[n], roots[n], out[n])

    @njit(cache=True)
    def _searchsorted_rows(cum, positions, out):
        """out[r] = np.searchsorted(cum[r], positions[r]) (side left) for sorted positions."""
        R, P = cum.shape
        for r in range(R):
            i = 0
            for j in range(positions.shape[1]):
                while i < P and cum[r, i] < positions[r, j]:
                    i += 1
                out[r, j] = i


if HAVE_NUMBA:

    @njit(cache=True)
    def _spreads_nb(x, roots, out):
        """out[n] = :func:`mocap.trackers.apf.particle_spread` (x[n], roots[n]) for x (T, P, D)."""
        root = np.empty(6)
        for n in range(x.shape[0]):
            _column_std_nb(x[n], out[n])
            _root_spread_nb(np.ascontiguousarray(x[n, :, :6]), roots[n], root)
            out[n, :6] = root


def _spreads(x: np.ndarray, root_points: Sequence[np.ndarray]) -> np.ndarray:
    """(T, D) :func:`mocap.trackers.apf.particle_spread` of each person's particles x (T, P, D)."""
    if HAVE_NUMBA and x.dtype == np.float64 and x.shape[2] >= 6:
        out = np.empty(x.shape[0::2])
        _spreads_nb(np.ascontiguousarray(x), np.ascontiguousarray(np.stack(root_points), np.float64), out)
        return out
    return np.stack([particle_spread(x[n], root_points[n]) for n in range(len(x))])


def _systematic(weights: np.ndarray, r: np.ndarray) -> np.ndarray:
    """:func:`mocap.trackers.apf.systematic_resample` of rows of weights (R, P) with their
    uniforms r (R,): indices (R, P)."""
    R, P = weights.shape
    positions = (r[:, None] + np.arange(P)) / P
    cum = np.cumsum(weights, axis=1)
    cum[:, -1] = 1.0
    if HAVE_NUMBA:
        out = np.empty((R, P), np.int64)
        _searchsorted_rows(cum, positions, out)
        return out
    return np.stack([np.searchsorted(c, p) for c, p in zip(cum, positions, strict=True)])


def _weights(costs: np.ndarray, groups: Sequence[PartGroup],
             survival: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`mocap.trackers.apf.part_weights` of T people's costs (T, P, L): weights
    (T, G + 2, P) (total, base, groups) and betas (T, G + 2)."""
    T, P, L = costs.shape
    base = np.ones(L, bool)
    for g in groups:
        base[g.landmarks] = False
    total = costs.sum(axis=2)
    Eb = costs[:, :, base].sum(axis=2) if base.sum() >= 3 else total
    E = np.stack([total, Eb] + [costs[:, :, g.landmarks].sum(axis=2) for g in groups], axis=1)
    E = E.reshape(-1, P)
    betas = find_betas(E, survival)
    W = np.exp(-betas[:, None] * (E - E.min(axis=1, keepdims=True)))
    W /= W.sum(axis=1, keepdims=True)
    return W.reshape(T, -1, P), betas.reshape(T, -1)


def anneal_people(energy: PeopleEnergy, centers: np.ndarray, init_std: np.ndarray, limits: np.ndarray,
                  settings: APFSettings, rngs: Sequence[np.random.Generator], previous: np.ndarray,
                  root_points: Sequence[np.ndarray],
                  groups: Sequence[PartGroup]) -> list[tuple[np.ndarray, AnnealTrace]]:
    """T people's annealed searches in lockstep: :func:`mocap.trackers.apf.anneal` with the
    truncated propagation, crossover ``groups`` (non-empty), every DOF free and the SE(3) root,
    for centers (T, D), init_std (D,), limits (D, 2), previous (T, D) estimates, root_points
    (T, 3), person n drawing from rngs[n]. Returns [(estimate (D,), trace)] per person, each
    what :func:`mocap.trackers.markers.crossover.run_annealing` returns for that person."""
    centers = np.clip(np.asarray(centers, np.float64), limits[:, 0], limits[:, 1])
    T, D = centers.shape
    P = settings.particles
    std0 = np.asarray(init_std, np.float64)
    x = np.repeat(centers[:, None], P, axis=1)                                  # (T, P, D)
    for n in range(T):
        u = rngs[n].random(P)
        x[n] = x[n] - (1.0 - u[:, None]) * (centers[n] - previous[n])
        x[n, :, :6] = interpolate_root(previous[n, :6], centers[n, :6], u)
    x = np.clip(x, limits[:, 0], limits[:, 1])
    x = _propagate(x, np.repeat(std0[None], T, axis=0), limits, rngs, root_points)
    layers: list[list[LayerTrace]] = [[] for _ in range(T)]
    best_x, best_e = centers.copy(), np.full(T, np.inf)
    G = len(groups)
    W = np.empty((T, G + 2, P))
    for m in range(settings.layers):
        costs = energy.landmark_costs(x)                                         # (T, P, L)
        E = costs.sum(axis=2)
        W, betas = _weights(costs, groups, settings.survival)
        spreads = _spreads(x, root_points)
        # the trace of anneal's layer, row by row (the same reductions as on each person's arrays)
        k, e_min = E.argmin(axis=1), E.min(axis=1)
        better = e_min < best_e
        best_x[better], best_e[better] = x[better, k[better]], e_min[better]
        w = W[:, 0]
        w2 = (w**2).sum(axis=1)
        survival, ess = w.sum(axis=1) ** 2 / (P * w2), 1.0 / w2
        spread_mean = spreads.mean(axis=1)
        for n in range(T):
            layers[n].append(LayerTrace(
                energy_min=float(e_min[n]), energy_mean=float(E[n] @ w[n]), beta=float(betas[n, 0]),
                survival=float(survival[n]), ess=float(ess[n]), spread=float(spread_mean[n])))
        if m == settings.layers - 1:
            break
        r = np.empty((T, G + 1))
        perms = np.empty((T, G, P), np.int64)
        for n in range(T):                                  # each generator in anneal's order
            r[n, 0] = rngs[n].random()
            for g in range(G):
                r[n, 1 + g] = rngs[n].random()
                perms[n, g] = rngs[n].permutation(P)
        idx = _systematic(W[:, 1:].reshape(-1, P), r.reshape(-1)).reshape(T, G + 1, P)
        rows = np.arange(T)[:, None]
        new = x[rows, idx[:, 0]]
        for g, grp in enumerate(groups):
            pick = np.take_along_axis(idx[:, 1 + g], perms[:, g], axis=1)        # (T, P)
            new[:, :, grp.dofs] = x[rows[:, :, None], pick[:, :, None], grp.dofs[None, None]]
        x = new
        scale = settings.shrink ** (m + 1)
        spread = _spreads(x, root_points)
        std = np.maximum(settings.diffusion * spread, settings.min_std_fraction * std0) * scale
        x = _propagate(x, std, limits, rngs, root_points)
    out = []
    for n in range(T):
        trace = AnnealTrace(tuple(layers[n]), evaluations=P * len(layers[n]))
        if settings.estimate == "best":
            out.append((best_x[n], trace))
            continue
        xn = x[n]
        wb = W[n, 1]
        est = wb @ xn
        est[:6] = root_mean(xn[:, :6], wb, root_points[n])
        for g, grp in enumerate(groups):
            est[grp.dofs] = W[n, 2 + g] @ xn[:, grp.dofs]
        out.append((est, trace))
    return out
