"""What the evaluation reads of a tracker's output, as a structural type: any per-frame
estimate with a pose, a shape and step diagnostics (e.g. :class:`mocap.trackers.base.Estimate`)
is one. The evaluation imports no tracker module."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class FrameEstimate(Protocol):
    """chi: (D,) pose; alpha: (K,) shape; diagnostics: the step's report (run metrics read
    ``energy_evaluations`` and ``apf_called``)."""

    chi: np.ndarray
    alpha: np.ndarray
    diagnostics: Any
