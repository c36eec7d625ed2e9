"""Several people's searches as one batch (mocap/trackers/markers/batch.py) give what each
person's own search gives; the vectorised skeleton-to-track costs equal np.median's."""

import copy

import numpy as np
import pytest

from mocap.data.crowd import crowd_sequence
from mocap.trackers.markers.batch import PeopleEnergy, anneal_people
from mocap.trackers.markers.crossover import run_annealing
from mocap.trackers.markers.people import _only, skeleton_costs
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

FAST = {"particles": 30, "layers": 4, "init": {"particles": 60, "passes": 2, "layers": 5}}


@pytest.fixture(scope="module")
def frame_one(body):
    """Three people started on the crowd's frame 0; their energies of frame 1 (own skeletons)."""
    seq = crowd_sequence(body=body, frames=20, seed=0)
    people = make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(0), **FAST)
    tracks = people.start(frame_of(seq, 0))
    frame = frame_of(seq, 1)
    rows, _ = people.assign(frame, tracks)
    trackers = [t.tracker for t in tracks]
    predicted = [trk.predict() for trk in trackers]
    energies = [trk.frame_energy(type(frame)(1, detections=_only(frame.detections, r)), p)[0]
                for trk, r, p in zip(trackers, rows, predicted, strict=True)]
    return trackers, predicted, energies


def test_the_batched_energy_equals_each_persons_energy_on_random_particles(frame_one):
    trackers, predicted, energies = frame_one
    assert len(energies) == 3
    rng = np.random.default_rng(7)
    chi = np.stack([p + rng.normal(0, 0.05, (40, len(p))) for p in predicted])      # (T, P, D)
    batch = PeopleEnergy(energies)
    assert batch.fused
    got = batch.landmark_costs(chi)
    for n, e in enumerate(energies):
        np.testing.assert_allclose(got[n], e.landmark_costs(chi[n]), rtol=0, atol=1e-12)
    # a person whose observation holds more candidates (padded for the others) changes nothing
    assert got.shape == (3, 40, len(trackers[0].landmarks))


def test_the_batched_search_gives_each_persons_own_search(frame_one):
    trackers, predicted, energies = frame_one
    a = trackers[0]
    rngs = [copy.deepcopy(trk.rng) for trk in trackers]
    own = [run_annealing(e.landmark_costs, p, trk.std0, trk.body.limits, trk.settings, copy.deepcopy(r),
                         previous=trk.history[-1], root_point=trk.shaped.rest_joints[0], groups=trk.groups)
           for trk, e, p, r in zip(trackers, energies, predicted, rngs, strict=True)]
    together = anneal_people(PeopleEnergy(energies), np.stack(predicted), a.std0, a.body.limits, a.settings,
                             [copy.deepcopy(r) for r in rngs], np.stack([t.history[-1] for t in trackers]),
                             [t.shaped.rest_joints[0] for t in trackers], a.groups)
    for (chi_own, trace_own), (chi, trace) in zip(own, together, strict=True):
        np.testing.assert_array_equal(chi, chi_own)
        assert trace == trace_own


def test_skeleton_costs_equal_the_median_of_each_pairs_distances():
    rng = np.random.default_rng(3)
    T, S, L = 3, 4, 9
    xy, u = rng.normal(0, 50, (S, L, 2)), rng.normal(0, 50, (T, L, 2))
    valid, front = rng.random((S, L)) > 0.3, rng.random((T, L)) > 0.2
    valid[0, 3:] = False                                         # a skeleton with < 3 usable points
    got = skeleton_costs(xy, valid, u, front)
    for i in range(T):
        for j in range(S):
            ok = valid[j] & front[i]
            want = np.median(np.linalg.norm(xy[j][ok] - u[i, ok], axis=1)) if ok.sum() >= 3 else 1e9
            assert got[i, j] == want


