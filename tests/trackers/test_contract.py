"""The parts of the tracker contract and the run's settings with known answers: births and ends
read from the people answered for per frame, the run's settings from a configuration (defaults,
one-line errors), what a tracker lacking a need or a self-initialisation is told."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from mocap.run_folder.people import births_and_ends
from mocap.run_folder.settings import RunSettings
from mocap.trackers.contract import Needs, OnePerson
from mocap.trackers.run import run_start

TRACKING_YAML = Path(__file__).resolve().parents[2] / "conf" / "tracking.yaml"


def test_births_and_ends_are_the_first_frame_in_and_the_first_frame_out():
    live = [(0, 1, 2), (0, 1, 2), (0, 2), (0, 2, 3), (2, 3), (2, 3)]
    born, ended = births_and_ends(live)
    assert born == {0: [0, 1, 2], 3: [3]}
    assert ended == {2: [1], 4: [0]}


def test_run_settings_take_the_defaults_the_tracking_config_documents():
    cfg = yaml.safe_load(TRACKING_YAML.read_text())
    s = RunSettings.from_config(cfg)
    assert s == RunSettings.from_config({})             # the YAML's values are the dataclass's defaults
    d = RunSettings()
    assert (d.seed, d.frames, d.threads, d.skip_complete, d.resume_on_change) == (
        cfg["seed"], cfg["frames"], cfg["threads"], cfg["skip_complete"], cfg["resume_on_change"])
    assert (d.init.mode, d.init.noise_deg, d.init.noise_translation, d.init.cache) == tuple(
        cfg["init"][k] for k in ("mode", "noise_deg", "noise_translation", "cache"))
    assert d.motion.vertices == cfg["motion"]["vertices"]
    assert (d.oracle.enabled, d.oracle.cache) == (cfg["oracle"]["enabled"], cfg["oracle"]["cache"])
    assert RunSettings.from_config({"frames": "all", "seed": 2}).frames is None


@pytest.mark.parametrize(("config", "message"), [
    ({"seed": -1}, "setting seed = -1 is not allowed"),
    ({"frames": 0}, "setting frames = 0 is out of range"),
    ({"init": {"mode": "bogus"}}, "init.mode must be one of"),
    ({"resume_on_change": "maybe"}, "setting resume_on_change = 'maybe' is not allowed"),
    ({"recording": {"level": "loud"}}, "setting recording.level = 'loud' is not allowed"),
])
def test_a_bad_run_setting_is_refused_in_one_line(config, message):
    with pytest.raises(ValueError, match=message) as err:
        RunSettings.from_config(config)
    assert "\n" not in str(err.value)


class Still(OnePerson):
    """One person, held where it started; reads masks; no self-initialisation."""

    name = "still"
    needs = Needs(masks=True)

    def initialize(self, chi, alpha):
        self.chi = chi

    def step(self, frame):
        raise AssertionError("not stepped here")


def test_a_tracker_is_told_what_the_data_lacks_and_that_it_cannot_start_itself(body):
    import mocap

    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=2, seed=0, masks=False,
                                   detections={"enabled": True, "labelled": True, "occlusion": False})
    with pytest.raises(ValueError, match="tracker 'still' needs silhouette masks, but sequence"):
        Still().check_sequence(seq)
    with pytest.raises(ValueError, match="tracker 'still' cannot initialise itself: use init.mode=gt_noise"):
        run_start("tracker", Still(), body, seq, np.random.default_rng(0))
    start = run_start("gt_noise", Still(), body, seq, np.random.default_rng(0), noise_deg=0.0,
                      noise_translation=0.0)
    est, info = start(None)
    np.testing.assert_allclose(est[0].chi, np.clip(seq.gt.chi[0], *body.limits.T))
    assert est[0].diagnostics.initial and info == {}
