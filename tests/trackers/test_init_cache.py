"""The self-initialisation cache returns the computed result and leaves the random state as the
computation would have."""

from __future__ import annotations

import numpy as np

from mocap.body import load_body
from mocap.cameras import rig_from_config
from mocap.trackers import initialization
from mocap.trackers.base import Frame
from mocap.trackers.contract import OnePerson
from mocap.trackers.init_cache import Cached, SilhouetteStart, initial_estimate
from mocap.trackers.initialization import INITIALIZER_VERSION


class Counting(OnePerson):
    """A stand-in tracker whose self-initialisation (the silhouette start, its computation
    replaced by a draw from the generator) counts its calls."""

    name = "counting"

    def __init__(self, body, rig, seed=0):
        self.body, self.rig, self.init_settings = body, rig, ("settings", 1)
        self.init_rng = np.random.default_rng(seed)
        self.calls = 0
        self.cacheable = True

    def initializer(self, cache=None):
        return Cached(CountingStart(self), cache)


class CountingStart(SilhouetteStart):
    def __init__(self, tracker):
        super().__init__(tracker.body, tracker.rig, tracker.init_settings, tracker.init_rng)
        self.tracker = tracker

    def __call__(self, frame):
        import unittest.mock

        def compute(body, rig, masks, rng, settings, progress=None, library=None):
            self.tracker.calls += 1
            return (rng.normal(size=body.num_dofs), np.zeros(body.num_shape),
                    {"margin": 0.5, "hypotheses": [{"energy": 1.0}], "other": 3})

        with unittest.mock.patch.object(initialization, "initialize_from_silhouettes", compute):
            return super().__call__(frame)

    def cache_key(self, frame):
        return super().cache_key(frame) if self.tracker.cacheable else None


def test_cache_hit_equals_the_computation_and_advances_the_random_state(tmp_path, monkeypatch):
    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    masks = np.zeros((len(rig.names), 8, 8), bool)
    masks[:, 2:5, 3:6] = True
    frame = Frame(index=0, masks=masks, images=None, detections=None)
    a, b = Counting(body, rig), Counting(body, rig)
    chi_a, alpha_a, info_a = initial_estimate(a, frame, tmp_path)
    chi_b, alpha_b, info_b = initial_estimate(b, frame, tmp_path)
    assert (a.calls, b.calls) == (1, 0) and not info_a["cached"] and info_b["cached"]
    np.testing.assert_array_equal(chi_a, chi_b)
    assert info_b["margin"] == 0.5 and "other" not in info_b
    assert info_a["initializer_version"] == info_b["initializer_version"] == INITIALIZER_VERSION
    assert a.init_rng.random() == b.init_rng.random()          # same state after the hit
    # another seed, other masks or other settings: computed anew
    c = Counting(body, rig, seed=1)
    initial_estimate(c, frame, tmp_path)
    d = Counting(body, rig)
    initial_estimate(d, Frame(index=0, masks=~masks, images=None, detections=None), tmp_path)
    e = Counting(body, rig)
    e.init_settings = ("settings", 2)
    initial_estimate(e, frame, tmp_path)
    assert (c.calls, d.calls, e.calls) == (1, 1, 1)
    assert len(list(tmp_path.glob("*.npz"))) == 4 and not list(tmp_path.glob(".*tmp*"))
    # a changed initialiser (its version raised): computed anew, not served from the cache
    monkeypatch.setattr(initialization, "INITIALIZER_VERSION", INITIALIZER_VERSION + 1)
    f = Counting(body, rig)
    initial_estimate(f, frame, tmp_path)
    assert f.calls == 1 and len(list(tmp_path.glob("*.npz"))) == 5


def test_without_a_cache_nothing_is_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    t = Counting(body, rig)
    masks = np.ones((len(rig.names), 4, 4), bool)
    _, _, info = initial_estimate(t, Frame(index=0, masks=masks, images=None, detections=None))
    assert t.calls == 1 and not info["cached"] and info["seconds"] >= 0
    assert not list(tmp_path.iterdir())


