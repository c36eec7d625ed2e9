"""What the evaluation reads of a tracker's output, as a structural type: any per-frame
estimate with a pose, a shape and step diagnostics (e.g. :class:`mocap.trackers.base.Estimate`)
is one. The evaluation imports no tracker module."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np


class FrameEstimate(Protocol):
    """chi: (D,) pose; alpha: (K,) shape; diagnostics: the step's report (run metrics read
    ``energy_evaluations`` and ``apf_called``). An estimate may also carry ``joint_offsets``
    (J, 3) rest-joint corrections or None (:func:`mocap.body.skeleton.joint_offsets_of`)."""

    chi: np.ndarray
    alpha: np.ndarray
    diagnostics: Any


def per_shape(body, alphas: np.ndarray, chis: np.ndarray,
              fn: Callable[[Any, np.ndarray], np.ndarray],
              joint_offsets: np.ndarray | None = None) -> np.ndarray:
    """``fn(shaped, chis)`` (n, ...) over frames whose shapes differ: alphas (K,) for every frame
    or (F, K) one per frame (a tracker that refines its shape while tracking), chis (F, D),
    joint_offsets None, (J, 3) for every frame or (F, J, 3) one per frame (the bodies' rest-joint
    corrections). The frames of each distinct shape are evaluated together; the result is in
    frame order."""
    chis = np.atleast_2d(chis)
    alphas = np.asarray(alphas, np.float64)
    offsets = None if joint_offsets is None else np.asarray(joint_offsets, np.float64)
    if alphas.ndim == 1 and (offsets is None or offsets.ndim == 2):
        return fn(body.shaped(alphas, offsets), chis)
    if alphas.ndim == 1:
        alphas = np.repeat(alphas[None], len(chis), axis=0)
    if len(alphas) != len(chis):
        raise ValueError(f"{len(alphas)} shapes for {len(chis)} poses")
    if offsets is None:
        keys, off_of = alphas, None
    else:
        if offsets.ndim == 2:
            offsets = np.repeat(offsets[None], len(chis), axis=0)
        if len(offsets) != len(chis):
            raise ValueError(f"{len(offsets)} joint offsets for {len(chis)} poses")
        keys = np.hstack([alphas, offsets.reshape(len(offsets), -1)])
        off_of = offsets
    K = alphas.shape[1]
    out = None
    for key in np.unique(keys, axis=0):
        sel = np.flatnonzero((keys == key).all(axis=1))
        d = None if off_of is None else off_of[sel[0]]
        part = np.asarray(fn(body.shaped(key[:K], d), chis[sel]))
        if out is None:
            out = np.empty((len(chis), *part.shape[1:]), part.dtype)
        out[sel] = part
    return out
