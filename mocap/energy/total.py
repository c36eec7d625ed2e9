"""The tracking energy E = w_S E_S + lambda E_R + w_P E_P (Zhang et al. 2013, Eq. 10), with
every term switchable and weighted from configuration (for ablations)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.energy.prior import PosePrior
from mocap.energy.silhouette import SilhouetteEnergy, SilhouetteTarget
from mocap.energy.smoothness import smoothness_energy
from mocap.energy.weights import EnergyWeights

EnergyFn = Callable[[np.ndarray], np.ndarray]


class FrameEnergy:
    """E bound to one frame's observation and prediction: callable (P, D) -> (P,).
    ``markers``: a further term (P, D) -> (P,), already weighted, added as ``"markers"`` (the
    two-cue hybrid's marker likelihood, :mod:`mocap.trackers.keypoint_cue`); None: none."""

    def __init__(self, weights: EnergyWeights, silhouette: SilhouetteEnergy | None,
                 target: SilhouetteTarget | None, predicted: np.ndarray | None,
                 prior: PosePrior | None, dof_mask: np.ndarray | None = None,
                 markers: EnergyFn | None = None):
        if weights.silhouette and (silhouette is None or target is None):
            raise ValueError("the silhouette term is on but there is no silhouette observation")
        if weights.prior and prior is None:
            raise ValueError("the prior term is on but no pose prior was given")
        self.w, self.sil, self.target, self.pred, self.prior = weights, silhouette, target, predicted, prior
        self.dof_mask, self.markers = dof_mask, markers
        self.evaluations = 0

    def terms(self, chi: np.ndarray) -> dict[str, np.ndarray]:
        """Weighted terms, each (P,): silhouette, smoothness, prior (E_prior), learned, markers."""
        P = len(chi)
        self.evaluations += P
        out = {}
        if self.w.silhouette:
            out["silhouette"] = self.w.silhouette * self.sil(chi, self.target)
        if self.w.smoothness and self.pred is not None:
            d = chi if self.dof_mask is None else chi[:, self.dof_mask]
            p = self.pred if self.dof_mask is None else self.pred[self.dof_mask]
            out["smoothness"] = self.w.smoothness * smoothness_energy(d, p)
        if self.w.prior:
            for k, v in self.prior.terms(chi).items():
                out[k] = self.w.prior * v
        if self.markers is not None:
            out["markers"] = self.markers(chi)
        return out

    def __call__(self, chi: np.ndarray) -> np.ndarray:
        t = self.terms(chi)
        total = np.zeros(len(chi))
        for v in t.values():
            total += v
        if not np.all(np.isfinite(total)):
            bad = {k: int((~np.isfinite(v)).sum()) for k, v in t.items()}
            raise FloatingPointError(f"non-finite energy values per term: {bad}")
        return total

