"""The tracker a config composes is the tracker the Python API builds (same estimates for the
same seed); the settings themselves: tests/trackers/test_settings.py."""

from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.utils import instantiate

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.trackers.presets import PRESETS, make_tracker
from mocap.trackers.run import track_sequence
from mocap_cli.conf_schema import register_configs

CONF = Path(__file__).resolve().parents[2] / "conf"
register_configs()
# small budgets, applied to both sides
FAST = {"apf": {"particles": 6, "layers": 2}, "apf_prior": {"particles": 6, "layers": 2},
        "apf_prior_real": {"particles": 6, "layers": 2},
        "apf_25x10": {"particles": 6, "layers": 2}, "local": {"iterations": 2},
        **{h: {"local": {"iterations": 2}, "apf": {"particles": 6, "layers": 2}}
           for h in PRESETS if h.startswith("hybrid")},
        "marker_apf": {"particles": 8, "layers": 2},
        "marker_people": {"particles": 8, "layers": 2, "init": {"particles": 30, "passes": 1, "layers": 3}}}
#: trackers of several people: compared on a scene of people (test_marker_people_config_equals_python_api)
PEOPLE = {"marker_people"}


def flat(d, prefix="tracker"):
    for k, v in d.items():
        yield from flat(v, f"{prefix}.{k}") if isinstance(v, dict) else [f"{prefix}.{k}={v}"]


@pytest.fixture(scope="module")
def sequences(body):
    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45, look_at=(0, 0, 0.9))
    sil = make_synthetic(body, rig, motion="walk", frames=3, fps=25, seed=0, images=False)
    markers = make_synthetic(body, rig, motion="walk", frames=3, fps=25, seed=0, masks=False,
                             images=False, detections={"enabled": True, "labelled": True,
                                                       "occlusion": False})
    both = make_synthetic(body, rig, motion="walk", frames=3, fps=25, seed=0, images=False,
                          detections={"enabled": True, "labelled": True, "occlusion": False})
    return sil, markers, both


def test_every_tracker_option_is_a_python_preset():
    with initialize_config_dir(str(CONF), version_base="1.3"):
        assert sorted(GlobalHydra.instance().config_loader().get_group_options("tracker")) == sorted(PRESETS)


@pytest.mark.parametrize("name", sorted(set(PRESETS) - PEOPLE))
def test_config_tracker_equals_python_api_tracker(name, body, sequences):
    seq = {"marker_apf": sequences[1], "hybrid_kp": sequences[2]}.get(name, sequences[0])
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=[f"tracker={name}", *flat(FAST[name])])
    from_config = instantiate(cfg.tracker, _partial_=True)(body=body, rig=seq.rig,
                                                          rng=np.random.default_rng(5))
    from_python = make_tracker(name, body=body, rig=seq.rig, rng=np.random.default_rng(5), **FAST[name])
    assert type(from_config) is type(from_python) and from_config.name == from_python.name == name
    assert from_config.tracker_settings == from_python.tracker_settings
    for attr in ("settings", "weights", "iterations", "refine_iterations", "damping"):
        assert getattr(from_config, attr, None) == getattr(from_python, attr, None), attr
    results = [track_sequence(t, seq, seq.gt.chi[0], seq.gt.alpha) for t in (from_config, from_python)]
    a, b = ([e.chi for e in r.estimates] for r in results)
    np.testing.assert_array_equal(np.stack(a), np.stack(b))
    assert not np.array_equal(a[1], a[0])          # it tracked


def test_apf_prior_composes_apf_25x10_and_the_hybrid_its_settings():
    with initialize_config_dir(str(CONF), version_base="1.3"):
        apf = compose("track", overrides=["tracker=apf"]).tracker
        prior = compose("track", overrides=["tracker=apf_prior"]).tracker
        x25 = compose("track", overrides=["tracker=apf_25x10"]).tracker
        hybrid = compose("track", overrides=["tracker=hybrid"]).tracker
        moved = compose("track", overrides=["tracker=hybrid", "tracker.local.iterations=4"]).tracker
    assert prior._target_ == apf._target_ and (prior.particles, prior.layers) == (25, 10)
    assert prior.energy.prior == 1.0 and x25.energy.prior == apf.energy.prior == 0.0
    assert (apf.particles, apf.layers) == (100, 15) and (x25.particles, x25.layers) == (25, 10)
    assert hybrid.local.iterations == 10 and hybrid.apf.particles == 25 and hybrid.apf.energy.prior == 0.0
    assert moved.local.iterations == 4


def test_marker_people_config_equals_python_api(body):
    from mocap.data.crowd import crowd_sequence
    from mocap.trackers.run import frame_of

    seq = crowd_sequence(body=body, frames=20)
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=["tracker=marker_people", *flat(FAST["marker_people"])])
    built = instantiate(cfg.tracker, _partial_=True)
    trackers = [built(body=body, rig=seq.rig, rng=np.random.default_rng(5)),
                make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(5),
                             **FAST["marker_people"])]
    assert trackers[0].tracker_settings == trackers[1].tracker_settings
    chis = []
    for t in trackers:
        tracks = t.start(frame_of(seq, 0))
        out = t.step(frame_of(seq, 1))
        chis.append(np.stack([out[k.id].chi for k in tracks]))
    assert len(chis[0]) == 3
    np.testing.assert_array_equal(chis[0], chis[1])
