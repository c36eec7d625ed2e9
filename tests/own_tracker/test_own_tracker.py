"""A tracker of one's own, defined only here and in ``conf/tracker/drift.yaml`` beside this file,
runs end to end as the shipped ones do: ``mocap track`` (recording, motion.npz, metrics),
``mocap export``, ``mocap ablate`` and :func:`mocap.track`, for one person and for several. It
is joined to the commands by Hydra's own flag adding a config folder to the search path
(``mocap track --config-dir tests/own_tracker/conf tracker=drift``), nothing registered in the
package: the contract (:mod:`mocap.trackers.contract`) is all a tracker implements.

The drift tracker moves each person's pose by ``step_m`` along the first root DOF per frame,
so every frame's answer is known: frame f = the start + f * step_m. With ``people: 2`` it
starts two people itself (the mean shape, 0.8 m apart) and person 1 leaves after frame 2.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocap.trackers.base import Estimate, Frame
from mocap.trackers.contract import Needs, OnePerson, SearchBudget, Uncached, initial_estimate_of
from mocap.trackers.diagnostics import StepDiagnostics
from tests.cli.in_process import mocap as in_process

REPO = Path(__file__).resolve().parents[2]
CONF = Path(__file__).resolve().parent / "conf"
LEAVES_AFTER = 2        # the frame person 1 of the two-people drift is last answered for


def _moved(est: Estimate, step_m: float) -> Estimate:
    chi = np.array(est.chi, np.float64)
    chi[0] += step_m
    return Estimate(chi=chi, alpha=est.alpha, diagnostics=StepDiagnostics(timings={"drift": 0.0}))


class Drift(OnePerson):
    """One person: the run's start, moved by ``step_m`` per frame."""

    def __init__(self, step_m: float, name: str = "drift"):
        self.step_m, self.name = step_m, name

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        self.last = initial_estimate_of(chi, alpha)

    def step(self, frame: Frame) -> Estimate:
        self.last = _moved(self.last, self.step_m)
        return self.last


class DriftStart(Uncached):
    """The two-people drift's start: person 0 and 1 at rest, 0.8 m apart (never cached)."""

    def __init__(self, body):
        self.body = body

    def __call__(self, frame: Frame):
        chi = np.zeros(self.body.num_dofs)
        alpha = np.zeros(self.body.num_shape)
        other = chi.copy()
        other[0] += 0.8
        return {0: initial_estimate_of(chi, alpha), 1: initial_estimate_of(other, alpha)}, {"seconds": 0.0}


class DriftPeople:
    """Two people it starts itself (:class:`DriftStart`), each moved by ``step_m`` per frame;
    person 1 is no longer answered for after frame ``LEAVES_AFTER``."""

    several_people = True
    revises_tracks = False
    needs = Needs()
    budget = SearchBudget()
    start_up_flags = ()

    def __init__(self, body, step_m: float, name: str = "drift"):
        self.body, self.step_m, self.name = body, step_m, name

    def check_sequence(self, seq) -> None:
        pass

    def initializer(self, cache=None):
        return DriftStart(self.body)

    def begin(self, frame, initial):
        self.last = dict(initial)
        return initial

    def track(self, frame):
        self.last = {pid: _moved(est, self.step_m) for pid, est in self.last.items()
                     if pid == 0 or frame.index <= LEAVES_AFTER}
        return self.last

    def final_tracks(self, tracks):
        return tracks


def make_drift_tracker(*, body, rig, rng, keep_particles: bool = False, name: str = "drift",
                       people: int = 1, step_m: float = 0.01):
    """The tracker of ``conf/tracker/drift.yaml`` (what a run hands every tracker factory:
    body, rig, rng, keep_particles)."""
    if people not in (1, 2):
        raise ValueError(f"setting people = {people!r} is out of range (allowed: 1 or 2)")
    return Drift(step_m, name) if people == 1 else DriftPeople(body, step_m, name)


# -- the commands ------------------------------------------------------------------------------

def mocap(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocap_cli", *args], capture_output=True, text=True,
                          cwd=REPO, timeout=600)


