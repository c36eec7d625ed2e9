"""The local optimizer: Gauss-Newton iterations of Eq. 9 with fresh correspondences."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.body.jacobian import dof_frames
from mocap.body.model import ShapedBody
from mocap.local import solver
from mocap.local.normal_equations import compiled_available
from mocap.local.posing import dof_frames_compiled
from mocap.local.solver import PointLines, gauss_newton_step, merge

Correspond = Callable[[np.ndarray], tuple[PointLines, dict]]


def optimize_pose(shaped: ShapedBody, chi: np.ndarray, correspond: Correspond, iterations: int = 5,
                  tolerance: float = 1e-4, damping: float = 1e-4, min_correspondences: int = 12,
                  free: np.ndarray | None = None,
                  energy_tolerance: float = 0.0,
                  extra: Callable[[np.ndarray], PointLines] | None = None,
                  active_limits: bool = False) -> tuple[np.ndarray, dict]:
    """Iterate: pose the body, find correspondences, solve the linearised system, update.

    Stops after ``iterations``, when the update is below ``tolerance`` (rad / m), or when the
    last step lowered the weighted RMS point-line distance (measured on fresh
    correspondences) by less than ``energy_tolerance`` x its value: then this iteration's
    update is still applied and the loop ends (``diag["stopped"]`` says why). An iteration
    whose system cannot be solved skips its update and says why in the diagnostics; the
    pose returned is always finite. ``extra``: pose (D,) -> correspondences solved beside
    ``correspond``'s (e.g. keypoints, :mod:`mocap.local.keypoints`), found anew each iteration.
    ``active_limits``: each step solved within the joint limits
    (:func:`~mocap.local.solver.gauss_newton_step`), not clipped to them after.
    """
    if solver.LEGACY:
        energy_tolerance = 0.0
    body = shaped.model
    chi = np.asarray(chi, np.float64)
    diag: dict = {"iterations": 0, "skipped": [], "correspondences": [], "rms_m": [],
                  "stopped": "iterations"}
    for it in range(iterations):
        verts = shaped.vertices(chi)[0].astype(np.float64)      # pose()'s, without the joints
        corr, info = correspond(verts)
        if extra is not None:
            corr = merge([corr, extra(chi)])
        diag["correspondences"].append(len(corr))
        diag.setdefault("per_iteration", []).append(info)
        if solver.LEGACY or not compiled_available():
            w, q, _ = dof_frames(body, shaped.axes, shaped.rest_joints, chi)
        else:                            # the same frames compiled (mocap.local.posing)
            w, q = dof_frames_compiled(body, shaped.axes, shaped.rest_joints, chi)
        step = gauss_newton_step(body, chi, corr, w, q, damping=damping,
                                 min_correspondences=min_correspondences, free=free,
                                 active_limits=active_limits)
        diag["iterations"] = it + 1
        diag["rms_m"].append(step.rms_before)
        if not step.ok:
            diag["skipped"].append(f"iteration {it}: {step.reason}")
            diag["stopped"] = "skipped"
            break
        chi = step.chi
        if np.abs(step.delta).max() < tolerance:
            diag["stopped"] = "update below tolerance"
            break
        rms = diag["rms_m"]
        if energy_tolerance > 0 and len(rms) > 1 and rms[-2] - rms[-1] < energy_tolerance * rms[-2]:
            diag["stopped"] = "energy decrease below tolerance"
            break
    return chi, diag
