"""Scores of several people (mocap/eval/people_metrics.py) against known answers."""

import numpy as np
import pytest

from mocap.eval.people_metrics import births_deaths, pcp_limbs, people_scores

# two joints 0.4 m apart (one limb), three people far apart, 6 frames
LIMB = [(0, 1)]


def people(T=6, P=3):
    base = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.4]])
    return np.stack([[base + [2.0 * p, 0.0, 0.0] for p in range(P)] for _ in range(T)])   # (T, P, 2, 3)


def test_exact_estimates_score_zero_in_any_track_order():
    gt = people()
    est = gt[:, [2, 0, 1]]
    s = people_scores(est, gt, LIMB)
    assert s["assignment"] == [1, 2, 0] and s["switches"] == 0
    assert all(p["mpjpe_mm"] == 0 and p["pcp"] == 1.0 and p["tracked_frames"] == 6 for p in s["people"])


def test_a_permuted_ground_truth_scores_the_same_per_person():
    gt = people()
    est = gt + np.random.default_rng(0).normal(0, 0.02, gt.shape)
    a, b = people_scores(est, gt, LIMB), people_scores(est, gt[:, [1, 2, 0]], LIMB)
    for i, j in enumerate([1, 2, 0]):
        assert b["people"][i]["mpjpe_mm"] == pytest.approx(a["people"][j]["mpjpe_mm"])
        assert b["assignment"][i] == a["assignment"][j]


def test_tracks_swapping_half_way_count_one_switch_per_person():
    gt = people()
    est = gt.copy()
    est[3:, [0, 1]] = gt[3:, [1, 0]]          # tracks 0 and 1 swap people at frame 3
    s = people_scores(est, gt, LIMB)
    assert [p["switches"] for p in s["people"]] == [1, 1, 0] and s["switches"] == 2


def test_pcp_error_of_half_the_limb_length_is_the_threshold():
    gt = people(T=2, P=1)
    est = gt.copy()
    est[0] += [0.19, 0, 0]                     # mean endpoint error 0.19 <= 0.2: correct
    est[1] += [0.21, 0, 0]                     # 0.21 > 0.2: wrong
    s = people_scores(est, gt, LIMB)
    assert s["people"][0]["pcp"] == 0.5
    assert s["people"][0]["mpjpe_mm"] == pytest.approx(200.0)


def test_late_entrant_latency_and_absent_frames():
    gt = people()
    gt[:2, 2] = np.nan                         # person 2 appears at frame 2
    est = gt.copy()
    est[:4, 2] = np.nan                        # tracked from frame 4
    s = people_scores(est, gt, LIMB)
    p = s["people"][2]
    assert (p["first_frame"], p["first_tracked_frame"], p["latency_frames"]) == (2, 4, 2)
    assert p["frames"] == 4 and p["tracked_frames"] == 2 and p["mpjpe_mm"] == 0


def test_a_person_never_tracked_has_no_track():
    gt = people(P=2)
    est = gt[:, :1]
    s = people_scores(est, gt, LIMB)
    assert s["assignment"] == [0, -1]
    assert s["people"][1]["latency_frames"] is None and np.isnan(s["people"][1]["mpjpe_mm"])


def test_births_and_deaths_are_first_and_last_live_frames():
    live = np.array([[1, 0], [1, 1], [0, 1], [0, 1]], bool)
    assert births_deaths(live, [7, 9]) == {"births": {"0": [7], "1": [9]}, "deaths": {"1": [7]}}


def test_pcp_limbs_of_mocap_joints_use_the_head_when_there_is_no_head_top():
    names = ["pelvis", "neck", "head", "l_shoulder", "l_elbow"]
    assert pcp_limbs(names) == [(1, 2), (0, 1), (3, 4)]


def test_mismatched_shapes_raise_one_line():
    with pytest.raises(ValueError, match=r"must be \(T, P, J, 3\)"):
        people_scores(np.zeros((3, 1, 2, 3)), np.zeros((4, 1, 2, 3)))
