"""Reading a finished run folder back: its configuration, body model and data.

A run's resolved configuration is stored in its ``metrics.json`` (``"config"``: plain
values, written last); its ``body`` and ``data`` entries name a ``_target_`` inside
:mod:`mocap` with keyword arguments, which :func:`mocap.presets.build` calls without Hydra.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from mocap import presets


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON to ``path`` atomically (a temporary file renamed over it)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    tmp.replace(path)


def run_config(run_dir: str | Path) -> dict:
    """The resolved configuration a finished run used (``metrics.json``'s ``"config"``)."""
    path = Path(run_dir) / "metrics.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not found (is {run_dir} a finished run directory?)")
    config = json.loads(path.read_text()).get("config")
    if not isinstance(config, Mapping):
        raise ValueError(f"{path} holds no config (not a run written by mocap track)")
    return dict(config)


def _target_call(node: Mapping, what: str, **kwargs):
    if not isinstance(node, Mapping) or "_target_" not in node:
        raise ValueError(f"the run's config has no {what} with a _target_")
    keys = {k: v for k, v in node.items() if k not in ("_partial_", "_recursive_", "_convert_")}
    return presets.build(keys, **kwargs)


def run_body(config: Mapping):
    """The body model of a run's configuration (its ``body`` entry)."""
    return _target_call(config.get("body"), "body")


def run_sequence(config: Mapping, body, drop: tuple[str, ...] = (), **changes):
    """The sequence of a run's configuration (its ``data`` entry) for ``body``; ``drop``:
    keys of the data entry left out (their defaults apply), ``changes``: keys replaced."""
    data = config.get("data")
    if not isinstance(data, Mapping):
        raise ValueError("the run's config has no data entry")
    return _target_call({**{k: v for k, v in data.items() if k not in drop}, **changes}, "data", body=body)
