"""Each default once: a tracker's settings are one frozen dataclass, and a preset's differences
are written once (mocap/trackers/presets.py): Hydra's ``tracker=<name>`` options are those
presets, registered from Python (no YAML restates them), composing one gives the Python preset's
settings and one builder builds both, every key is overridable without ``+``, and bad keys or
values give one line naming the dotted key."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.utils import instantiate

import mocap
from mocap.cameras import ring_rig
from mocap.energy.prior import default_prior_path
from mocap.settings import settings_from_mapping, settings_to_mapping, with_overrides
from mocap.trackers import factory
from mocap.trackers.markers.settings import MarkerInit, MarkerPeopleSettings, MarkerSettings
from mocap.trackers.presets import PRESETS, SETTINGS_CLASSES, make_tracker, preset_settings
from mocap.trackers.tracker_settings import APFTrackerSettings, HybridSettings, LocalSettings, PriorSettings
from mocap_cli.conf_schema import register_configs

CONF = Path(__file__).resolve().parents[2] / "conf"
TRACKERS = CONF / "tracker"
NOT_SETTINGS = ("_target_", "name")        # what a tracker config selects, not settings
register_configs()


def compose_tracker(name: str, overrides=()):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        return compose("track", overrides=[f"tracker={name}", *overrides]).tracker


def build(cfg, body, rig):
    """The tracker a config names (partial: Hydra would turn the rig, a dataclass, into a config)."""
    return instantiate(cfg, _partial_=True)(body=body, rig=rig, rng=np.random.default_rng(0))


def leaves(tree: dict, prefix: str = ""):
    """(dotted key, value) of every leaf of a nested mapping."""
    for k, v in tree.items():
        if isinstance(v, dict) and v:
            yield from leaves(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}", v


def at(settings, dotted: str):
    for part in dotted.split("."):
        settings = getattr(settings, part)
    return settings


def settings_class(name: str) -> type:
    return type(PRESETS[name])


def tracker_options() -> list[str]:
    """The ``tracker=`` options Hydra offers with the shipped config folder."""
    with initialize_config_dir(str(CONF), version_base="1.3"):
        return sorted(GlobalHydra.instance().config_loader().get_group_options("tracker"))


@pytest.fixture(scope="module")
def rig():
    return ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45, look_at=(0, 0, 0.9))


def test_the_tracker_options_are_the_presets_and_no_yaml_restates_one():
    assert tracker_options() == sorted(PRESETS)
    assert not list(TRACKERS.glob("*.yaml"))
    assert {settings_class(n) for n in PRESETS} == set(SETTINGS_CLASSES.values())
    for name, cls in SETTINGS_CLASSES.items():
        assert PRESETS[name] == cls(), name          # the root presets are the defaults
        assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_composed_config_gives_the_python_preset(name, body, rig):
    cfg = compose_tracker(name)
    assert cfg.name == name
    keys = {k: v for k, v in cfg.items() if k not in NOT_SETTINGS}
    assert settings_from_mapping(settings_class(name), keys) == PRESETS[name]
    assert cfg._target_ == "mocap.trackers.presets.make_tracker"           # one builder for all
    tracker = build(cfg, body, rig)
    assert tracker.tracker_settings == PRESETS[name] and tracker.name == name


def test_the_hybrid_composes_settings_not_another_tracker():
    cfg = compose_tracker("hybrid")
    assert "_target_" not in cfg.apf and "name" not in cfg.apf and "_target_" not in cfg.local


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_key_is_overridable_without_plus(name, body, rig):
    """Every leaf of the settings tree is in the composed config; one override per leaf kind
    (a number, a list, a nested key) composes without ``+`` and reaches the settings."""
    cfg = compose_tracker(name)
    tree = settings_to_mapping(PRESETS[name])
    for key, _ in leaves(tree):
        node = cfg
        for part in key.split("."):
            assert part in node, f"tracker={name}: {key} is missing from the composed config"
            node = node[part]
    picks = {"apf": ["tracker.particles=7", "tracker.init_std=[0.01,0.02,0.05]",
                     "tracker.prior.limit_sigma=0.2", "tracker.initialization.rounds=1"],
             "local": ["tracker.iterations=4", "tracker.misalignment.threshold=0.2",
                       "tracker.sift.enabled=false", "tracker.contour.observed_stride=2"],
             "hybrid": ["tracker.apf.particles=7", "tracker.apf.init_std=[0.01,0.02,0.05]",
                        "tracker.local.shape.every=0", "tracker.apf.prior.prior_source=procedural"],
             "marker_apf": ["tracker.layers=3", "tracker.init.particles=50", "tracker.refine.gate_px=5.0",
                            "tracker.offsets.frames=2"],
             "marker_people": ["tracker.layers=3", "tracker.init.particles=50",
                               "tracker.people.confirm_frames=5", "tracker.people.radius=0.4"]}
    family = next((f for f in ("apf", "hybrid") if name.startswith(f)), name)     # presets of one class
    cfg = compose_tracker(name, picks[family])
    settings = build(cfg, body, rig).tracker_settings
    for override in picks[family]:
        key, value = override[len("tracker."):].split("=")
        value = yaml.safe_load(value)
        want = tuple(value) if isinstance(value, list) else value
        assert at(settings, key) == want, override


def test_python_overrides_and_config_overrides_give_the_same_settings(body, rig):
    cfg = compose_tracker("hybrid", ["tracker.apf.layers=3", "tracker.local.iterations=4",
                                     "tracker.apf.energy.smoothness=0.05"])
    from_config = build(cfg, body, rig).tracker_settings
    from_python = preset_settings("hybrid", {"apf": {"layers": 3, "energy": {"smoothness": 0.05}},
                                             "local": {"iterations": 4}})
    assert from_config == from_python != HybridSettings()
    assert from_python.apf.particles == 25 and from_python.apf.energy.prior == 0.0   # the rest kept


def test_presets_are_the_settings_with_their_differences():
    apf, x25, prior = (PRESETS[n] for n in ("apf", "apf_25x10", "apf_prior"))
    assert (x25.particles, x25.layers) == (25, 10) and x25.energy == apf.energy
    assert dataclasses.replace(x25, particles=apf.particles, layers=apf.layers) == apf
    assert dataclasses.replace(prior, energy=x25.energy) == x25 and prior.energy.prior == 1.0


@pytest.mark.parametrize("cls", [APFTrackerSettings, LocalSettings, HybridSettings, MarkerSettings,
                                 MarkerPeopleSettings])
def test_settings_round_trip_through_a_plain_tree(cls):
    tree = settings_to_mapping(cls())
    assert yaml.safe_load(yaml.safe_dump(tree)) == tree            # plain values only
    assert settings_from_mapping(cls, tree) == cls()


def test_lists_become_tuples_and_nested_mappings_nested_settings(body, rig):
    s = settings_from_mapping(MarkerSettings, {"init_std": [0.01, 0.02, 0.04], "init": {"std": [1, 2, 3]},
                                               "landmarks": ["l_wrist", {"name": "x", "joint": "head"}]})
    assert s.init_std == (0.01, 0.02, 0.04) and s.init.std == (1.0, 2.0, 3.0)
    assert isinstance(s.init, MarkerInit) and s.init.particles == MarkerInit().particles
    assert s.landmarks == ("l_wrist", {"name": "x", "joint": "head"})
    tracker = make_tracker("apf", body=body, rig=rig, rng=np.random.default_rng(0),
                           init_std=[0.01, 0.02, 0.05])
    np.testing.assert_array_equal(tracker.std0[[0, 3, 6]], [0.01, 0.02, 0.05])


@pytest.mark.parametrize(("name", "overrides", "pattern"), [
    ("hybrid", {"apf": {"partcles": 5}}, r"'apf\.partcles' .*did you mean apf\.particles[,?]"),
    ("apf", {"energy": {"smooth": 0.1}}, r"'energy\.smooth' .*allowed: silhouette, smoothness, prior"),
    ("local", {"misalignment": {"treshold": 0.1}}, r"'misalignment\.treshold'.*misalignment\.threshold"),
    ("marker_apf", {"init": {"particles": 1}},
     r"init\.particles = 1 is out of range \(allowed: an integer >= 2\)"),
    ("hybrid", {"apf": {"restart": 1.5}}, r"apf\.restart = 1\.5 is out of range \(allowed: \[0, 1\]\)"),
    ("hybrid", {"local": {"shape": {"every": -1}}}, r"setting local\.shape\.every = -1 is out of range"),
    ("apf_prior", {"survival": 1.0}, r"setting survival = 1\.0 is out of range \(allowed: \(0, 1\)\)"),
    ("apf", {"energy": {"prior": -1}}, r"setting energy\.prior = -1 is out of range \(allowed: >= 0"),
    ("apf", {"particles": "many"}, r"setting particles = 'many' must be a number \(default 100\)"),
    ("apf", {"particles": 2.5}, r"setting particles = 2\.5 must be an integer"),
    ("apf", {"init_std": [0.1, 0.2]}, r"setting init_std = \(0\.1, 0\.2\) must be a list of 3 numbers"),
    ("local", {"sift": {"enabled": "yes"}}, r"setting sift\.enabled = 'yes' must be true or false"),
    ("marker_apf", {"refine": 3}, r"setting refine = 3 must be a mapping of the settings Refinement"),
])
def test_bad_keys_and_values_give_one_line_naming_the_key(name, overrides, pattern):
    with pytest.raises(ValueError, match=pattern) as err:
        preset_settings(name, overrides)
    assert "\n" not in str(err.value)


def test_bad_values_fail_before_work_through_every_entrance(body, rig):
    seq = mocap.synthetic_sequence(body, frames=2)
    with pytest.raises(ValueError, match=r"unknown setting 'apf\.partcles'"):
        mocap.track(seq, "hybrid", body=body, apf={"partcles": 5})
    with pytest.raises(ValueError, match=r"unknown setting 'partcles'"):
        make_tracker("apf", body=body, rig=rig, rng=np.random.default_rng(0), partcles=5)
    cfg = compose_tracker("hybrid", ["tracker.apf.restart=2"])
    with pytest.raises(Exception, match=r"apf\.restart = 2 is out of range \(allowed: \[0, 1\]\)"):
        build(cfg, body, rig)
    with pytest.raises(ValueError, match="unknown tracker 'nope'; available: apf, apf_25x10"):
        preset_settings("nope")


def test_one_builder_per_settings_class_and_no_keyword_factories():
    assert set(factory.BUILDERS) == set(SETTINGS_CLASSES.values())
    assert not [n for n in vars(factory) if n.startswith("make_") and n != "make_pose_prior"]
    with pytest.raises(TypeError, match="no tracker is built from PriorSettings"):
        factory.build_tracker(None, None, None, PriorSettings(), "x")


def test_prior_source_selects_the_prior_file(body):
    assert factory.prior_file(body, PriorSettings()) == default_prior_path(body.name)
    assert factory.prior_file(body, PriorSettings(prior_file="/x/p.npz")) == Path("/x/p.npz")
    with pytest.raises(ValueError, match="bogus"):
        factory.prior_file(body, PriorSettings(prior_source="bogus"))
    assert with_overrides(PriorSettings(), {"prior_source": "real"}).prior_source == "real"
