"""The trackers' settings as Hydra config nodes: each tracker config
(``conf/tracker/<name>.yaml``) starts from the full default tree of its settings dataclass
(:data:`mocap.trackers.presets.SETTINGS_CLASSES`), stored in the config group
``tracker_settings`` by :func:`register_configs`, so that every key can be overridden on the
command line without a ``+`` while the dataclass stays the only place a default is written.
The YAML files list only a preset's differences. Call :func:`register_configs` before
composing (:mod:`mocap_cli.hydra_edge` does); without it the configs still compose (the group
is optional) and the factories still fill in the defaults, but keys the YAML does not list
then need a ``+``."""

from __future__ import annotations

from hydra.core.config_store import ConfigStore

from mocap.settings import settings_to_mapping
from mocap.trackers.presets import SETTINGS_CLASSES

#: the config group of the settings' default trees (``/tracker_settings@_here_: <name>``)
GROUP = "tracker_settings"


def register_configs() -> None:
    """Store each tracker settings dataclass's defaults as ``tracker_settings/<name>``
    (idempotent)."""
    store = ConfigStore.instance()
    for name, cls in SETTINGS_CLASSES.items():
        store.store(group=GROUP, name=name, node=settings_to_mapping(cls()))
