"""The marker likelihood's settings (:class:`MarkerLikelihood`), apart from its evaluation
(:mod:`mocap.energy.markers`) so that settings importing them (the marker tracker's,
:mod:`mocap.trackers.markers.settings`) import none of the numeric stack."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MarkerLikelihood:
    """gate_px: tau, the outlier threshold (pixels); min_views: landmarks with candidates in
    fewer views get temporal coherence; coherence_radius: r (metres); coherence_weight:
    multiplies the coherence term (0 disables it); near: minimum depth (m) of a usable view;
    use_confidence: weigh each kept detection by its confidence (module docstring); compiled:
    evaluate with the compiled kernels (:mod:`mocap.energy.marker_kernel`), else
    with the numpy reference."""

    gate_px: float = 30.0
    min_views: int = 3
    coherence_radius: float = 0.15
    coherence_weight: float = 1.0
    near: float = 0.05
    compiled: bool = True
    use_confidence: bool = False

    def __post_init__(self) -> None:
        if not self.gate_px > 0 or not self.coherence_radius > 0:
            raise ValueError("gate_px and coherence_radius must be positive")
