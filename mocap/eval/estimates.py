"""What the evaluation reads of a tracker's output, as a structural type: any per-frame
estimate with a pose, a shape and step diagnostics (e.g. :class:`mocap.trackers.base.Estimate`)
is one. The evaluation imports no tracker module."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from mocap.body.skeleton import frames_by_body


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
    groups = frames_by_body(alphas, joint_offsets, len(chis))
    if len(groups) == 1:
        return fn(body.shaped(groups[0][1], groups[0][2]), chis)
    out = None
    for sel, alpha, offsets in groups:
        part = np.asarray(fn(body.shaped(alpha, offsets), chis[sel]))
        if out is None:
            out = np.empty((len(chis), *part.shape[1:]), part.dtype)
        out[sel] = part
    return out