def test_a_start_without_a_cache_key_is_never_cached(tmp_path):
    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    t = Counting(body, rig)
    t.cacheable = False
    masks = np.ones((len(rig.names), 4, 4), bool)
    frame = Frame(index=0, masks=masks, images=None, detections=None)
    initial_estimate(t, frame, tmp_path)
    initial_estimate(t, frame, tmp_path)
    assert t.calls == 2 and not list(tmp_path.iterdir())


def test_the_key_changes_with_the_initialiser_version_and_its_settings(monkeypatch):
    from mocap.trackers.tracker_settings import InitSettings

    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 4, 4), bool), images=None, detections=None)

    def key(settings):
        return SilhouetteStart(body, rig, settings, np.random.default_rng(0)).cache_key(frame)

    before = key(InitSettings())
    assert key(InitSettings()) == before
    for changed in (InitSettings(energy_mesh=None), InitSettings(prune_margin=0.123)):
        assert key(changed) != before
    monkeypatch.setattr(initialization, "INITIALIZER_VERSION", INITIALIZER_VERSION - 1)
    assert key(InitSettings()) != before         # the results of version 2 are not served


def test_the_start_reports_its_progress_to_the_callback_or_a_progress_line(monkeypatch, capsys):
    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 8, 8), bool), images=None, detections=None)

    def compute(body, rig, masks, rng, settings, progress=None, library=None):
        for stage, f in (("heading", 0.0), ("refine", 0.5), ("done", 1.0)):
            progress(stage, f)
        return np.zeros(body.num_dofs), np.zeros(body.num_shape), {}

    monkeypatch.setattr(initialization, "initialize_from_silhouettes", compute)
    seen = []
    SilhouetteStart(body, rig, None, np.random.default_rng(0),
                    progress=lambda s, f: seen.append((s, f)))(frame)
    assert seen == [("heading", 0.0), ("refine", 0.5), ("done", 1.0)]
    assert "silhouette start-up" not in capsys.readouterr().err
    SilhouetteStart(body, rig, None, np.random.default_rng(0))(frame)       # None: a line on stderr
    err = capsys.readouterr().err
    assert "silhouette start-up" in err and "100%" in err and "done" in err


def test_the_limb_hypotheses_change_the_key_and_read_their_library_only_when_on():
    from mocap.trackers.tracker_settings import InitSettings

    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 4, 4), bool), images=None, detections=None)
    lib_a, lib_b = np.zeros((3, body.num_dofs)), np.ones((3, body.num_dofs))

    def key(settings, library=None):
        start = SilhouetteStart(body, rig, settings, np.random.default_rng(0), library=library)
        return start.cache_key(frame)

    off, on = InitSettings(), InitSettings(limb_hypotheses=200)
    assert key(off, lib_a) == key(off, lib_b) == key(off)          # off: the old start's key
    assert key(on, lib_a) != key(off, lib_a)                       # on: not the old start's result
    assert key(on, lib_a) != key(on, lib_b)                        # another library, another start


def test_a_silhouette_trackers_start_draws_from_the_library_the_tracker_declares():
    """The library is part of the silhouette trackers' contract (SilhouetteInitialisation.library):
    the local and APF trackers declare none, the hybrid its restarts' motion library, and the
    start its initializer hands out is given exactly that array."""
    from mocap.trackers.init_cache import SilhouetteInitialisation
    from mocap.trackers.presets import make_tracker

    body, rig = load_body("paper22"), rig_from_config("ring4_small")
    assert SilhouetteInitialisation.library is None
    for name in ("local", "apf"):
        tracker = make_tracker(name, body=body, rig=rig, rng=np.random.default_rng(0))
        assert tracker.library is None and tracker.initializer().start.library is None
    hybrid = make_tracker("hybrid", body=body, rig=rig, rng=np.random.default_rng(0))
    assert hybrid.library is not None and hybrid.library.shape[1] == body.num_dofs
    assert hybrid.initializer().start.start.library is hybrid.library      # Refined(Cached(start))
