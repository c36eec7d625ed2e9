"""Joint limits widened from data (issue 34 item 4): where poses retargeted onto our body with wide
bounds (:func:`mocap.clips.retarget.retarget`) go past a DOF's limit, or come within a margin of
it, the limit is moved out to the margin beyond them; a limit the data stay further from stays as
it is (never narrowed), and the
root (unbounded) is untouched. What the shipped limits leave out of the motion library's training
poses is measured by ``experiments/joint_limits.py``."""

from __future__ import annotations

import numpy as np


def widened_limits(limits: np.ndarray, angles: np.ndarray, margin: float = np.deg2rad(2.0),
                   quantile: float = 0.0) -> np.ndarray:
    """limits (D, 2) (rad; +-inf unbounded) widened to contain the data: angles (T, D) (rad, NaN
    where a pose has no value for a DOF). Per DOF the lower limit becomes min(limit, the data's
    ``quantile`` - margin), the upper max(limit, its 1 - ``quantile`` + margin) (quantile 0: the
    data's extremes, every pose inside). -> (D, 2)."""
    limits = np.asarray(limits, np.float64)
    angles = np.asarray(angles, np.float64)
    if limits.ndim != 2 or limits.shape[1] != 2 or angles.ndim != 2 or angles.shape[1] != len(limits):
        raise ValueError(f"widened_limits: limits (D, 2) and angles (T, D), got {limits.shape} and "
                         f"{angles.shape}")
    if not 0.0 <= quantile < 0.5 or not margin >= 0:
        raise ValueError(f"widened_limits: quantile in [0, 0.5) and margin >= 0, got {quantile}, {margin}")
    out = limits.copy()
    seen = np.isfinite(angles).any(axis=0)
    if not seen.any():
        return out
    lo = np.nanquantile(angles[:, seen], quantile, axis=0) - margin
    hi = np.nanquantile(angles[:, seen], 1.0 - quantile, axis=0) + margin
    out[seen, 0] = np.minimum(limits[seen, 0], lo)
    out[seen, 1] = np.maximum(limits[seen, 1], hi)
    return out
