"""The compiled marker likelihood (mocap/energy/marker_kernel.py) against its numpy
references: forward kinematics (LandmarkSet.positions) and view_costs."""

import numpy as np
import pytest

from mocap.energy import fallback
from mocap.energy.markers import MarkerEnergy, MarkerLikelihood


def test_compiled_landmarks_match_forward_kinematics(body64, false_positive_scene):
    seq, lms, obs, rig = false_positive_scene
    shaped = body64.shaped(seq.gt.alpha)
    chi = seq.gt.chi[1] + np.random.default_rng(0).normal(0, 0.3, (50, body64.num_dofs))
    e = MarkerEnergy(lms, shaped, rig, obs, MarkerLikelihood(gate_px=30.0))
    np.testing.assert_allclose(e.points(chi), lms.positions(shaped, chi), atol=1e-9)


@pytest.mark.parametrize("use_confidence", [False, True])
@pytest.mark.parametrize("gate", [5.0, 30.0])
def test_compiled_costs_match_the_numpy_likelihood(body64, false_positive_scene, gate, use_confidence):
    seq, lms, obs, rig = false_positive_scene
    shaped = body64.shaped(seq.gt.alpha)
    rng = np.random.default_rng(1)
    chi = seq.gt.chi[1] + rng.normal(0, 0.05, (80, body64.num_dofs))
    chi[:5, 3:6] += [0.0, -6.0, 0.0]                # some particles behind a camera / far off
    s = MarkerLikelihood(gate_px=gate, use_confidence=use_confidence)
    pred = lms.positions(shaped, seq.gt.chi[1][None])[0]
    weak = np.arange(len(lms)) % 3 == 0
    fast = MarkerEnergy(lms, shaped, rig, obs, s, predicted=pred, weak=weak)
    ref = MarkerEnergy(lms, shaped, rig, obs, s, predicted=pred, weak=weak, compiled=False)
    a, b = fast.landmark_costs(chi), ref.landmark_costs(chi)
    assert np.ptp(b) > 0 and (use_confidence or (b < gate**2 / (len(lms) * len(rig))).any())
    np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-9)


def test_without_numba_the_likelihood_falls_back_to_numpy_and_says_so_once(body64, false_positive_scene,
                                                                           monkeypatch):
    import warnings

    from mocap.energy import markers

    seq, lms, obs, rig = false_positive_scene
    shaped = body64.shaped(seq.gt.alpha)
    chi = seq.gt.chi[1] + np.random.default_rng(2).normal(0, 0.05, (20, body64.num_dofs))
    s = MarkerLikelihood(gate_px=30.0)
    compiled = MarkerEnergy(lms, shaped, rig, obs, s)
    monkeypatch.setattr(markers, "HAVE_NUMBA", False)
    monkeypatch.setattr(fallback, "WARNED", set())
    with pytest.warns(RuntimeWarning, match="numba is not installed"):
        first = MarkerEnergy(lms, shaped, rig, obs, s)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        second = MarkerEnergy(lms, shaped, rig, obs, s)
    assert compiled.compiled and not first.compiled and not second.compiled
    np.testing.assert_allclose(first(chi), compiled(chi), rtol=1e-7, atol=1e-9)
