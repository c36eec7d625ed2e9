"""The same seed gives the same track on one and on two threads (issue 28): each tracker family
(local, APF, hybrid, marker) tracks a 3-frame synthetic clip with a numeric thread budget of 1,
then 2, then 1 again (BLAS / OpenMP, numba and OpenCV: mocap.threads.thread_budget) and every
pose and every frame's diagnostic values (energy terms, misalignment errors, iterations; not
the timings) agree to 1e-12 (relative for the diagnostics). Before the
distance transforms left Intel IPP out (mocap/render/distance.py), the silhouette energies of
one-thread runs differed from those of two-thread runs and from each other by ~1e-10.
benchmarks/bench_threads.py prints the same comparison for longer clips and larger rigs."""

from __future__ import annotations

import numpy as np
import pytest

import mocap
from mocap.threads import thread_budget

FRAMES = 3
#: family -> (tracker, settings, sequence kind, init)
FAMILIES = {
    "local": ("local", {}, "silhouettes", "gt_noise"),
    "local_sift": ("local", {}, "images", "gt_noise"),        # + SIFT matches (OpenCV's threads)
    "apf": ("apf_25x10", {}, "silhouettes", "gt_noise"),
    "hybrid": ("hybrid", {"apf": {"layers": 3}}, "silhouettes", "gt_noise"),
    "marker": ("marker_apf", {"particles": 20, "layers": 3}, "markers", "tracker"),
}


@pytest.fixture(scope="module")
def sequences(body) -> dict:
    common = {"cameras": "ring4_small", "motion": "walk", "frames": FRAMES, "seed": 0}
    return {"silhouettes": mocap.synthetic_sequence(body, **common),
            "images": mocap.synthetic_sequence(body, images=True, **common),
            "markers": mocap.synthetic_sequence(body, masks=False, detections={
                "enabled": True, "labelled": True, "occlusion": False}, **common)}


def run(body, sequences, family: str, threads: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Poses (F, D) and every frame's diagnostic scalars but the timings (name -> (F,))."""
    tracker, settings, kind, init = FAMILIES[family]
    with thread_budget(threads):
        result = mocap.track(sequences[kind], tracker, body=body, seed=0, init=init, **settings)
    scalars = [e.diagnostics.scalars() for e in result.estimates]
    names = sorted({k for s in scalars for k in s if not k.startswith("timing/")})
    return (np.stack([e.chi for e in result.estimates]),
            {k: np.array([s.get(k, np.nan) for s in scalars]) for k in names})


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_one_and_two_threads_give_the_same_track(body, sequences, family):
    chi, values = run(body, sequences, family, 1)
    assert not np.array_equal(chi[1], chi[0]) and not np.array_equal(chi[2], chi[1])    # it tracked
    expected = {"local": "misalignment/limb_errors/r_knee", "local_sift": "misalignment/limb_errors/r_knee",
                "apf": "energy/silhouette",
                "hybrid": "energy/silhouette", "marker": "energy/markers"}[family]
    assert np.isfinite(values[expected][1:]).any(), sorted(values)
    for threads in (2, 1):
        other, other_values = run(body, sequences, family, threads)
        np.testing.assert_allclose(other, chi, rtol=0, atol=1e-12, err_msg=f"{threads} threads")
        assert other_values.keys() == values.keys()
        for name, v in values.items():
            np.testing.assert_allclose(other_values[name], v, rtol=1e-12, atol=0,
                                       err_msg=f"{name}, {threads} threads")
