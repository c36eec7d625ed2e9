"""The marker likelihood (mocap/energy/markers.py): arrangement of detections, per-view costs
against a naive reference, gating and the temporal-coherence term."""

import numpy as np
import pytest

from mocap.body.catalogue import probe_poses
from mocap.body.landmarks import LandmarkSet
from mocap.cameras import fundamental_matrices, project, ring_rig
from mocap.data.sequence import Detections
from mocap.energy.epipolar import symmetric_epipolar_sq
from mocap.energy.markers import (
    EpipolarTables,
    MarkerEnergy,
    MarkerLikelihood,
    arrange_detections,
    pinhole_project,
    view_costs,
)


@pytest.fixture(scope="module")
def rig():
    return ring_rig(4, 3.5, 1.6, 640, 480, fov_deg=45, look_at=(0, 0, 0.9), start_deg=45)


def detections_of(rig, points, names, rng, noise=0.0, extra=()):
    """Labelled detections of points (L, 3) in every view (frame 0), plus extra rows
    (view, label, x, y)."""
    px = project(rig, points)                                          # (C, L, 2)
    C, L = px.shape[:2]
    view = np.repeat(np.arange(C), L)
    label = np.tile(np.arange(L), C)
    xy = px.reshape(-1, 2) + rng.normal(0, noise, (C * L, 2)) if noise else px.reshape(-1, 2)
    for v, lab, x, y in extra:
        view, label = np.r_[view, v], np.r_[label, lab]
        xy = np.vstack([xy, [x, y]])
    n = len(view)
    return Detections(tuple(names), np.zeros(n, np.int64), view, label, xy, np.ones(n))


def test_arranged_detections_put_labels_on_their_landmark_and_unlabelled_on_all(rig):
    det = Detections(("a", "b", "zzz"), np.zeros(5, np.int64), np.array([0, 0, 1, 2, 3]),
                     np.array([0, 0, 1, 2, -1]), np.arange(10.0).reshape(5, 2), np.ones(5))
    obs = arrange_detections(det, ["b", "a"], rig)
    assert obs.xy.shape == (2, 4, 2, 2)                               # K = 2: two "a" in view 0
    np.testing.assert_array_equal(obs.valid[1, 0], [True, True])       # "a" -> landmark 1
    np.testing.assert_allclose(obs.xy[1, 0], [[0, 1], [2, 3]])
    np.testing.assert_array_equal(obs.valid[0, 1], [True, False])      # "b" -> landmark 0
    assert not obs.valid[:, 2].any()                                   # "zzz" is not fitted
    np.testing.assert_array_equal(obs.valid[:, 3, 0], [True, True])    # unlabelled: everyone
    np.testing.assert_array_equal(obs.views_with_candidates(), [2, 2])


def test_view_costs_match_a_naive_per_particle_reference(rig):
    rng = np.random.default_rng(0)
    names = ["p0", "p1", "p2"]
    X0 = np.array([[0.1, 0.0, 1.0], [0.3, -0.2, 1.4], [-0.2, 0.1, 0.4]])
    det = detections_of(rig, X0, names, rng, noise=3.0, extra=[(1, 0, 300.0, 200.0), (2, 2, 10.0, 10.0)])
    obs = arrange_detections(det, names, rig)
    F = fundamental_matrices(rig)
    X = X0 + rng.normal(0, 0.01, (6, 3, 3))                            # 6 particles
    u, depth = pinhole_project(rig, X)
    tau = 30.0
    cost, kept = view_costs(u, depth > 0, obs, EpipolarTables.build(obs, rig, F), tau)
    for p in range(6):
        for lm in range(3):
            for a in range(4):
                d2 = ((obs.xy[lm, a] - u[p, lm, a]) ** 2).sum(-1)
                d2[~obs.valid[lm, a]] = np.inf
                k = int(np.argmin(d2))
                if d2[k] >= tau**2:
                    assert cost[p, lm, a] == tau**2 and not kept[p, lm, a]
                    continue
                z = obs.xy[lm, a, k]
                sym = [symmetric_epipolar_sq(F[a, b], z, u[p, lm, b]) for b in range(4) if b != a]
                ref = min(0.5 * d2[k] + 0.5 * np.mean(sym) / 2, tau**2)
                assert cost[p, lm, a] == pytest.approx(ref, rel=1e-9, abs=1e-9)


