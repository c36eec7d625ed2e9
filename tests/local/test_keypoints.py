"""Keypoints as point-line correspondences (mocap/local/keypoints.py): the residual's
Jacobian against finite differences, the robust weights, and false detections that do not
pull the fit."""

import numpy as np
import pytest

from mocap.body.catalogue import make_landmark_set
from mocap.body.jacobian import dof_frames
from mocap.cameras import ring_rig
from mocap.energy.markers import MarkerObservation, pinhole_project
from mocap.local.keypoints import keypoint_lines, tukey_weights
from mocap.local.optimize import optimize_pose
from mocap.local.solver import PointLines, apply_delta, linear_system, point_line_residuals

NAMES = ("pelvis", "head", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist",
         "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")


@pytest.fixture(scope="module")
def scene(body64):
    rig = ring_rig(8, 3.5, 1.5, 400, 300, fov_deg=45, look_at=(0, 0, 0.9))
    lms = make_landmark_set(body64, list(NAMES))
    shaped = body64.shaped(np.zeros(body64.num_shape))
    chi = np.zeros(body64.num_dofs)
    chi[6:] = 0.5 * body64.limits[6:].mean(axis=1) + 0.1      # a pose away from the limits
    return rig, lms, shaped, chi


def observe(rig, points, false=None):
    """One candidate per landmark and view at the exact projection of ``points`` (L, 3); in
    ``false``: {(landmark, view): pixel offset} the true one is missed and a false one is there,
    ``offset`` from it (a second slot, empty otherwise)."""
    u, _ = pinhole_project(rig, points[None], compiled=False)
    L, C = u.shape[1:3]
    xy = np.zeros((L, C, 2, 2))
    valid = np.zeros((L, C, 2), bool)
    xy[:, :, 0], valid[:, :, 0] = u[0], True
    for (lm, c), off in (false or {}).items():
        xy[lm, c, 1], valid[lm, c, 1] = u[0, lm, c] + off, True
        valid[lm, c, 0] = False
    return MarkerObservation(xy, valid, np.ones((L, C, 2)))


def test_tukey_weights_are_one_at_zero_and_zero_from_the_gate():
    w = tukey_weights(np.array([0.0, 5.0, 10.0, 30.0]), 10.0)
    np.testing.assert_allclose(w, [1.0, 0.75**2, 0.0, 0.0])


def test_keypoint_residual_jacobian_matches_finite_differences(body64, scene):
    """The keypoint correspondences' linear system A (solver.linear_system, the landmark on its
    joint) is the derivative of e = X(chi) x d - m along every DOF's update (apply_delta)."""
    rig, lms, shaped, chi = scene
    X = lms.positions(shaped, chi[None])[0]
    rng = np.random.default_rng(0)
    obs = observe(rig, X + rng.normal(0, 0.01, X.shape))           # rays near, not through, X
    corr = keypoint_lines(X, lms.joint, obs, rig, gate_px=40.0, weight=2.0)
    assert len(corr) == len(NAMES) * len(rig)
    w, q, _ = dof_frames(body64, shaped.axes, shaped.rest_joints, chi)
    e0, A, wt = linear_system(body64, corr, w, q)
    np.testing.assert_allclose(e0, point_line_residuals(X[np.repeat(np.arange(len(NAMES)), len(rig))],
                                                        corr.d, corr.m).reshape(-1), atol=1e-12)
    eps = 1e-6
    for k in range(body64.num_dofs):
        step = np.zeros(body64.num_dofs)
        step[k] = eps
        Xk = lms.positions(shaped, apply_delta(body64, chi, step)[None])[0]
        ek = point_line_residuals(Xk[np.repeat(np.arange(len(NAMES)), len(rig))], corr.d, corr.m)
        np.testing.assert_allclose((ek.reshape(-1) - e0) / eps, A[:, k], atol=2e-5,
                                   err_msg=body64.dof_names[k])
    assert np.all((wt > 1.9) & (wt <= 2.0))            # weight x Tukey of a few px off


def fit(body64, lms, shaped, chi, obs, rig, gate_px):
    """Keypoints only (no contours): the local optimiser from ``chi``."""
    empty = PointLines(np.zeros((0, 3)), np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    return optimize_pose(shaped, chi, lambda verts: (empty, {}), iterations=15, damping=1e-3,
                         extra=lambda c: keypoint_lines(lms.positions(shaped, c[None])[0], lms.joint,
                                                        obs, rig, gate_px))[0]


def test_false_detections_do_not_pull_the_fit(body64, scene):
    """From a pose 0.15 rad off in every angle, keypoints alone bring the landmarks back to within
    2 mm. In half the views of the left arm and leg the detection is missed and a false one is
    18 px off (towards one side): with the gate at 20 px the robust fit still lands within 5 mm,
    while the same fit that counts every detection alike (gate 10^4 px, weights ~1) is pulled
    more than 3x further."""
    rig, lms, shaped, chi = scene
    truth = lms.positions(shaped, chi[None])[0]
    start = chi.copy()
    start[6:] += 0.15
    start = np.clip(start, body64.limits[:, 0], body64.limits[:, 1])
    clean = fit(body64, lms, shaped, start, observe(rig, truth), rig, 20.0)
    err = lambda c: np.linalg.norm(lms.positions(shaped, c[None])[0] - truth, axis=1).max()  # noqa: E731
    assert err(clean) < 0.002
    false = {(lms.names.index(n), c): np.array([18.0, 0.0]) for n in ("l_elbow", "l_wrist", "l_knee",
                                                                      "l_ankle") for c in range(0, 8, 2)}
    obs = observe(rig, truth, false)
    robust = fit(body64, lms, shaped, start, obs, rig, 20.0)
    plain = fit(body64, lms, shaped, start, obs, rig, 1e4)
    assert err(robust) < 0.005
    assert err(plain) > 3 * err(robust)


def test_a_detection_beyond_the_gate_gives_no_correspondence(scene):
    rig, lms, shaped, chi = scene
    X = lms.positions(shaped, chi[None])[0]
    obs = observe(rig, X)
    far = MarkerObservation(obs.xy + np.array([25.0, 0.0]), obs.valid, obs.confidence)
    assert len(keypoint_lines(X, lms.joint, far, rig, gate_px=20.0)) == 0
    half = MarkerObservation(obs.xy, obs.valid, np.full(obs.confidence.shape, 0.5))
    assert np.allclose(keypoint_lines(X, lms.joint, half, rig, 20.0).weights, 0.5)
    assert np.allclose(keypoint_lines(X, lms.joint, half, rig, 20.0, use_confidence=False).weights, 1.0)
