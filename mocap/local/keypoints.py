"""2D keypoints as point-line correspondences for the local optimiser (the hybrid's second cue).

A detection of landmark l in view c at the undistorted pixel z is the ray from the camera's
centre through z; the landmark's posed 3D point X_l (attached to its joint, like a contour
vertex to its limb) should lie on it. That is one more point-line correspondence of Eq. 6,
e = X_l x d - m (:mod:`mocap.local.solver`), solved beside the contour correspondences in
the same Gauss-Newton system; its Jacobian is the one of any point of the landmark's limb.

Which detection, and how much it counts (re-chosen at every iteration, so the weights are
those of an iteratively reweighted least squares):

- per landmark and view, the candidate nearest the landmark's projection (several may be
  there: false positives, unlabelled detections), as the marker likelihood's gate does
  (:mod:`mocap.energy.markers`);
- its weight is ``weight`` x Tukey's biweight of the reprojection distance r with scale
  ``gate_px``, (1 - (r / gate)^2)^2, zero at and beyond the gate: a far (false) detection
  does not pull at all, a near one almost fully, and the weight falls smoothly between;
- x the detector's confidence when ``use_confidence``.
"""

from __future__ import annotations

import numpy as np

from mocap.cameras import Rig, pixel_rays, plucker_from_rays
from mocap.energy.markers import MarkerObservation, associate, pinhole_project
from mocap.local.solver import PointLines


def tukey_weights(r: np.ndarray, scale: float) -> np.ndarray:
    """Tukey's biweight (1 - (r / scale)^2)^2 for |r| < scale, else 0; r any shape."""
    u = np.minimum((np.asarray(r, np.float64) / float(scale)) ** 2, 1.0)
    return (1.0 - u) ** 2


def keypoint_lines(points: np.ndarray, limbs: np.ndarray, obs: MarkerObservation, rig: Rig,
                   gate_px: float, weight: float = 1.0, use_confidence: bool = True,
                   near: float = 0.05) -> PointLines:
    """Point-line correspondences of the landmarks to their detections' rays.

    points: (L, 3) posed landmarks (world metres); limbs: (L,) the joint each is attached to;
    obs: the frame's detections arranged per landmark and view (undistorted pixels); rig:
    the cameras without distortion (:func:`mocap.trackers.markers.startup.pinhole_rig`).
    Returns up to L x C correspondences (those with a nonzero weight), weights as in the
    module docstring."""
    points = np.asarray(points, np.float64)
    u, depth = pinhole_project(rig, points[None], compiled=False)      # (1, L, C, 2), (1, L, C)
    z, conf, ok = associate(u[0], depth[0] > near, obs, gate_px)     # nearest, within the gate
    r = np.where(ok, np.sqrt(((z - u[0]) ** 2).sum(axis=-1)), np.inf)
    w = float(weight) * tukey_weights(r, gate_px)
    if use_confidence:
        w = w * np.clip(conf, 0.0, 1.0)
    li, ci = np.nonzero(w > 0)
    if len(li) == 0:
        zero = np.zeros((0, 3))
        return PointLines(zero, np.zeros(0, np.int64), zero, zero, np.zeros(0))
    origin, direction = pixel_rays(rig, np.ascontiguousarray(z.transpose(1, 0, 2)))   # (C, L, 3)
    d, m = plucker_from_rays(origin[ci, li], direction[ci, li])
    return PointLines(points[li], np.asarray(limbs, np.int64)[li], d, m, w[li, ci])
