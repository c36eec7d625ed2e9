"""Reading a finished run folder back: its configuration, body model and data.

A run's resolved configuration is stored in its ``metrics.json`` (``"config"``: plain
values, written last); its ``body`` and ``data`` entries name a registered builder
(:data:`mocap.presets.TARGETS`) with its settings, which :func:`mocap.presets.build` calls
without Hydra. The file is data: a ``_target_`` that is not registered, a setting the builder
does not take or a value that is not plain data is refused in one line naming the file, before
anything is built or written.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from mocap import presets
from mocap.safe_files import write_text_atomic


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON to ``path`` atomically (a temporary file of an unpredictable name,
    created exclusively, renamed over it: :func:`mocap.safe_files.write_text_atomic`)."""
    write_text_atomic(path, json.dumps(data, indent=2))


def run_config(run_dir: str | Path) -> dict:
    """The resolved configuration a finished run used (``metrics.json``'s ``"config"``)."""
    path = Path(run_dir) / "metrics.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not found (is {run_dir} a finished run directory?)")
    try:
        metrics = json.loads(path.read_text())
    except ValueError as exc:
        raise ValueError(f"{path}: not readable JSON ({exc})") from None
    config = metrics.get("config") if isinstance(metrics, Mapping) else None
    if not isinstance(config, Mapping):
        raise ValueError(f"{path} holds no config (not a run written by mocap track)")
    check_run_config(config, str(path))
    return dict(config)


def _target_call(node: Mapping, what: str, where: str, **kwargs):
    if not isinstance(node, Mapping) or "_target_" not in node:
        raise ValueError(f"{where}: the run's config has no {what} with a _target_")
    return presets.build(node, kind=what, where=f"{where}: config.{what}", **kwargs)


def check_run_config(config: Mapping, where: str = "metrics.json") -> None:
    """Refuse (:class:`mocap.presets.UnregisteredTargetError`, one line) a stored configuration
    whose ``body`` / ``data`` is not a registered builder, or that holds anything but plain
    data anywhere (a nested ``_target_`` included). Builds nothing (imports only registered modules)."""
    presets.check_plain(dict(config), f"{where}: config")
    for what in ("body", "data"):
        node = config.get(what)
        if isinstance(node, Mapping) and "_target_" in node:
            presets.check(node, what, f"{where}: config.{what}")


def run_body(config: Mapping, where: str = "metrics.json"):
    """The body model of a run's configuration (its ``body`` entry, a registered builder)."""
    check_run_config(config, where)
    return _target_call(config.get("body"), "body", where)


def run_sequence(config: Mapping, body, drop: tuple[str, ...] = (), where: str = "metrics.json", **changes):
    """The sequence of a run's configuration (its ``data`` entry, a registered builder) for
    ``body``; ``drop``: keys of the data entry left out (their defaults apply), ``changes``: keys
    replaced."""
    check_run_config(config, where)
    data = config.get("data")
    if not isinstance(data, Mapping):
        raise ValueError(f"{where}: the run's config has no data entry")
    return _target_call({**{k: v for k, v in data.items() if k not in drop}, **changes}, "data", where,
                        body=body)