def track(out: Path, *overrides: str) -> subprocess.CompletedProcess:
    """``mocap track --config-dir ...`` in this process (:mod:`tests.cli.in_process`: the same
    argv through the entry point's function); export and ablate below run as processes."""
    return in_process("track", "--config-dir", str(CONF), "tracker=drift", "data=walk_small", "frames=5",
                      f"hydra.run.dir={out}", "recording.level=summary", *overrides)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """A folder of two runs of the drift tracker: ``one`` (one person, from ground truth plus
    noise) and ``two`` (two people, started by the tracker)."""
    sweep = tmp_path_factory.mktemp("drift_runs")
    for run, overrides in (("one", ()), ("two", ("tracker.people=2", "init.mode=tracker"))):
        r = track(sweep / run, *overrides)
        assert r.returncode == 0, r.stderr[-3000:]
    return sweep


@pytest.mark.slow
def test_one_person_runs_through_mocap_track(runs):
    from mocap.export.motion import load_motion

    d = runs / "one"
    m = json.loads((d / "metrics.json").read_text())
    assert m["tracker"] == "drift" and m["particles"] == 0 and np.isfinite(m["mpjpe_mm"])
    motion = load_motion(d)
    assert motion.num_frames == 5
    steps = motion.chi[1:] - motion.chi[:-1]
    np.testing.assert_allclose(steps[:, 0], 0.01, atol=1e-12)
    np.testing.assert_array_equal(steps[:, 1:], 0.0)
    assert (d / "recording.rrd").is_file() and (d / "manifest.json").is_file()


@pytest.mark.slow
def test_several_people_run_through_mocap_track(runs):
    from mocap.export.people_motion import load_people_motion

    d = runs / "two"
    m = json.loads((d / "metrics.json").read_text())
    assert m["tracker"] == "drift" and m["people"] == [0, 1]
    assert m["people_per_frame"] == [2, 2, 2, 1, 1]
    assert m["ended_at"] == {str(LEAVES_AFTER + 1): [1]}
    a = load_people_motion(d)
    assert a["live"][:, 1].tolist() == [True, True, True, False, False] and a["live"][:, 0].all()
    np.testing.assert_allclose(a["chi"][:, 0, 0], 0.01 * np.arange(5), atol=1e-12)
    np.testing.assert_allclose(a["chi"][:3, 1, 0], 0.8 + 0.01 * np.arange(3), atol=1e-12)
    assert (d / "recording.rrd").is_file() and (d / "manifest.json").is_file()


@pytest.mark.slow
def test_both_runs_export_and_ablate(runs, tmp_path):
    from mocap.clips.bvh import read_bvh

    r = mocap("export", str(runs / "one"), "--format", "bvh", "--out", str(tmp_path / "one.bvh"))
    assert r.returncode == 0, r.stderr[-2000:]
    r = mocap("export", str(runs / "two"), "--format", "bvh", "--person", "1",
              "--out", str(tmp_path / "two.bvh"))
    assert r.returncode == 0, r.stderr[-2000:]
    assert read_bvh(tmp_path / "one.bvh").num_frames == 5
    assert read_bvh(tmp_path / "two.bvh").num_frames == LEAVES_AFTER + 1     # the frames person 1 was in
    r = mocap("ablate", str(runs), "--out", str(tmp_path / "ablation"))
    assert r.returncode == 0, r.stderr[-2000:]
    md = (tmp_path / "ablation" / "ablation.md").read_text()
    assert "drift" in md


@pytest.mark.parametrize("people", [1, 2])
def test_the_python_api_runs_it(people, body):
    import mocap

    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=4, seed=0)
    result = mocap.track(seq, make_drift_tracker, body=body, seed=0, people=people, step_m=0.02)
    assert result.several_people == (people == 2)
    assert sorted(result.tracks) == list(range(people))
    chi0 = np.stack([result.tracks[0][f].chi for f in range(4)])
    np.testing.assert_allclose(np.diff(chi0[:, 0]), 0.02, atol=1e-12)
    if people == 1:                 # started at the ground truth plus noise, as mocap track does
        assert np.abs(result.estimates[0].chi - seq.gt.chi[0]).max() < 0.2
    else:
        assert sorted(result.tracks[1]) == list(range(LEAVES_AFTER + 1))
