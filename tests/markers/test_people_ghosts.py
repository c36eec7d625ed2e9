"""No ghost tracks (mocap/trackers/markers/people.py): a person must be seen in ``min_views``
views to be started, a track seen in fewer for long ends; the crowd simulator's false
skeletons (mocap/data/crowd.py)."""

import hashlib

import numpy as np
import pytest

from mocap.body.skeletons import LAYOUTS
from mocap.cameras import rig_from_config
from mocap.data.crowd import (
    CROWD_RIG,
    crowd_detections,
    crowd_sequence,
    false_skeletons,
    straight_walk,
    with_false_skeletons,
)
from mocap.data.sequence import Detections
from mocap.trackers.markers.settings import PeopleOptions
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]
FAST = {"particles": 20, "layers": 3, "init": {"particles": 60, "passes": 2, "layers": 5}}
FRAMES = 10


def _rows(det: Detections, views, first: int = 0, tag: int = 0) -> np.ndarray:
    """det's rows in ``views`` from frame ``first`` on, as false_skeletons' rows (person ``tag``)."""
    keep = np.isin(det.view, list(views)) & (det.frame >= first)
    return np.column_stack([det.frame[keep], det.view[keep], det.label[keep], det.xy[keep],
                            det.confidence[keep], np.full(keep.sum(), tag)]).astype(np.float64)


def _walker(body, rig, start, end, yaw, seed):
    chi = straight_walk(body, FRAMES, start, end, yaw, seed=seed)
    alpha = np.random.default_rng(seed).normal(0, 0.5, body.num_shape)
    det, _ = crowd_detections(body, rig, chi[None], alpha[None], LABELS, noise_px=1.0, seed=seed)
    return det


@pytest.fixture(scope="module")
def scene(body):
    """One person seen in all 5 views; a false person (a whole walking skeleton) in views 0 and 2
    only from frame 0; a newcomer seen in views 0, 1 and 3 only from frame 4."""
    rig = rig_from_config(CROWD_RIG)
    real = _walker(body, rig, (-1.0, 0.0), (0.0, 0.0), 0.0, 1)
    ghost = _walker(body, rig, (0.3, 1.2), (1.0, 1.0), -0.3, 2)
    newcomer = _walker(body, rig, (1.0, -1.2), (0.2, -1.2), np.pi, 3)
    rows = np.concatenate([_rows(ghost, (0, 2), tag=0), _rows(newcomer, (0, 1, 3), first=4, tag=1)])
    det = with_false_skeletons(real, rows, seed=0)
    return rig, det


def _people(body, rig, **people):
    return make_tracker("marker_people", body=body, rig=rig, rng=np.random.default_rng(0), **FAST,
                        people=people)


def test_min_views_defaults_to_three_with_four_or_more_cameras():
    assert PeopleOptions().views_needed(5) == 3
    assert PeopleOptions().views_needed(4) == 3
    assert PeopleOptions().views_needed(3) == 2
    assert PeopleOptions(min_views=2).views_needed(5) == 2


def test_a_false_skeleton_in_two_of_five_views_never_becomes_a_track_and_three_views_do(body, scene):
    from mocap.data.sequence import Sequence

    rig, det = scene
    seq = Sequence(name="ghost", rig=rig, fps=25, detections=det)
    people = _people(body, rig)
    assert people.min_views == 3
    first = people.start(frame_of(seq, 0))
    assert len(first) == 1                                   # the 2-view false person is no person
    for f in range(1, FRAMES):
        people.step(frame_of(seq, f))
    # the newcomer (3 views from frame 4) is confirmed in its third frame, and nothing else is born
    assert people.births == {0: [0], 6: [1]}
    assert people.deaths == {}
    # with min_views=2 the false person is started as a person
    before = _people(body, rig, min_views=2)
    assert len(before.start(frame_of(seq, 0))) == 2


