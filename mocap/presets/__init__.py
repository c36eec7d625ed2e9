"""Presets shipped with the package: ``body/<name>.yaml`` (DOF definitions of a body) and
``cameras/<name>.yaml`` (camera rigs). They are read with :mod:`importlib.resources`, so an
installed ``mocap`` works without the repository; Hydra finds them as the ``body`` and
``cameras`` config groups through ``hydra.searchpath: [pkg://mocap.presets]`` in
``conf/track.yaml`` and ``conf/make_dataset.yaml``.

Each file is a mapping with a ``_target_`` (the function that builds it) and its keyword
arguments; :func:`build` calls it without Hydra (targets inside ``mocap`` only).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from importlib import resources

import yaml

KINDS = ("body", "cameras")


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


def build(config: Mapping, **kwargs):
    """Call ``config["_target_"]`` (a function in the ``mocap`` package) with the other keys
    of ``config`` and ``kwargs``."""
    config = dict(config)
    target = str(config.pop("_target_"))
    module, _, attr = target.rpartition(".")
    if not module.startswith("mocap."):
        raise ValueError(f"preset target outside mocap: {target!r}")
    return getattr(importlib.import_module(module), attr)(**config, **kwargs)
