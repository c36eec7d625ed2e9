"""Each data-source default once (mocap/data/source_settings.py): no conf/data YAML restates a
default of its source's settings, every setting stays overridable as ``data.<key>=...`` without
``+``, the generator's and the Python API's defaults are the settings', and a bad key is one line
naming it, through the loader and in a stored config."""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import pytest
import yaml

import mocap
from mocap import presets
from mocap.data.generate import make_synthetic
from mocap.data.source_settings import SOURCES, FolderSource, SyntheticSource
from mocap.data.sources import folder_sequence
from mocap.data.synthetic import generate_sequence
from mocap_cli.hydra_edge import compose

CONF = Path(__file__).resolve().parents[2] / "conf" / "data"
SOURCE_CONFIGS = sorted(p.stem for p in CONF.glob("*.yaml")
                        if yaml.safe_load(p.read_text()).get("_target_") in SOURCES)


def test_the_synthetic_and_folder_configs_are_found():
    assert {"walk_small", "folder", "mismatch_box", "real_bow_tall_man"} <= set(SOURCE_CONFIGS)


@pytest.mark.parametrize("name", SOURCE_CONFIGS)
def test_no_data_config_restates_a_default(name):
    own = yaml.safe_load((CONF / f"{name}.yaml").read_text())
    cls = SOURCES[own["_target_"]]
    defaults = {f.name: f.default for f in dataclasses.fields(cls)}
    for key, value in own.items():
        if key in ("defaults", "_target_"):
            continue
        assert key in defaults, f"{name}.yaml: {key} is not a setting of {cls.__name__}"
        assert value != defaults[key], f"{name}.yaml restates {key} = {value!r}, its default"


@pytest.mark.parametrize("name", SOURCE_CONFIGS)
def test_every_setting_is_in_the_composed_config(name):
    overrides = ["data.path=/x"] if name == "folder" else []
    data = compose("track", [f"data={name}", *overrides]).data
    cls = SOURCES[data._target_]
    assert set(data) == {"_target_", *(f.name for f in dataclasses.fields(cls))}


def test_an_unlisted_setting_overrides_without_plus():
    data = compose("track", ["data=mismatch_box", "data.views=[0,2,4,6]", "data.nonfinite=drop"]).data
    assert list(data.views) == [0, 2, 4, 6] and data.nonfinite == "drop"
    assert compose("track", ["data=walk_small", "data.fps=30"]).data.fps == 30


def test_the_generator_and_the_api_take_their_defaults_from_the_settings():
    for fn in (make_synthetic, generate_sequence, mocap.synthetic_sequence):
        for p in inspect.signature(fn).parameters.values():
            if p.default is not inspect.Parameter.empty and p.name in SyntheticSource.__dataclass_fields__:
                assert p.default == getattr(SyntheticSource, p.name), (fn.__name__, p.name)


def test_a_bad_key_is_one_line_naming_it(body):
    with pytest.raises(ValueError, match=r"unknown setting 'view' \(FolderSource\); did you mean views") as e:
        folder_sequence(body=body, path="/x", view=[0])
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match=r"setting images = 'yes' must be true or false"):
        folder_sequence(body=body, path="/x", images="yes")
    with pytest.raises(ValueError, match="data.fps = 0.0 is not a frame rate"):
        SyntheticSource(fps=0)
    assert FolderSource().path is None


def test_a_stored_config_with_a_key_the_source_lacks_is_refused():
    stored = {"_target_": "mocap.data.sources.folder_sequence", "path": "/x", "bogus": 1}
    with pytest.raises(presets.UnregisteredTargetError, match="takes no setting 'bogus'; refused"):
        presets.check(stored, "data")
    presets.check({"_target_": stored["_target_"], "path": "/x", "views": [0]}, "data")   # its own keys pass
