"""What the evaluation reads of a tracker's output, as a structural type: any per-frame
estimate with a pose, a shape and step diagnostics (e.g. :class:`mocap.trackers.base.Estimate`)
is one. The evaluation imports no tracker module."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np


class FrameEstimate(Protocol):
    """chi: (D,) pose; alpha: (K,) shape; diagnostics: the step's report (run metrics read
    ``energy_evaluations`` and ``apf_called``)."""

    chi: np.ndarray
    alpha: np.ndarray
    diagnostics: Any


def per_shape(body, alphas: np.ndarray, chis: np.ndarray,
              fn: Callable[[Any, np.ndarray], np.ndarray]) -> np.ndarray:
    """``fn(shaped, chis)`` (n, ...) over frames whose shapes differ: alphas (K,) for every frame
    or (F, K) one per frame (a tracker that refines its shape while tracking), chis (F, D). The
    frames of each distinct shape are evaluated together; the result is in frame order."""
    chis = np.atleast_2d(chis)
    alphas = np.asarray(alphas, np.float64)
    if alphas.ndim == 1:
        return fn(body.shaped(alphas), chis)
    if len(alphas) != len(chis):
        raise ValueError(f"{len(alphas)} shapes for {len(chis)} poses")
    out = None
    for a in np.unique(alphas, axis=0):
        sel = np.flatnonzero((alphas == a).all(axis=1))
        part = np.asarray(fn(body.shaped(a), chis[sel]))
        if out is None:
            out = np.empty((len(chis), *part.shape[1:]), part.dtype)
        out[sel] = part
    return out