def test_a_track_seen_in_fewer_views_than_min_views_for_long_ends(body):
    from mocap.data.sequence import Sequence

    rig = rig_from_config(CROWD_RIG)
    real = _walker(body, rig, (-1.0, 0.0), (0.0, 0.0), 0.0, 1)
    keep = (real.frame < 3) | np.isin(real.view, [0, 1])     # from frame 3 on: views 0 and 1 only
    det = Detections(real.labels, real.frame[keep], real.view[keep], real.label[keep], real.xy[keep],
                     real.confidence[keep], real.person[keep])
    seq = Sequence(name="fading", rig=rig, fps=25, detections=det)
    people = _people(body, rig, max_under_viewed=3)
    (track,) = people.start(frame_of(seq, 0))
    for f in range(1, FRAMES):
        people.step(frame_of(seq, f))
    # under-viewed in frames 3, 4, 5, 6: more than 3 frames at frame 6; its frames after 2 dropped
    assert people.deaths == {6: [track.id]}
    assert track.ended and max(track.estimates) == 2
    # with a longer allowance it lives on (the person is still triangulated from two views)
    longer = _people(body, rig, max_under_viewed=20)
    longer.start(frame_of(seq, 0))
    for f in range(1, FRAMES):
        longer.step(frame_of(seq, f))
    assert longer.deaths == {} and max(longer.tracks[0].estimates) == FRAMES - 1


def _digest(det: Detections) -> str:
    h = hashlib.sha256()
    for a in (det.frame, det.view, det.label, det.xy, det.confidence, det.person):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def test_the_crowd_has_no_false_skeletons_by_default_and_its_detections_are_unchanged(body):
    seq = crowd_sequence(body=body, frames=30, seed=0)
    # the digest of crowd_sequence(frames=30, seed=0) made by the code before false skeletons
    assert _digest(seq.detections) == "1ae1533999e82196"
    again = crowd_sequence(body=body, frames=30, seed=0, false_people=0)
    assert _digest(again.detections) == "1ae1533999e82196"
    assert "false_people" not in seq.meta["crowd"]


def test_false_skeletons_are_whole_moving_people_in_one_or_two_views(body):
    rig = rig_from_config(CROWD_RIG)
    rows, pts = false_skeletons(body, rig, 30, 4, LABELS, seed=0)
    assert set(np.unique(rows[:, 6]).astype(int)) == {0, 1, 2, 3}
    for n in range(4):
        mine = rows[rows[:, 6] == n]
        assert 1 <= len(np.unique(mine[:, 1])) <= 2                  # seen in one or two views
        frames = np.unique(mine[:, 0]).astype(int)
        assert len(frames) >= 30 // 4 - 1
        f0 = mine[mine[:, 0] == frames[0]]
        assert len(np.unique(f0[:, 2])) >= 10                        # a whole skeleton, not a keypoint
        moved = np.nanmean(pts[n, frames[-1]], axis=0) - np.nanmean(pts[n, frames[0]], axis=0)
        assert np.linalg.norm(moved[:2]) > 0.1                       # it walks
        height = np.nanmax(pts[n, frames[0], :, 2]) - np.nanmin(pts[n, frames[0], :, 2])
        assert 1.2 < height < 2.2                                    # a plausible person


def test_the_crowd_with_false_people_keeps_every_real_detection_and_adds_skeletons(body):
    clean = crowd_sequence(body=body, frames=20, seed=1).detections
    noisy = crowd_sequence(body=body, frames=20, seed=1, false_people=3)
    det = noisy.detections
    assert noisy.meta["crowd"]["false_people"] == 3
    key = lambda d: {(int(f), int(v), int(k), float(x), float(y))  # noqa: E731
                     for f, v, k, (x, y) in zip(d.frame, d.view, d.label, d.xy, strict=True)}
    assert key(clean) < key(det)
    extra = 0
    for f in range(20):
        for c in range(5):
            a = len(np.unique(clean.person[(clean.frame == f) & (clean.view == c)]))
            b = len(np.unique(det.person[(det.frame == f) & (det.view == c)]))
            assert b >= a
            extra += b - a
            sel = (det.frame == f) & (det.view == c)
            assert np.array_equal(np.unique(det.person[sel]), np.arange(b))   # one index per skeleton
    assert extra > 0
    assert np.all(np.diff(det.frame) >= 0)
