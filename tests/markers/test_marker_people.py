"""Several people with the marker tracker (mocap/trackers/markers/people.py)."""

import numpy as np
import pytest

from mocap.body.skeletons import LAYOUTS
from mocap.cameras import rig_from_config
from mocap.data.crowd import crossing_scene, crowd_detections
from mocap.data.sequence import Sequence
from mocap.trackers.markers.people import PeopleTracker
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]
FRAMES = 24


def factory(body, rig, seed=0):
    rngs = iter(np.random.default_rng(seed).spawn(10))
    return lambda: make_tracker("marker_apf", body=body, rig=rig, rng=next(rngs))


@pytest.fixture(scope="module")
def crossing(body):
    rig = rig_from_config("humaneva")
    chis, alphas = crossing_scene(body, FRAMES, people=2, gap=0.25)
    det, truth = crowd_detections(body, rig, chis, alphas, LABELS, noise_px=1.0, seed=0)
    return Sequence(name="crossing", rig=rig, fps=25, detections=det), truth


def test_two_people_crossing_keep_their_identities(body, crossing):
    seq, truth = crossing                                       # truth: (2, F, L, 3)
    people = PeopleTracker(factory(body, seq.rig))
    tracks = people.start(frame_of(seq, 0))
    assert len(tracks) == 2
    for f in range(1, FRAMES):
        people.step(frame_of(seq, f))
    first = {}
    for t in tracks:
        lms = t.tracker.landmarks
        idx = [LABELS.index(n) for n in lms.names]
        for f, est in sorted(t.estimates.items()):
            X = lms.positions(t.tracker.shaped, est.chi[None])[0].astype(np.float64)
            d = [np.linalg.norm(X - truth[n, f][idx], axis=1).mean() for n in range(2)]
            who = int(np.argmin(d))
            first.setdefault(t.id, who)
            assert who == first[t.id], f"track {t.id} switched to person {who} at frame {f}"
            assert d[who] < 0.06, f"track {t.id} lost its person at frame {f}: {d[who]:.3f} m"
    assert sorted(first.values()) == [0, 1]


def test_a_chosen_person_is_tracked_alone(body, crossing):
    seq, truth = crossing
    near_second = truth[1, 0].mean(axis=0)
    people = PeopleTracker(factory(body, seq.rig), select=tuple(near_second))
    (track,) = people.start(frame_of(seq, 0))
    X = track.tracker.landmarks.positions(track.tracker.shaped, track.tracker.history[-1][None])[0]
    assert np.linalg.norm(X.mean(axis=0) - near_second) < 0.1
    with pytest.raises(ValueError, match="person id 5 not found"):
        PeopleTracker(factory(body, seq.rig), select=5).start(frame_of(seq, 0))
