"""The oracle in a run's metrics (issue 38): a setting skips it, a cache folder keeps each fit by
the content of the ground truth it was fitted to, and a bad setting is one line."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import mocap.eval.run_metrics as run_metrics
from mocap.body import load_body
from mocap.data.sequence_io import load_ground_truth
from mocap.eval.run_metrics import OracleSettings, accuracy_metrics, oracle_settings

WALK = Path(__file__).resolve().parents[2] / "data" / "mismatch" / "walk"
F = 4


@pytest.fixture(scope="module")
def body():
    return load_body("paper22")


@pytest.fixture
def seq():
    """The model-mismatch walk's ground truth (joints by name, no pose chi; its true surface left
    out: the surface oracle has tests of its own); F frames are scored."""
    gt = dataclasses.replace(load_ground_truth(WALK / "gt.npz"), surface=None, surface_faces=None)
    return SimpleNamespace(name="mismatch_walk", gt=gt)


def score(body, seq, oracle):
    chis = np.zeros((F, body.num_dofs))
    return accuracy_metrics(body, seq, chis, np.zeros(body.num_shape), oracle)


def test_the_oracle_can_be_switched_off_without_changing_the_other_metrics(body, seq, monkeypatch):
    monkeypatch.setattr(run_metrics, "_ORACLES", {})
    monkeypatch.setattr(run_metrics, "_FITS", {})
    on = score(body, seq, None)
    off = score(body, seq, {"enabled": False})
    assert "oracle" in on and on["oracle"]["raw_mm"] > 0 and "oracle" not in off
    assert {k: v for k, v in on.items() if k != "oracle"} == off


def test_a_cached_fit_is_reused_by_content_and_equals_the_fit(body, seq, tmp_path, monkeypatch):
    monkeypatch.setattr(run_metrics, "_ORACLES", {})
    monkeypatch.setattr(run_metrics, "_FITS", {})
    fitted = []
    real = run_metrics.fit_oracle
    monkeypatch.setattr(run_metrics, "fit_oracle", lambda *a, **k: fitted.append(1) or real(*a, **k))
    cache = {"cache": str(tmp_path / "oracles")}
    first = score(body, seq, cache)["oracle"]
    (written,) = (tmp_path / "oracles").glob("oracle-*.json")
    assert json.loads(written.read_text())["metrics"] == first
    monkeypatch.setattr(run_metrics, "_ORACLES", {})            # another process: the file serves
    monkeypatch.setattr(run_metrics, "_FITS", {})
    assert score(body, seq, cache)["oracle"] == first and len(fitted) == 1
    # other ground truth (one joint moved 1 cm in one frame): another key, fitted again
    joints = seq.gt.joints.copy()
    joints[2, 3, 0] += 0.01
    moved = SimpleNamespace(name=seq.name, gt=dataclasses.replace(seq.gt, joints=joints))
    assert score(body, moved, cache)["oracle"] != first and len(fitted) == 2
    assert len(list((tmp_path / "oracles").glob("oracle-*.json"))) == 2
    assert not list((tmp_path / "oracles").glob(".*tmp"))


@pytest.mark.parametrize("config, words", [({"enabled": "yes"}, ["oracle.enabled", "'yes'"]),
                                           ({"cache": 3}, ["oracle.cache", "3"]),
                                           ({"skip": True}, ["oracle.skip"])])
def test_a_bad_oracle_setting_is_one_line_naming_it(config, words):
    with pytest.raises(ValueError) as info:
        oracle_settings(config)
    assert all(w in str(info.value) for w in words) and "\n" not in str(info.value)


def test_the_defaults_fit_the_oracle_without_a_cache():
    assert oracle_settings(None) == OracleSettings() == OracleSettings(enabled=True, cache=None)
