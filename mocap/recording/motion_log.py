"""What a reviewer needs beside the meshes: the motion itself and the tracker's decisions.

Entities (timeline ``frame``):

    plots/motion/chi/<dof>          every pose coordinate (root twist, joint angles in degrees)
    plots/decisions/apf_called      1 when the hybrid called its APF on the frame
    plots/decisions/misaligned      number of misaligned limbs
    plots/decisions/limb_error/<limb>   the misalignment detector's error per limb
    log/decisions                   one line per frame: "frame 12: APF on l_knee, l_ankle"
    log/shape                       one line per shape refinement: keyframes, E_S before and
                                    after, kept or not (its values also under plots/shape/)
    run/shape                       shape coefficients alpha (text, logged when they change)
    views/<view>/landmarks          reprojected 3D landmarks (keypoint runs), next to the
                                    detections

Diagnostics are read through :func:`mocap.export.motion.decisions`, the one adapter. Rows go
into a :class:`mocap.recording.columns.Columns` batch (sent with ``send_columns``); the shape
text, logged only when it changes, directly to the recording.
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from mocap.cameras import project
from mocap.export.motion import decisions
from mocap.recording.columns import Columns


class MotionLogger:
    def __init__(self, dof_names, rig_small=None):
        self.dof_names = tuple(dof_names)
        self.rig_small = rig_small
        self.alpha = None
        self._styled: dict[str, tuple] = {}

    def frame(self, rec: rr.RecordingStream, cols: Columns, f: int, estimate) -> None:
        """Frame ``f``'s motion and decisions into ``cols``; ``rec``'s time must be frame ``f``."""
        chi = np.asarray(estimate.chi, np.float64)
        for d, name in enumerate(self.dof_names):
            cols.scalar(f"plots/motion/chi/{name}", f, chi[d] if d < 6 else np.rad2deg(chi[d]))
        alpha = np.asarray(estimate.alpha, np.float64)
        if self.alpha is None or not np.array_equal(alpha, self.alpha):
            self.alpha = alpha
            rec.log("run/shape", rr.TextDocument("alpha = " + np.array2string(alpha, precision=3)))
        dec = decisions(estimate.diagnostics)
        if dec["apf_called"] is not None:
            cols.scalar("plots/decisions/apf_called", f, dec["apf_called"])
        if dec["limb_errors"] or dec["misaligned"]:
            cols.scalar("plots/decisions/misaligned", f, len(dec["misaligned"]))
            for limb, err in dec["limb_errors"].items():
                cols.scalar(f"plots/decisions/limb_error/{limb}", f, err)
            for chain, share in dec["unexplained"].items():
                cols.scalar(f"plots/decisions/unexplained/{chain}/share", f, share)
                cols.scalar(f"plots/decisions/unexplained/{chain}/limit", f, dec["unexplained_limit"][chain])
            limbs = ", ".join(dec["misaligned"])
            text = (f"frame {f}: APF on {limbs}" if limbs and dec["apf_called"]
                    else f"frame {f}: misaligned {limbs}" if limbs else f"frame {f}: all limbs aligned")
            if dec["patrol"]:
                text += "; patrol search of " + ", ".join(dec["apf_free_dofs"])
            over = [f"{c} {100 * v:.2f}% > {100 * dec['unexplained_limit'][c]:.2f}%"
                    for c, v in dec["unexplained"].items() if v > dec["unexplained_limit"][c]]
            if over:
                text += " (unexplained pixels: " + ", ".join(over) + ")"
            cols.text("log/decisions", f, text, "WARN" if dec["misaligned"] else "INFO")
        shape = dec["shape_update"]
        if shape:
            frames = ", ".join(str(k) for k in shape["keyframes"])
            kept = "kept" if shape["accepted"] else "not kept"
            cols.text("log/shape", f, f"frame {f}: shape searched on keyframes {frames}: E_S "
                      f"{shape['energy_before']:.4f} -> {shape['energy_after']:.4f}, {kept}")
        if dec["lost"]:
            cols.text("log/decisions", f, f"frame {f}: tracker lost", "ERROR")

    def landmarks(self, rec: rr.RecordingStream, cols: Columns, f: int, names, landmarks) -> None:
        """Reprojected landmarks (L, 3) in each view at frame ``f``, at the views' logged
        resolution (their style and labels static, logged once)."""
        if self.rig_small is None or landmarks is None:
            return
        px = project(self.rig_small, np.asarray(landmarks, np.float64)).astype(np.float32)   # (C, L, 2)
        for c, view in enumerate(self.rig_small.names):
            if self._styled.get(view) != tuple(names or ()):
                self._styled[view] = tuple(names or ())
                rec.log(f"views/{view}/landmarks", rr.Points2D.from_fields(
                    radii=1.5, colors=[60, 220, 255], labels=list(names) if names else None), static=True)
            cols.add(f"views/{view}/landmarks", rr.Points2D, f, positions=px[c])
