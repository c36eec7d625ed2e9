"""Gauss-Newton refinement of the marker tracker's estimate (mocap/trackers/markers/refine.py)."""

import numpy as np
import pytest

from mocap.body.catalogue import make_landmark_set
from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.energy.markers import MarkerEnergy, MarkerLikelihood, arrange_detections
from mocap.trackers.markers.refine import Refinement, refine_pose
from mocap.trackers.markers.startup import pinhole_rig


def test_refinement_recovers_a_perturbed_pose_from_exact_detections(body64):
    rig = pinhole_rig(rig_from_config("humaneva"))
    det = {"enabled": True, "detection_rate": 1.0, "false_positive_rate": 0.3, "noise_px": 0.0,
           "occlusion": False}
    seq = make_synthetic(body64, rig, motion="walk", frames=1, fps=25, seed=2, masks=False, detections=det)
    lms = make_landmark_set(body64, "auto", seq.detections.labels)
    obs = arrange_detections(seq.detections.select(0), lms.names, rig)
    shaped = body64.shaped(seq.gt.alpha)
    energy = MarkerEnergy(lms, shaped, rig, obs, MarkerLikelihood(gate_px=40.0))
    truth = seq.gt.chi[0]
    rng = np.random.default_rng(0)
    start = np.clip(truth + rng.normal(0, 0.03, truth.shape), body64.limits[:, 0], body64.limits[:, 1])
    err = lambda chi: 1e3 * np.linalg.norm(energy.points(chi[None])[0] - seq.gt.markers[0], axis=1).mean()  # noqa: E731
    chi, info = refine_pose(energy.points, start, obs, rig, body64.limits,
                            Refinement(iterations=5, prior_std=10.0), 40.0)
    assert err(start) > 15.0
    assert err(chi) < 0.1 * err(start) and err(chi) < 2.0                # exact data: back to the truth
    assert info["residual_px_after"] < 0.2 < info["residual_px_before"]
    same, info0 = refine_pose(energy.points, start, obs, rig, body64.limits, Refinement(iterations=0), 40.0)
    np.testing.assert_array_equal(same, start)
    assert info0["iterations"] == 0


def test_compiled_association_equals_numpy_bit_for_bit():
    """Nearest valid candidate within the gate: the same pixels, confidences and flags from
    the compiled loop as from numpy's argmin, with empty cells, ties, NaN projections."""
    from mocap.energy.markers import HAVE_NUMBA, MarkerObservation, associate

    if not HAVE_NUMBA:
        pytest.skip("numba is not installed")
    rng = np.random.default_rng(11)
    matched = 0
    for trial in range(30):
        L, C, K = rng.integers(1, 25), rng.integers(1, 6), rng.integers(1, 5)
        xy = rng.uniform(0, 100, (L, C, K, 2)).round(0 if trial % 3 == 0 else 6)    # rounding: ties
        valid = rng.random((L, C, K)) < 0.7
        conf = rng.random((L, C, K))
        obs = MarkerObservation(np.where(valid[..., None], xy, 0.0), valid, np.where(valid, conf, 0.0))
        u = rng.uniform(0, 100, (L, C, 2)).round(0 if trial % 3 == 0 else 6)
        u[rng.random((L, C)) < 0.1] = np.nan
        front = rng.random((L, C)) < 0.9
        got = associate(u, front, obs, 20.0, compiled=True)
        want = associate(u, front, obs, 20.0, compiled=False)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)
        matched += int(got[2].sum())
    assert matched > 100


def test_an_outlier_view_is_down_weighted_and_the_others_are_not():
    from mocap.trackers.markers.refine import view_weights

    rng = np.random.default_rng(0)
    view = np.repeat(np.arange(5), 10)
    norm = np.abs(rng.normal(0, 2.0, 50))
    norm[view == 3] += 40.0                                     # a view with the wrong person / swapped
    w = view_weights(norm, view, 5, factor=3.0, floor_px=4.0)
    assert np.all(w[view != 3] == 1.0)
    assert np.all(w[view == 3] < 0.1)
    assert np.all(view_weights(np.abs(rng.normal(0, 2.0, 50)), view, 5, 3.0, 4.0) == 1.0)


@pytest.mark.parametrize("outlier_views", [0.0, 3.0])
def test_refining_people_together_gives_each_persons_own_refinement(body64, outlier_views):
    """Three people (own shapes, starts and detections; the third has too few detections and
    stops at once): refine_people equals refine_pose person by person, bit for bit."""
    from mocap.energy.markers import MarkerObservation
    from mocap.trackers.markers.refine import refine_people

    rig = pinhole_rig(rig_from_config("humaneva"))
    det = {"enabled": True, "detection_rate": 0.9, "false_positive_rate": 0.3, "noise_px": 1.0,
           "occlusion": False}
    seq = make_synthetic(body64, rig, motion="walk", frames=3, fps=25, seed=4, masks=False, detections=det)
    lms = make_landmark_set(body64, "auto", seq.detections.labels)
    rng = np.random.default_rng(1)
    points, obs, starts = [], [], []
    for n in range(3):
        o = arrange_detections(seq.detections.select(n), lms.names, rig)
        if n == 2:                                                       # two detections left
            keep = np.zeros_like(o.valid)
            keep[0, 0, 0] = keep[1, 1, 0] = True
            o = MarkerObservation(o.xy, o.valid & keep, o.confidence)
        shaped = body64.shaped(seq.gt.alpha + rng.normal(0, 0.3, seq.gt.alpha.shape))
        points.append(MarkerEnergy(lms, shaped, rig, o, MarkerLikelihood(gate_px=40.0)).points)
        obs.append(o)
        starts.append(np.clip(seq.gt.chi[n] + rng.normal(0, 0.03, body64.num_dofs),
                              body64.limits[:, 0], body64.limits[:, 1]))
    s = Refinement(iterations=4, outlier_views=outlier_views)
    together = refine_people(points, np.stack(starts), obs, rig, body64.limits, s, 40.0)
    for n in range(3):
        chi, info = refine_pose(points[n], starts[n], obs[n], rig, body64.limits, s, 40.0)
        np.testing.assert_array_equal(together[n][0], chi)
        np.testing.assert_equal(together[n][1], info)                   # NaN where NaN
    assert [t[1]["iterations"] for t in together] == [4, 4, 0]
