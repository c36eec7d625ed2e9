"""The named trackers, in Python: each is a factory of :mod:`mocap.trackers.factory` and the
arguments that differ from the factory's defaults (which are the one source of defaults).

``conf/tracker/<name>.yaml`` states the same overrides for Hydra (``apf_prior`` and
``apf_25x10`` compose ``apf``, ``hybrid`` composes ``local`` and ``apf_prior``);
``tests/trackers/test_presets.py`` checks that both give the same tracker.
"""

from __future__ import annotations

from collections.abc import Callable

from mocap.trackers import factory
from mocap.trackers.factory import merge

#: name -> (factory, overrides of its defaults)
PRESETS: dict[str, tuple[Callable, dict]] = {
    "apf": (factory.make_apf_tracker, {}),
    "apf_prior": (factory.make_apf_tracker, {"particles": 25, "layers": 10, "energy": {"prior": 1.0}}),
    "apf_25x10": (factory.make_apf_tracker, {"particles": 25, "layers": 10}),
    "local": (factory.make_local_tracker, {}),
    "hybrid": (factory.make_hybrid_tracker, {}),
    "marker_apf": (factory.make_marker_tracker, {}),
}


def make_tracker(name: str, *, body, rig, rng, **overrides):
    """The tracker ``name`` (a key of :data:`PRESETS`) with ``overrides`` of its settings
    (nested mappings, e.g. ``energy={"smoothness": 0.1}``, are merged)."""
    if name not in PRESETS:
        raise ValueError(f"unknown tracker {name!r}; available: {sorted(PRESETS)}")
    make, preset = PRESETS[name]
    return make(body=body, rig=rig, rng=rng, name=name, **merge(preset, overrides))
