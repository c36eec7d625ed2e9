"""The weights of the tracking energy's terms (:mod:`mocap.energy.total`, Zhang et al. 2013,
Eq. 10): each term switchable and weighted from configuration (for ablations)."""

from __future__ import annotations

from dataclasses import dataclass

from mocap.settings import check


@dataclass(frozen=True)
class EnergyWeights:
    silhouette: float = 1.0     # w_S (0 switches E_S off)
    smoothness: float = 0.01    # lambda of Eq. 10
    prior: float = 0.0          # w_P (0: no pose prior, the plain APF)

    def __post_init__(self) -> None:
        for name in ("silhouette", "smoothness", "prior"):
            check(self, name, getattr(self, name) >= 0, ">= 0 (0 switches the term off)")

    @property
    def terms(self) -> tuple[str, ...]:
        return tuple(n for n in ("silhouette", "smoothness", "prior") if getattr(self, n))
