"""Quality flags of a run without ground truth: things a user must look at before trusting
the motion. Written into metrics.json (``quality``) and printed as warnings.

* ``implausible_bones``: bones of the run's body (fitted shape) outside the PCA shape model's
  mean +- 3 sigma (:mod:`mocap.body.bone_lengths`), e.g. a thigh fitted to two people.
* ``high_reprojection``: median reprojection error (landmark to its keypoint) above
  ``max(reprojection_px, reprojection_fraction x image diagonal)``.
* ``lost_subject``: runs of at least ``lost_frames`` frames in which fewer than a third of
  the landmarks have a detection near them in two or more views.
* warnings the tracker's start-up reported (``extra_flags``, e.g. the fallback to the mean
  shape).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mocap.body.bone_lengths import skeleton_length_model


def lost_runs(lost: np.ndarray, min_length: int) -> list[tuple[int, int]]:
    """[(first, last)] frame ranges of ``lost`` (F,) bool that last >= min_length frames."""
    runs, start = [], None
    for f, v in enumerate([*map(bool, lost), False]):
        if v and start is None:
            start = f
        elif not v and start is not None:
            if f - start >= min_length:
                runs.append((start, f - 1))
            start = None
    return runs


def _landmark_report(diagnostics) -> tuple[float | None, dict | None]:
    """(reprojection px, {landmark: views}) of a step's diagnostics: a dict
    (``reprojection_px``, ``views_per_landmark``) or a typed report with a ``landmarks``
    attribute (``reprojection_px``, ``views``)."""
    if isinstance(diagnostics, Mapping):
        return diagnostics.get("reprojection_px"), diagnostics.get("views_per_landmark")
    lm = getattr(diagnostics, "landmarks", None)
    return getattr(lm, "reprojection_px", None), getattr(lm, "views", None)


def quality_flags(body, alpha: np.ndarray, estimates: Sequence, image_diagonal: float,
                  n_sigma: float = 3.0, reprojection_px: float = 20.0,
                  reprojection_fraction: float = 0.015, lost_frames: int = 5,
                  extra_flags: Sequence[str] = ()) -> dict:
    """{"flags": [str, ...] (empty: nothing found), and the measured values}. ``estimates``:
    the run's estimates (their diagnostics are read when present)."""
    flags: list[str] = []
    model, names = skeleton_length_model(body)
    _, joints = body.rest(np.asarray(alpha, np.float64)[None])
    lengths = model.lengths(np.asarray(joints[0], np.float64))
    z = model.z_scores(lengths)
    bad = [names[i] for i in np.flatnonzero(np.abs(z) > n_sigma)]
    if bad:
        worst = int(np.argmax(np.abs(z)))
        flags.append(f"implausible bone lengths (outside the shape model's +-{n_sigma:g} sigma): "
                     f"{', '.join(bad)}; worst {names[worst]} {1e3 * lengths[worst]:.0f} mm "
                     f"(model {1e3 * model.mean[worst]:.0f} +- {1e3 * model.sigma[worst]:.0f} mm)")
    out = {"bone_length_z_max": float(np.abs(z).max()), "implausible_bones": bad}
    diag = [_landmark_report(e.diagnostics) for e in estimates]
    reproj = np.array([np.nan if r is None else r for r, _ in diag], np.float64)
    if np.isfinite(reproj).any():
        limit = max(reprojection_px, reprojection_fraction * image_diagonal)
        med = float(np.nanmedian(reproj))
        out["reprojection_median_px"], out["reprojection_limit_px"] = med, limit
        if med > limit:
            flags.append(f"high reprojection error: median {med:.1f} px > {limit:.1f} px (wrong layout, "
                         "calibration or person?)")
    views = [v for _, v in diag]
    if views and all(v is not None for v in views):
        lost = np.array([np.mean(np.asarray(list(v.values())) >= 2) < 1 / 3 for v in views])
        runs = lost_runs(lost, lost_frames)
        out["lost_frames"] = int(lost.sum())
        if runs:
            flags.append("lost subject (fewer than a third of the landmarks seen in 2+ views) in frames "
                         + ", ".join(f"{a}-{b}" for a, b in runs))
    flags.extend(extra_flags)
    out["flags"] = flags
    return out
