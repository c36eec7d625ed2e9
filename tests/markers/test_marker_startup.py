"""The marker tracker's start-up with other people in view (mocap/trackers/markers/tracker.py
initial_estimate, mocap/trackers/markers/associate.py, mocap/body/bone_lengths.py)."""

import numpy as np
import pytest

from mocap.body.bone_lengths import shrink_to_bounds, skeleton_length_model
from mocap.body.catalogue import make_landmark_set, probe_poses
from mocap.body.skeletons import LAYOUTS
from mocap.body.twists import se3_exp, se3_log
from mocap.cameras import fundamental_matrices, project, rig_from_config
from mocap.data.crowd import crowd_detections
from mocap.data.motion import generate_motion
from mocap.data.sequence import Sequence
from mocap.trackers.markers.associate import associate_people, skeletons_of
from mocap.trackers.markers.startup import pinhole_rig
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]


def tracker(body, rig, seed=0, **overrides):
    return make_tracker("marker_apf", body=body, rig=rig, rng=np.random.default_rng(seed), **overrides)


def two_people(body, rig, offset=(0.7, 0.0, 0.0), frames=1, seed=0):
    """The subject walking at the centre and a taller bystander ``offset`` metres away doing
    the same, both fully seen in every view (1 px noise)."""
    chi = generate_motion(body, "walk", frames, fps=25, seed=3)
    other = chi.copy()
    T = se3_exp(chi[:, :6].astype(np.float64))
    T[:, :3, 3] += offset                                     # the same motion, moved by offset
    other[:, :6] = se3_log(T)
    alphas = np.zeros((2, body.num_shape))
    alphas[0, :3] = [-1.0, 0.5, 0.0]
    alphas[1, :3] = [2.0, -0.5, 0.5]
    det, pts = crowd_detections(body, rig, np.stack([chi, other]), alphas, LABELS, noise_px=1.0, seed=seed)
    return Sequence(name="two_people", rig=rig, fps=25, detections=det), alphas, pts


@pytest.fixture(scope="module")
def rig():
    return rig_from_config("humaneva")


def test_skeletons_are_associated_across_views_by_person(body, rig):
    seq, _, pts = two_people(body, rig)
    det = seq.detections.select(0)
    sk = skeletons_of(det, LABELS, rig)
    people = associate_people(sk, fundamental_matrices(pinhole_rig(rig)), threshold_px=20.0)
    assert len(people) == 2 and all(all(i is not None for i in p) for p, _ in people)
    for person, err in people:                                 # each set holds one true person
        truth = set()
        for c, i in enumerate(person):
            ok = sk.valid[c][i]
            d = [np.abs(sk.xy[c][i][ok] - project(rig[c], pts[n, 0])[ok]).max() for n in range(2)]
            assert min(d) < 6.0                                  # 1 px noise: this skeleton is person n
            truth.add(int(np.argmin(d)))
        assert len(truth) == 1 and err < 5.0


@pytest.mark.parametrize("seed", [0, 1])
def test_a_second_person_in_every_view_does_not_corrupt_the_shape(body, rig, seed):
    seq, alphas, _ = two_people(body, rig, seed=seed)
    trk = tracker(body, rig, seed=seed)
    chi, alpha = trk.initial_estimate(frame_of(seq, 0))
    model, names = skeleton_length_model(body)
    _, joints = body.rest(np.stack([alpha, alphas[0]]))
    fitted, true = model.lengths(np.asarray(joints, np.float64))
    assert np.abs(model.z_scores(fitted)).max() <= 3.0                  # within the model's bounds
    legs = [names.index(n) for n in ("l_hip-l_knee", "l_knee-l_ankle", "r_hip-r_knee", "r_knee-r_ankle")]
    np.testing.assert_allclose(fitted[legs], true[legs], atol=0.03)     # the subject's legs, not a mix
    assert "associated person (2 in view)" in trk.start_up["chosen"]


def test_a_fit_beyond_the_bounds_is_shrunk_not_replaced_by_the_mean(body):
    model, _ = skeleton_length_model(body)
    alpha = np.zeros(body.num_shape)
    alpha[:3] = [4.0, 3.0, -2.0]                                       # far outside the model
    _, joints = body.rest(alpha[None])
    assert model.implausible(model.lengths(np.asarray(joints[0], np.float64)), 3.0).any()
    shrunk, scale = shrink_to_bounds(body, alpha, model, 3.0)
    _, joints = body.rest(shrunk[None])
    z = model.z_scores(model.lengths(np.asarray(joints[0], np.float64)))
    assert np.abs(z).max() <= 3.0 and np.abs(z).max() > 2.9            # at the bound, not the mean
    np.testing.assert_allclose(shrunk, scale * alpha)
    inside = 0.3 * alpha
    np.testing.assert_allclose(shrink_to_bounds(body, inside, model, 3.0)[0], inside)


def test_neck_base_and_mid_hip_are_midpoints_of_their_joints_in_any_pose(body):
    lms = make_landmark_set(body, ["neck_base", "mid_hip"])
    shaped = body.shaped(np.linspace(-1, 1, body.num_shape))
    chi = probe_poses(body, 4)
    chi[:, :6] = 0.3
    X = lms.positions(shaped, chi).astype(np.float64)
    J = shaped.pose(chi).joints.astype(np.float64)
    idx = body.joint_index
    np.testing.assert_allclose(X[:, 0], J[:, [idx("l_clavicle"), idx("r_clavicle")]].mean(1), atol=1e-5)
    np.testing.assert_allclose(X[:, 1], J[:, [idx("l_hip"), idx("r_hip")]].mean(1), atol=1e-5)
