"""Presets shipped with the package: ``body/<name>.yaml`` (DOF definitions of a body) and
``cameras/<name>.yaml`` (camera rigs). They are read with :mod:`importlib.resources`, so an
installed ``mocap`` works without the repository; Hydra finds them as the ``body`` and
``cameras`` config groups through ``hydra.searchpath: [pkg://mocap.presets]`` in
``conf/track.yaml`` and ``conf/make_dataset.yaml``.

Each file is a mapping with a ``_target_`` (the name of what builds it) and its keyword
arguments; :func:`build` calls it without Hydra. A ``_target_`` is a name looked up in a closed
registry (:data:`TARGETS`: body models, camera rigs, data sources, trackers), never an import
path followed: a configuration read from a file someone else wrote (a run folder's
``metrics.json``, a camera YAML) cannot reach any other function. Its keys are checked against
what the registered function takes, and its values must be plain data (numbers, strings,
lists, mappings); anything else is refused in one line before anything is built or written.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
from collections.abc import Mapping
from importlib import resources

import yaml

KINDS = ("body", "cameras")

#: everything a configuration may build: ``_target_`` name -> (kind, module, function). The
#: only functions :func:`build` calls; the names are the ones conf/ and the presets use.
TARGETS: dict[str, tuple[str, str, str]] = {
    "mocap.body.load_body_model": ("body", "mocap.body.model", "load_body_model"),
    "mocap.body.load_body": ("body", "mocap.body", "load_body"),
    "mocap.cameras.rigs.ring_rig": ("cameras", "mocap.cameras.rigs", "ring_rig"),
    "mocap.data.sources.synthetic_sequence": ("data", "mocap.data.sources", "synthetic_sequence"),
    "mocap.data.sources.folder_sequence": ("data", "mocap.data.sources", "folder_sequence"),
    "mocap.data.crowd.crowd_sequence": ("data", "mocap.data.crowd", "crowd_sequence"),
    "mocap.data.openpose.openpose_sequence": ("data", "mocap.data.openpose", "openpose_sequence"),
    "mocap.video.sequence.video_sequence": ("data", "mocap.video.sequence", "video_sequence"),
    # the same function's name before mocap/video/ held it: runs recorded then still rescore
    "mocap.data.video_sequence.video_sequence": ("data", "mocap.video.sequence", "video_sequence"),
    "mocap.trackers.presets.make_tracker": ("tracker", "mocap.trackers.presets", "make_tracker"),
    # the per-tracker builders runs recorded before the presets had one builder name: their
    # metrics.json still reads (a tracker is never built from a file)
    **{f"mocap.trackers.factory.{f}": ("tracker", "mocap.trackers.presets", "make_tracker")
       for f in ("make_apf_tracker", "make_local_tracker", "make_hybrid_tracker",
                 "make_marker_tracker", "make_marker_people_tracker")},
}
#: a function taking ``**keys`` that are its settings: (module, settings dataclass) whose fields
#: are the accepted keys (:mod:`mocap.data.source_settings`)
_SETTINGS = {"mocap.data.sources.synthetic_sequence": ("mocap.data.source_settings", "SyntheticSource"),
             "mocap.data.sources.folder_sequence": ("mocap.data.source_settings", "FolderSource"),
             "mocap.data.crowd.crowd_sequence": ("mocap.data.source_settings", "CrowdSource"),
             "mocap.data.openpose.openpose_sequence": ("mocap.data.source_settings", "OpenPoseSource")}
#: keys of a Hydra node that are instructions to Hydra, not arguments
HYDRA_KEYS = ("_partial_", "_recursive_", "_convert_", "_args_")
_MAX_DEPTH = 12


class UnregisteredTargetError(ValueError):
    """A configuration names something to build that is not in :data:`TARGETS`, or gives it
    arguments it does not take or values that are not plain data."""


def names(kind: str) -> list[str]:
    """The presets of one kind (``"body"`` or ``"cameras"``)."""
    if kind not in KINDS:
        raise ValueError(f"preset kind must be one of {KINDS}, got {kind!r}")
    return sorted(p.name[:-5] for p in (resources.files(__name__) / kind).iterdir()
                  if p.name.endswith(".yaml"))


def read(kind: str, name: str) -> dict:
    """The preset ``name`` of ``kind`` as a plain dict."""
    available = names(kind)
    if name not in available:
        what = {"cameras": "camera", "body": "body"}[kind]
        raise ValueError(f"no {what} preset {name!r}; available: {available}")
    return yaml.safe_load((resources.files(__name__) / kind / f"{name}.yaml").read_text())


def target_of(config: Mapping, kind: str | None = None, where: str = "config") -> tuple[str, str, str]:
    """(kind, module, function) of ``config["_target_"]`` from :data:`TARGETS`; refused
    (:class:`UnregisteredTargetError`, one line naming ``where``) when it is not registered or
    not of ``kind``. Imports nothing."""
    target = config.get("_target_") if isinstance(config, Mapping) else None
    if not isinstance(target, str) or target not in TARGETS:
        raise UnregisteredTargetError(
            f"{where}: _target_ {str(target)[:120]!r} is not a registered builder; refused "
            f"(a file names what to build only from: {', '.join(sorted(TARGETS))})")
    entry = TARGETS[target]
    if kind is not None and entry[0] != kind:
        raise UnregisteredTargetError(f"{where}: _target_ {target!r} builds a {entry[0]}, "
                                      f"not a {kind}; refused")
    return entry


def check_plain(value, where: str, depth: int = 0) -> None:
    """Refuse (one line naming ``where``) a value that is not plain data: None, bool, int,
    finite-or-not float, str, or lists / mappings of them (a nested ``_target_`` must be
    registered too)."""
    if depth > _MAX_DEPTH:
        raise UnregisteredTargetError(f"{where}: nested more than {_MAX_DEPTH} levels deep; refused")
    if value is None or isinstance(value, (bool, int, str)):
        return
    if isinstance(value, float):
        return
    if isinstance(value, Mapping):
        if "_target_" in value:
            target_of(value, where=where)
        for k, v in value.items():
            if not isinstance(k, str):
                raise UnregisteredTargetError(f"{where}: key {k!r} is not a string; refused")
            check_plain(v, f"{where}.{k}", depth + 1)
        return
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            check_plain(v, f"{where}[{i}]", depth + 1)
        return
    raise UnregisteredTargetError(f"{where}: a {type(value).__name__} is not plain data; refused")


def check_targets(value, where: str = "config", depth: int = 0) -> None:
    """Every ``_target_`` anywhere in ``value`` (mappings and lists) is registered; else
    :class:`UnregisteredTargetError`, one line."""
    if depth > _MAX_DEPTH:
        raise UnregisteredTargetError(f"{where}: nested more than {_MAX_DEPTH} levels deep; refused")
    if isinstance(value, Mapping):
        if "_target_" in value:
            target_of(value, where=where)
        for k, v in value.items():
            check_targets(v, f"{where}.{k}", depth + 1)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            check_targets(v, f"{where}[{i}]", depth + 1)


def _accepted(target: str, fn) -> set[str] | None:
    """The keyword names ``fn`` takes (None: any)."""
    params = inspect.signature(fn).parameters
    names = {n for n, p in params.items() if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
    if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        return names
    if target in _SETTINGS:
        module, attr = _SETTINGS[target]
        return names | {f.name for f in dataclasses.fields(getattr(importlib.import_module(module), attr))}
    return None


def check(config: Mapping, kind: str | None = None, where: str = "config"):
    """The registered function ``config`` would call, after checking everything about it
    (:func:`build` without the call): a registered ``_target_`` of ``kind``, plain values, and
    only settings the function takes; else :class:`UnregisteredTargetError`, one line."""
    if not isinstance(config, Mapping):
        raise UnregisteredTargetError(f"{where}: expected a mapping with a _target_, "
                                      f"got {type(config).__name__}")
    _, module, attr = target_of(config, kind, where)
    args = {k: v for k, v in config.items() if k != "_target_" and k not in HYDRA_KEYS}
    check_plain(args, where)
    fn = getattr(importlib.import_module(module), attr)
    accepted = _accepted(str(config["_target_"]), fn)
    if accepted is not None:
        unknown = sorted(set(args) - accepted)
        if unknown:
            raise UnregisteredTargetError(f"{where}: {config['_target_']} takes no setting "
                                          f"{', '.join(map(repr, unknown))}; refused")
    return fn


def build(config: Mapping, kind: str | None = None, where: str = "config", **kwargs):
    """Build what ``config`` describes: its ``_target_`` looked up in :data:`TARGETS` (of
    ``kind`` when given), called with the other keys of ``config`` (plain data, each one a
    parameter the function takes) and ``kwargs`` (objects from the caller, e.g. ``body``).
    Anything else is refused with :class:`UnregisteredTargetError` before the call."""
    fn = check(config, kind, where)
    return fn(**{k: v for k, v in config.items() if k != "_target_" and k not in HYDRA_KEYS}, **kwargs)
