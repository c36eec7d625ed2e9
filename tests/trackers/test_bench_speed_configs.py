"""benchmarks/bench_speed.py's tracker variants compose and build with the settings they name
(a benchmark that fails to start, or silently times another configuration, measures nothing)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mocap.body import load_body
from mocap.cameras import rig_from_config
from mocap_cli.hydra_edge import build, compose

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_speed.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_speed", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", sorted(_bench().TRACKERS))
def test_every_variant_composes_and_builds_as_named(name):
    cfg_name, overrides, _ = _bench().TRACKERS[name]
    cfg = compose("track", [f"tracker={cfg_name}", *overrides])
    tracker = build(cfg.tracker, body=load_body("paper22"), rig=rig_from_config("ring4_small"),
                    rng=np.random.default_rng(0))
    settings = tracker.tracker_settings
    if name == "local":
        assert not settings.sift.enabled
    if name == "local_sift":
        assert settings.sift.enabled
    if name == "hybrid":
        assert not settings.local.sift.enabled
    if name.endswith("_full"):
        assert settings.energy_mesh is None
    elif name.startswith("apf"):
        assert settings.energy_mesh is not None