def test_energy_is_lowest_at_the_true_pose_and_a_far_outlier_costs_a_miss(body, rig):
    lms = LandmarkSet(body)
    shaped = body.shaped(np.zeros(body.num_shape))
    chi = probe_poses(body, 1)[0] * 0.3
    truth = lms.positions(shaped, chi[None])[0].astype(np.float64)
    rng = np.random.default_rng(2)
    det = detections_of(rig, truth, lms.names, rng, noise=1.0)
    s = MarkerLikelihood(gate_px=30)
    energy = MarkerEnergy(lms, shaped, rig, arrange_detections(det, lms.names, rig), s)
    perturbed = chi + rng.normal(0, 0.05, (50, body.num_dofs))
    E = energy(np.vstack([chi, perturbed]))
    assert np.argmin(E) == 0
    # a landmark whose detections are all moved 200 px away costs the same as undetected
    far = Detections(det.labels, det.frame, det.view, det.label,
                     det.xy + np.where((det.label == 0)[:, None], 200.0, 0.0), det.confidence)
    none = Detections(det.labels, det.frame[det.label != 0], det.view[det.label != 0],
                      det.label[det.label != 0], det.xy[det.label != 0], det.confidence[det.label != 0])
    e_far = MarkerEnergy(lms, shaped, rig, arrange_detections(far, lms.names, rig), s)
    e_none = MarkerEnergy(lms, shaped, rig, arrange_detections(none, lms.names, rig), s)
    assert e_far(chi[None])[0] == pytest.approx(e_none(chi[None])[0], rel=1e-6)


def test_coherence_pulls_weak_landmarks_towards_their_prediction(body, rig):
    lms = LandmarkSet(body)
    shaped = body.shaped(np.zeros(body.num_shape))
    chi = np.zeros(body.num_dofs)
    X = lms.positions(shaped, chi[None])[0].astype(np.float64)
    empty = Detections(lms.names, *(np.zeros(0, np.int64),) * 3, np.zeros((0, 2)), np.zeros(0))
    obs = arrange_detections(empty, lms.names, rig)
    weak = np.zeros(len(lms), bool)
    weak[lms.names.index("l_wrist")] = True
    s = MarkerLikelihood(gate_px=30, coherence_radius=0.1)
    moved = X.copy()
    moved[lms.names.index("l_wrist")] += [0.05, 0, 0]
    e = MarkerEnergy(lms, shaped, rig, obs, s, predicted=moved, weak=weak)
    coh = e.terms(chi)["coherence"][0]
    assert coh == pytest.approx(30**2 * 0.25 / (len(lms) * 4), rel=1e-4)   # (5 cm / 10 cm)^2
    e0 = MarkerEnergy(lms, shaped, rig, obs, s, predicted=X, weak=weak)
    assert e0.terms(chi)["coherence"][0] == pytest.approx(0.0, abs=1e-9)


