"""The silhouette annealed particle filter (Deutscher & Reid 2005, as Zhang et al. 2013 use
it): :func:`run_apf` is the annealing core :func:`mocap.trackers.anneal.anneal` with the
reflected Gaussian diffusion (:func:`perturb`, the global twist perturbed about the posed
root point). The building blocks are re-exported from :mod:`mocap.trackers.anneal`.
"""

from __future__ import annotations

import numpy as np

from mocap.trackers.anneal import (  # noqa: F401  (re-exported: the APF's public names)
    AnnealTrace,
    APFDiagnostics,
    APFSettings,
    EnergyFn,
    LayerTrace,
    anneal,
    annealing_weights,
    find_beta,
    particle_spread,
    perturb,
    reflect_into,
    survival_rate,
    systematic_resample,
)


def run_apf(energy: EnergyFn, center: np.ndarray, init_std: np.ndarray, limits: np.ndarray,
            settings: APFSettings, rng: np.random.Generator, keep_particles: bool = False,
            free: np.ndarray | None = None, previous: np.ndarray | None = None,
            root_point: np.ndarray | None = None) -> tuple[np.ndarray, AnnealTrace]:
    """One frame of annealed search with the reflected Gaussian diffusion; the arguments are
    those of :func:`mocap.trackers.anneal.anneal`. Returns (estimate (D,), trace)."""
    return anneal(energy, center, init_std, limits, settings, rng, propagate=perturb, free=free,
                  previous=previous, root_point=root_point, keep_particles=keep_particles)