@pytest.mark.parametrize("use_confidence", [False, True])
@pytest.mark.parametrize("gate", [5.0, 30.0])
def test_the_people_kernel_gives_each_persons_energy_bit_for_bit(body64, false_positive_scene, gate,
                                                                  use_confidence):
    """Three people: all candidates (several per view), one candidate per view, and views with
    none; particles behind a camera; weak landmarks pulled by coherence for two of them."""
    from mocap.energy.markers import HAVE_NUMBA, MarkerEnergy, MarkerLikelihood, MarkerObservation

    if not HAVE_NUMBA:
        pytest.skip("numba is not installed")
    seq, lms, obs, rig = false_positive_scene
    rng = np.random.default_rng(5)
    one = MarkerObservation(obs.xy[:, :, :1], obs.valid[:, :, :1], obs.confidence[:, :, :1])
    valid = obs.valid & (rng.random(obs.valid.shape) > 0.3)
    valid[:, 2] = False                                                  # a view with no candidate
    sparse = MarkerObservation(obs.xy, valid, rng.random(obs.valid.shape))
    s = MarkerLikelihood(gate_px=gate, use_confidence=use_confidence)
    energies, chis = [], []
    for n, o in enumerate((obs, one, sparse)):
        shaped = body64.shaped(rng.normal(0, 1, body64.num_shape))
        pred = lms.positions(shaped, seq.gt.chi[1][None])[0].astype(np.float64)
        weak = rng.random(len(lms)) < 0.4 if n < 2 else None
        energies.append(MarkerEnergy(lms, shaped, rig, o, s, predicted=pred, weak=weak))
        chi = seq.gt.chi[1] + rng.normal(0, 0.05, (60, body64.num_dofs))
        chi[:4, 3:6] += [0.0, -6.0, 0.0]                        # behind a camera / far off
        chis.append(chi)
    batch = PeopleEnergy(energies)
    assert batch.fused and batch.coherent.tolist() == [True, True, False]
    got = batch.landmark_costs(np.stack(chis))
    for n, e in enumerate(energies):
        want = e.landmark_costs(chis[n])
        assert np.ptp(want) > 0
        np.testing.assert_array_equal(got[n], want)


def test_the_batched_propagation_gives_each_persons_own_draws():
    from mocap.trackers.markers.batch import _propagate
    from mocap.trackers.markers.propagation import propagate_truncated

    rng = np.random.default_rng(11)
    T, P, D = 3, 50, 14
    limits = np.stack([np.r_[np.full(6, -np.inf), rng.uniform(-2, -0.1, D - 6)],
                       np.r_[np.full(6, np.inf), rng.uniform(0.1, 2, D - 6)]], axis=1)
    x = rng.uniform(limits[:, 0].clip(-1), limits[:, 1].clip(None, 1), (T, P, D))
    std = rng.uniform(0.01, 0.3, (T, D))
    std[1, :6] = 0.0                                                   # a person whose root stays
    roots = rng.normal(0, 1, (T, 3))
    seeds = [np.random.default_rng(100 + n) for n in range(T)]
    got = _propagate(x, std, limits, [copy.deepcopy(g) for g in seeds], roots)
    for n in range(T):
        np.testing.assert_array_equal(got[n], propagate_truncated(x[n], std[n], limits, seeds[n], roots[n]))


def test_a_distortion_free_rig_is_undistorted_all_rows_at_once_as_view_by_view():
    from mocap.cameras import Camera, Rig, undistort_points
    from mocap.energy.markers import _through_pinhole

    rng = np.random.default_rng(2)
    cams = []
    for c in range(3):
        K = np.array([[rng.uniform(400, 900), rng.uniform(-2, 2), rng.uniform(200, 400)],
                      [0.0, rng.uniform(400, 900), rng.uniform(150, 300)], [0.0, 0.0, 1.0]])
        cams.append(Camera(f"c{c}", K, None, np.eye(3), np.array([0.0, 0.0, 3.0 + c]), 640, 480))
    rig = Rig(tuple(cams))
    view = rng.integers(0, 3, 200)
    xy = rng.uniform(-50, 700, (200, 2))
    got = _through_pinhole(rig, view, xy)
    for c in range(3):
        np.testing.assert_array_equal(got[view == c], undistort_points(rig[c], xy[view == c]))


def test_the_particles_innermost_kinematics_equal_the_compiled_landmarks(body64):
    """landmarks_by_particle (L, 3, P) holds landmark_points' (P, L, 3) numbers, bit for bit
    (root rotations large, tiny and zero: both branches of the twist exponential)."""
    pytest.importorskip("numba")
    from mocap.body.catalogue import make_landmark_set
    from mocap.energy.marker_kernel import landmark_points
    from mocap.trackers.markers.people_kernel import landmarks_by_particle

    lms = make_landmark_set(body64, "default")
    shaped = body64.shaped(np.random.default_rng(0).normal(0, 1, body64.num_shape))
    m = lms.model
    args = (np.asarray(m.parents, np.int64), np.asarray(m.dof_joint, np.int64),
            np.ascontiguousarray(shaped.axes, np.float64),
            np.ascontiguousarray(shaped.rest_joints, np.float64))
    rest = np.ascontiguousarray(lms.rest_points(shaped), np.float64)
    joint = np.asarray(lms.joint, np.int64)
    rng = np.random.default_rng(4)
    chi = rng.uniform(body64.limits[:, 0].clip(-2), body64.limits[:, 1].clip(None, 2), (64, body64.num_dofs))
    chi[:8, 3:6] *= 1e-6                                                # |omega| < 1e-4: the series
    chi[8, 3:6] = 0.0
    got = landmarks_by_particle(*args, chi, joint, rest)
    np.testing.assert_array_equal(got.transpose(2, 0, 1), landmark_points(*args, chi, joint, rest))