def test_projection_and_rest_points_equal_the_camera_model_and_the_landmark_set(body, rig):
    """pinhole_project is the camera's undistorted projection K (R X + t) (rig arrays used
    in place, not copied: the rig is unchanged), and MarkerEnergy's rest points (computed
    once for both paths) are the landmark set's, plus offsets when given."""
    lms = LandmarkSet(body)
    shaped = body.shaped(np.zeros(body.num_shape))
    X = lms.positions(shaped, probe_poses(body, 3) * 0.3).astype(np.float64)      # (3, L, 3)
    R0 = rig.R.copy()
    u, depth = pinhole_project(rig, X)
    expected = np.moveaxis(project(rig, X.reshape(-1, 3)), 0, 1).reshape(3, -1, len(rig), 2)
    np.testing.assert_allclose(u, expected, atol=1e-9)
    cam = np.einsum("cij,plj->plci", rig.R, X) + rig.t
    np.testing.assert_allclose(depth, cam[..., 2], atol=1e-12)
    np.testing.assert_array_equal(rig.R, R0)
    det = detections_of(rig, X[0], lms.names, np.random.default_rng(0))
    obs = arrange_detections(det, lms.names, rig)
    offsets = np.random.default_rng(1).normal(0.0, 0.01, (len(lms), 3))
    for compiled in (True, False):
        for off in (None, offsets):
            e = MarkerEnergy(lms, shaped, rig, obs, MarkerLikelihood(gate_px=30), compiled=compiled,
                             rest_offsets=off)
            want = lms.rest_points(shaped).astype(np.float64) + (0.0 if off is None else off)
            np.testing.assert_allclose(e.rest, want.astype(body.dtype), rtol=1e-6)
            if e.compiled:
                np.testing.assert_array_equal(e._fk[-1], want)


def test_arranging_with_prebuilt_view_rigs_is_the_same_with_distortion(body):
    """views=view_rigs(rig) undistorts each view as rig[c] does: identical arrays, on a rig
    with lens distortion (the iterative inverse)."""
    from dataclasses import replace as dc_replace

    from mocap.cameras import Rig, view_rigs

    base = ring_rig(3, 3.5, 1.6, 640, 480, fov_deg=50, look_at=(0, 0, 0.9))
    dist = np.array([-0.2, 0.05, 0.001, -0.002, 0.0])
    rig = Rig(tuple(dc_replace(cam, dist=dist * (1 + 0.1 * i)) for i, cam in enumerate(base)))
    lms = LandmarkSet(body)
    truth = lms.positions(body.shaped(np.zeros(body.num_shape)), probe_poses(body, 1) * 0.3)[0]
    det = detections_of(rig, truth.astype(np.float64), lms.names, np.random.default_rng(3), noise=1.0,
                        extra=[(0, -1, 100.0, 80.0), (2, -1, 500.0, 400.0)])
    a = arrange_detections(det, lms.names, rig)
    b = arrange_detections(det, lms.names, rig, views=view_rigs(rig))
    for x, y in zip((a.xy, a.valid, a.confidence), (b.xy, b.valid, b.confidence), strict=True):
        np.testing.assert_array_equal(x, y)
    raw = arrange_detections(det, lms.names, base)                     # the same pixels, no distortion
    np.testing.assert_array_equal(raw.valid, a.valid)
    assert np.abs(raw.xy[raw.valid] - a.xy[a.valid]).max() > 1.0         # distortion was removed


def test_compiled_projection_equals_numpy_and_handles_points_on_the_camera_plane(body, rig):
    rng = np.random.default_rng(4)
    X = rng.normal(0.0, 1.0, (7, 5, 21, 3)) + [0.0, 0.0, 0.9]
    u1, z1 = pinhole_project(rig, X)
    u0, z0 = pinhole_project(rig, X, compiled=False)
    assert u1.shape == u0.shape == (7, 5, 21, len(rig), 2) and z1.shape == z0.shape
    np.testing.assert_allclose(z1, z0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(u1, u0, rtol=1e-9, atol=1e-9)
    # a point on the camera plane (depth exactly 0): inf / nan as numpy gives, no exception
    from mocap.energy.marker_kernel import project_points

    u, z = np.empty((1, 2, 1, 2)), np.empty((1, 2, 1))
    K = np.array([[[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]]])
    project_points(np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]]), np.eye(3)[None], np.zeros((1, 3)), K, u, z)
    assert np.all(z == 0.0) and not np.isfinite(u).any()
