"""The settings of the local optimiser's parts: the contour matcher, the SIFT tracker and the
misalignment check. Each frozen dataclass is the one place its defaults are written; the
parts' keyword arguments default to them."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ContourSettings:
    """The contour matcher's options (:class:`mocap.local.contour.ContourMatcher`, its defaults)."""

    visibility_scale: float = 0.5
    visibility_tolerance_px: float = 1.5
    reject_factor: float = 3.0
    min_reject_px: float = 10.0
    max_distance: float = 0.08
    stride: int = 1
    observed_stride: int = 4


@dataclass(frozen=True)
class SiftSettings:
    """SIFT correspondences (``enabled``) and the options of :class:`mocap.local.sift.SiftTracker`."""

    enabled: bool = True
    scale: float = 0.5
    ratio: float = 0.75
    max_features: int = 400
    weight: float = 0.5
    mask_margin_px: int = 4


@dataclass(frozen=True)
class MisalignmentSettings:
    """The misalignment check's options (:class:`mocap.local.misalignment.MisalignmentDetector`)."""

    threshold: float = 0.15
    resolution: int = 256
    tolerance_px: int = 1
    scale: float | None = None
    relative: bool = True
    baseline_cap: float = 0.15
    unexplained: float = 0.0
    unexplained_window: int = 0
