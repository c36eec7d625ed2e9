"""The tracker presets as Hydra config nodes: each preset of :mod:`mocap.trackers.presets` is
stored by :func:`register_configs` as the option ``tracker/<name>`` of Hydra's ConfigStore,
the full tree of its settings (so that every key can be overridden on the command line without
a ``+``) with ``_target_`` the one builder, :func:`mocap.trackers.presets.make_tracker`, and
``name`` the preset. No YAML restates a preset: the settings dataclasses stay the only place a
default is written and presets.py the only place a preset's differences are. A config folder
added with ``--config-dir`` may add trackers of its own (``tracker/<name>.yaml``) beside these.
Call :func:`register_configs` before composing (:mod:`mocap_cli.hydra_edge` does)."""

from __future__ import annotations

from hydra.core.config_store import ConfigStore

from mocap.settings import settings_to_mapping
from mocap.trackers.presets import PRESETS

#: the config group of the trackers (``tracker=<name>``)
GROUP = "tracker"
#: what every preset's node builds it with
BUILDER = "mocap.trackers.presets.make_tracker"


def preset_node(name: str) -> dict:
    """The config node of preset ``name``: builder, name, then its settings' full tree."""
    return {"_target_": BUILDER, "name": name, **settings_to_mapping(PRESETS[name])}


def register_configs() -> None:
    """Store each preset as ``tracker/<name>`` (idempotent)."""
    store = ConfigStore.instance()
    for name in PRESETS:
        store.store(group=GROUP, name=name, node=preset_node(name))


def options(group: str) -> list[str]:
    """The names ConfigStore holds in ``group`` (none when it holds no such group)."""
    try:
        return [n.removesuffix(".yaml") for n in ConfigStore.instance().list(group)]
    except OSError:
        return []
