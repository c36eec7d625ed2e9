"""The smoothness term E_R (Zhang et al. 2013, Eq. 12): ||chi - P(chi~)||^2, the squared
distance to the pose predicted from the previous estimates."""

from __future__ import annotations

import numpy as np

from mocap.body.root_motion import predict_root


def predict_constant_velocity(previous: list[np.ndarray], damping: float = 1.0) -> np.ndarray:
    """P(chi~): chi_t + damping (chi_t - chi_{t-1}) from the last estimates (D,) each, the
    global twist extrapolated on SE(3) (its rotation vector wraps at pi); the last estimate
    itself when only one is known."""
    if not previous:
        raise ValueError("prediction needs at least one previous estimate")
    if len(previous) == 1:
        return np.array(previous[-1], dtype=np.float64)
    a, b = np.asarray(previous[-2], np.float64), np.asarray(previous[-1], np.float64)
    out = b + damping * (b - a)
    out[:6] = predict_root(a[:6], b[:6], damping)
    return out


def smoothness_energy(chi: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """(P, D), (D,) -> (P,) squared Euclidean distance."""
    return ((np.asarray(chi, np.float64) - predicted) ** 2).sum(axis=1)
