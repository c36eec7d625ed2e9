"""The marker tracker's search: the annealed particle filter (:func:`mocap.trackers.apf.anneal`) with the
truncated Gaussian of Canton-Ferrer et al. 2010, Sec. 3.5
(:func:`mocap.trackers.markers.propagation.propagate_truncated`) as its propagation, and
crossover between body parts (the soft partitioning / crossover of Deutscher & Reid 2005,
Sec. 5): when the energy returns per-landmark costs (P, L) and ``groups`` lists disjoint
sets of DOFs with the landmarks they move (e.g. one arm), every layer resamples the whole
particles by their total energy and then, independently, each group's DOFs by the energy of
that group's landmarks alone (with its own survival-rate annealing). A particle whose left
arm fits well can then pass that arm on even if its legs fit badly.

:func:`part_groups` finds the groups from which DOF moves which landmark.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.trackers.apf import AnnealTrace, EnergyFn, PartGroup, Propagate, anneal
from mocap.trackers.markers.propagation import propagate_truncated
from mocap.trackers.tracker_settings import APFSettings


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
                  groups: Sequence[PartGroup] = ()) -> tuple[np.ndarray, AnnealTrace]:
    """:func:`mocap.trackers.apf.anneal` over all DOFs with the truncated propagation and
    crossover ``groups``. energy: (P, D) -> (P,) energies, or (P, L) per-landmark costs.
    Returns (estimate (D,), trace); energy evaluations = particles x layers."""
    return anneal(energy, center, init_std, limits, settings, rng, propagate=propagate,
                  previous=previous, root_point=root_point, groups=groups,
                  keep_particles=keep_particles)
