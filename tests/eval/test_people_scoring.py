"""Ground truth of several people (issue 26): tracks are assigned to people by the Hungarian
method on mean joint error, so known offsets give known per-person errors, a permuted person
order scores the same, and identity switches / track jumps are counted frame by frame."""

from __future__ import annotations

import numpy as np
import pytest

from mocap.data.sequence import GroundTruth
from mocap.eval.people import score_people

NAMES = ("pelvis", "neck", "head_top", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow",
         "r_wrist", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")
# a standing stick figure (m), x to the person's left, z up
FIGURE = np.array([[0, 0, 1.0], [0, 0, 1.5], [0, 0, 1.75], [0.2, 0, 1.45], [0.45, 0, 1.45], [0.7, 0, 1.45],
                   [-0.2, 0, 1.45], [-0.45, 0, 1.45], [-0.7, 0, 1.45], [0.1, 0, 0.95], [0.1, 0, 0.5],
                   [0.1, 0, 0.08], [-0.1, 0, 0.95], [-0.1, 0, 0.5], [-0.1, 0, 0.08]])
F = 12


def people(P: int = 3) -> np.ndarray:
    """(F, P, J, 3): P figures 1.5 m apart, walking 2 cm per frame along y."""
    t = np.arange(F)[:, None, None, None]
    start = np.arange(P)[None, :, None, None] * np.array([1.5, 0.0, 0.0])
    return FIGURE[None, None] + start + t * np.array([0.0, 0.02, 0.0])


def truth(joints: np.ndarray, names=None, valid=None) -> GroundTruth:
    return GroundTruth(alpha=None, chi=None, joints=joints, markers=None, dof_names=(), joint_names=NAMES,
                       marker_names=(), joint_valid=valid,
                       person_names=tuple(names or (f"p{i}" for i in range(joints.shape[1]))))


def track(points: np.ndarray) -> dict:
    """(F, J, 3) -> named points."""
    return {n: points[:, j] for j, n in enumerate(NAMES)}


def score(tracks, gt, **kw):
    return score_people([track(t) for t in tracks], gt, {n: n for n in NAMES}, **kw)


def test_each_track_gets_its_person_with_the_known_error():
    J = people(3)
    tracks = [J[:, 2] + [0.0, 0.0, 0.030], J[:, 0] + [0.010, 0.0, 0.0]]       # 30 mm and 10 mm off
    got = score(tracks, truth(J, ["ann", "bob", "cid"]))
    assert got["people"]["cid"]["track"] == 0 and got["people"]["ann"]["track"] == 1
    assert got["people"]["cid"]["mpjpe_mm"] == pytest.approx(30.0)
    assert got["people"]["ann"]["mpjpe_mm"] == pytest.approx(10.0)
    assert got["people"]["ann"]["pcp"] == 1.0 and got["people"]["ann"]["coverage"] == 1.0
    bob = got["people"]["bob"]
    assert bob["track"] is None and bob["coverage"] == 0.0 and "mpjpe_mm" not in bob
    assert got["people_tracked"] == 2 and got["people_in_ground_truth"] == 3
    assert got["mpjpe_mm"] == pytest.approx(20.0) and got["identity_switches"] == 0
    assert got["tracks"]["0"]["person"] == "cid" and got["tracks"]["1"]["track_jumps"] == 0


def test_a_permuted_person_order_scores_the_same():
    J = people(3)
    rng = np.random.default_rng(0)
    tracks = [J[:, p] + rng.normal(0, 0.02, J[:, p].shape) for p in (1, 2, 0)]
    names = ["ann", "bob", "cid"]
    base = score(tracks, truth(J, names))
    for order in ([2, 0, 1], [1, 0, 2]):
        got = score(tracks, truth(J[:, order], [names[i] for i in order]))
        assert got["people"] == {n: base["people"][n] for n in got["people"]}
        assert got["mpjpe_mm"] == base["mpjpe_mm"] and got["pcp"] == base["pcp"]
    # permuting the tracks moves the track indices only
    got = score(tracks[::-1], truth(J, names))
    for n in names:
        assert got["people"][n]["mpjpe_mm"] == base["people"][n]["mpjpe_mm"]
        assert got["people"][n]["track"] == 2 - base["people"][n]["track"]


def test_two_tracks_swapping_people_are_identity_switches():
    J = people(2)
    a, b = J[:, 0].copy(), J[:, 1].copy()
    a[6:], b[6:] = J[6:, 1], J[6:, 0]              # the tracks swap people at frame 6
    got = score([a, b], truth(J, ["ann", "bob"]))
    assert got["people"]["ann"]["identity_switches"] == 1 and got["people"]["bob"]["identity_switches"] == 1
    assert got["identity_switches"] == 2
    assert got["tracks"]["0"]["track_jumps"] == 1 and got["tracks"]["1"]["track_jumps"] == 1
    # half the frames on the wrong person (1.5 m away): PCP 0.5 for each
    assert got["people"]["ann"]["pcp"] == pytest.approx(0.5)


def test_a_single_track_moving_to_a_bystander_jumps_once():
    J = people(2)
    t = J[:, 0].copy()
    t[8:] = J[8:, 1]
    got = score([t], truth(J, ["subject", "bystander"]))
    assert got["people"]["subject"]["track"] == 0 and got["tracks"]["0"]["track_jumps"] == 1
    assert got["people"]["subject"]["pcp"] == pytest.approx(8 / 12)
    assert got["identity_switches"] == 0            # no person changed its track (CLEAR-MOT)


def test_absent_frames_and_the_gate():
    J = people(2)
    valid = np.ones(J.shape[:3], bool)
    valid[:4, 1] = False                            # bob enters at frame 4
    t0 = J[:, 0] + [0.0, 0.0, 0.02]
    t1 = J[:, 1].copy()
    t1[:6] = np.nan                                 # bob's track starts at frame 6
    far = J[:, 0] + [0.0, 3.0, 0.0]                 # follows nobody (3 m off)
    got = score([t0, far, t1], truth(J, ["ann", "bob"], valid))
    bob = got["people"]["bob"]
    assert bob["track"] == 2 and bob["frames"] == 8 and bob["tracked_frames"] == 6
    assert bob["coverage"] == pytest.approx(0.75) and bob["mpjpe_mm"] == pytest.approx(0.0, abs=1e-9)
    assert bob["pcp_all_frames"] == pytest.approx(0.75)
    assert got["tracks"]["1"]["person"] is None and got["people"]["ann"]["track"] == 0
    # a tighter gate than the error leaves the person untracked
    assert score([t0], truth(J, ["ann", "bob"]), gate_mm=10.0)["people"]["ann"]["track"] is None


def test_ground_truth_person_view():
    J = people(2)
    gt = truth(J, ["ann", "bob"])
    assert gt.num_people == 2 and gt.num_frames == F
    np.testing.assert_array_equal(gt.person(1).joints, J[:, 1])
    assert gt.person(1).person_names == () and gt.person(1).num_people == 1
