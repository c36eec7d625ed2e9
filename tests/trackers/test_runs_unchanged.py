"""Runs through the run folder's frame loop (:func:`mocap.run_folder.run_tracking`, what ``mocap
track`` runs) give the tracks saved in ``tests/data/runs_before_contract.npz`` by the code before
the tracker contract (issue 33): a several-people ``marker_people`` run on 20 frames of the
synthetic crowd (a person leaving, two entering), and two single-person runs (``local`` from
ground truth plus noise, ``marker_apf`` self-initialised), with the same people, births and
deaths, and poses within 10x the spread measured across CPUs' numeric paths (:data:`SPREAD`; the
saved runs were made on one machine, and another CPU's OpenBLAS kernels round differently:
docs/cluster.md, "Numbers on another CPU"); on the machine that saved them they are identical.
``tests/trackers/test_tracks_unchanged.py`` checks the Python API's path the same way.

Regenerate (only when a change of behaviour is intended):
``OPENBLAS_NUM_THREADS=1 .venv/bin/python -m tests.trackers.test_runs_unchanged``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

SAVED = Path(__file__).resolve().parents[1] / "data" / "runs_before_contract.npz"
CROWD_FRAMES = 20
FAST_PEOPLE = {"particles": 20, "layers": 3, "init": {"particles": 60, "passes": 2, "layers": 5},
               "people": {"max_missed": 3}}
#: run name -> the largest |chi difference| (rad / m) from the saved runs over the pinned numeric
#: paths of scripts/numeric_spread.py (OpenBLAS Haswell; numba generic + OpenBLAS Prescott),
#: measured 2026-11 on an Intel Xeon; the tolerance is 10x this
SPREAD = {"crowd": 1.9e-6, "local": 3.5e-5, "marker_apf": 3.5e-5}
#: run name -> (tracker, overrides, data kind, init.mode)
RUNS = {
    "crowd": ("marker_people", FAST_PEOPLE, "crowd", "tracker"),
    "local": ("local", {"iterations": 4}, "silhouettes", "gt_noise"),
    "marker_apf": ("marker_apf", {"particles": 20, "layers": 3}, "markers", "tracker"),
}


def _sequence(body, kind):
    import mocap
    from mocap.data.crowd import crowd_sequence

    if kind == "crowd":
        return crowd_sequence(body=body, frames=CROWD_FRAMES, seed=0)
    common = {"cameras": "ring4_small", "motion": "walk", "frames": 3, "seed": 0}
    if kind == "markers":
        return mocap.synthetic_sequence(body, masks=False, detections={
            "enabled": True, "labelled": True, "occlusion": False}, **common)
    return mocap.synthetic_sequence(body, **common)


def run(body, name: str, out: Path) -> dict[str, np.ndarray]:
    """The run ``name`` into ``out``: its poses (F, P, D) (NaN where a person has none), person
    ids, births, deaths and ended_at (as JSON text)."""
    from mocap.export.motion import read_motion_npz
    from mocap.run_folder import run_tracking
    from mocap.trackers.presets import make_tracker

    tracker, overrides, kind, mode = RUNS[name]
    seq = _sequence(body, kind)
    config = {"seed": 0, "frames": None, "threads": 1,
              "init": {"mode": mode, "noise_deg": 3.0, "noise_translation": 0.02, "cache": None},
              "recording": {"enabled": False}, "motion": {"vertices": False}}
    metrics = run_tracking(out, config, make_body=lambda: body, make_sequence=lambda b: seq,
                           make_tracker=lambda **objects: make_tracker(tracker, **objects, **overrides))
    _, arrays = read_motion_npz(out)
    chi = arrays["chi"]
    if chi.ndim == 2:                           # one person: (F, D) -> (F, 1, D)
        chi = chi[:, None]
    events = {k: metrics[k] for k in ("people", "births", "deaths", "ended_at") if k in metrics}
    return {"chi": np.asarray(chi, np.float64),
            "person_ids": np.asarray(arrays.get("person_ids", [0]), np.int64),
            "events": np.array(json.dumps(events, sort_keys=True))}


@pytest.mark.slow
@pytest.mark.golden
@pytest.mark.parametrize("name", sorted(RUNS))
def test_runs_equal_those_before_the_tracker_contract(name, body, tmp_path):
    if not SAVED.is_file():
        pytest.skip(f"{SAVED} is missing")
    saved = np.load(SAVED)
    after = run(body, name, tmp_path)
    before_chi = saved[f"{name}.chi"]
    assert after["chi"].shape == before_chi.shape
    assert not np.array_equal(after["chi"][1], after["chi"][0], equal_nan=True)       # it tracked
    np.testing.assert_allclose(after["chi"], before_chi, rtol=0, atol=10 * SPREAD[name])   # NaN where NaN
    np.testing.assert_array_equal(after["person_ids"], saved[f"{name}.person_ids"])
    assert json.loads(str(after["events"])) == json.loads(str(saved[f"{name}.events"]))


if __name__ == "__main__":
    import tempfile

    from mocap.body import load_body_model
    from mocap.threads import thread_budget
    from tests.conftest import body_config

    b = load_body_model(body_config("paper22")["dofs"], name="paper22")
    out = {}
    with thread_budget(1):
        for n in RUNS:
            with tempfile.TemporaryDirectory() as d:
                for key, value in run(b, n, Path(d) / "run").items():
                    out[f"{n}.{key}"] = value
    np.savez_compressed(SAVED, **out)
    print(f"wrote {SAVED}")
