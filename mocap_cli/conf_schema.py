"""The tracker presets and the data sources' default settings as Hydra config nodes.

Each preset of :mod:`mocap.trackers.presets` is stored by :func:`register_configs` as the option
``tracker/<name>`` of Hydra's ConfigStore: the full tree of its settings (so that every key can
be overridden on the command line without a ``+``), ``_target_`` the one builder
(:func:`mocap.trackers.presets.make_tracker`) and ``name`` the preset. No YAML restates a
preset: the settings dataclasses stay the only place a default is written and presets.py the
only place a preset's differences are. A config folder added with ``--config-dir`` may add
trackers of its own (``tracker/<name>.yaml``) beside these.

The data sources' settings dataclasses (:mod:`mocap.data.source_settings`) are stored as
``data_settings/<source>``, the full default tree a ``conf/data/*.yaml`` starts from
(``defaults: [/data_settings@_here_: folder, _self_]``), so that it lists only what differs
and every key stays overridable as ``data.<key>=...``.

Call :func:`register_configs` before composing (:mod:`mocap_cli.hydra_edge` and reading
``mocap_cli.CONF_DIR`` do)."""

from __future__ import annotations

from hydra.core.config_store import ConfigStore

from mocap.data.source_settings import CrowdSource, FolderSource, OpenPoseSource, SyntheticSource, VideoSource
from mocap.settings import settings_to_mapping
from mocap.trackers.presets import PRESETS

#: the config group of the trackers (``tracker=<name>``)
GROUP = "tracker"
#: the config group of the data sources' default trees (``/data_settings@_here_: <source>``)
DATA_GROUP = "data_settings"
DATA_SOURCES = {"synthetic": SyntheticSource, "folder": FolderSource, "crowd": CrowdSource,
                "openpose": OpenPoseSource, "video": VideoSource}
#: what every preset's node builds it with
BUILDER = "mocap.trackers.presets.make_tracker"


def preset_node(name: str) -> dict:
    """The config node of preset ``name``: builder, name, then its settings' full tree."""
    return {"_target_": BUILDER, "name": name, **settings_to_mapping(PRESETS[name])}


def register_configs() -> None:
    """Store each preset as ``tracker/<name>`` and each data source's defaults as
    ``data_settings/<source>`` (idempotent)."""
    store = ConfigStore.instance()
    for name in PRESETS:
        store.store(group=GROUP, name=name, node=preset_node(name))
    for name, cls in DATA_SOURCES.items():
        store.store(group=DATA_GROUP, name=name, node=settings_to_mapping(cls()))


def options(group: str) -> list[str]:
    """The names ConfigStore holds in ``group`` (none when it holds no such group)."""
    try:
        return [n.removesuffix(".yaml") for n in ConfigStore.instance().list(group)]
    except OSError:
        return []
