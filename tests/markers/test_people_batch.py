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
