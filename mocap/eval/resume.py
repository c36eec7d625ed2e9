"""Resuming a sweep honestly: a run directory counts as complete only when its results were
made by the configuration asked for now.

The resolved configuration a finished run used is stored in its ``metrics.json``
(``"config"``, written last, atomically). A run is complete when that file exists, its
stored configuration equals the requested one (minus the keys that do not change results,
:data:`IGNORED`), and, when recording, its ``recording.rrd`` exists. Anything else reruns;
before it does, the outputs of an earlier attempt (results, recordings, failed recordings)
are removed, so that nothing in the directory can describe another configuration.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

#: top-level keys that do not change a run's results (resume bookkeeping)
IGNORED = ("skip_complete", "resume_on_change")
#: what a run writes; removed before a rerun
OUTPUTS = ("metrics.json", "metrics.json.tmp", "recording.rrd", "recording.rrd.part",
           "recording.failed.rrd")


def comparable(config: Mapping) -> dict:
    return {k: v for k, v in config.items() if k not in IGNORED}


def run_state(out_dir: Path, config: Mapping, recording: bool) -> str:
    """"complete", "missing" (no finished run), "changed" (finished with another config) or
    "unreadable" (metrics.json cannot be read). config: the resolved requested config."""
    path = Path(out_dir) / "metrics.json"
    if not path.is_file():
        return "missing"
    try:
        stored = json.loads(path.read_text()).get("config")
    except (OSError, ValueError, AttributeError):
        return "unreadable"
    if not isinstance(stored, Mapping) or comparable(stored) != comparable(config):
        return "changed"
    if recording and not (Path(out_dir) / "recording.rrd").is_file():
        return "missing"
    return "complete"


def config_changes(out_dir: Path, config: Mapping, prefix: str = "") -> list[str]:
    """Dotted keys whose stored value differs from ``config`` (for messages)."""
    try:
        stored = json.loads((Path(out_dir) / "metrics.json").read_text()).get("config") or {}
    except (OSError, ValueError):
        return ["metrics.json"]
    return _diff(comparable(stored), comparable(config))


def _diff(a, b, prefix: str = "") -> list[str]:
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        out = []
        for k in sorted(set(a) | set(b), key=str):
            out += _diff(a.get(k), b.get(k), f"{prefix}{k}.")
        return out
    return [] if a == b else [prefix.rstrip(".")]


def clear_outputs(out_dir: Path) -> list[str]:
    """Remove what an earlier attempt wrote (see :data:`OUTPUTS`); returns the names removed."""
    removed = []
    for name in OUTPUTS:
        p = Path(out_dir) / name
        if p.is_file():
            p.unlink()
            removed.append(name)
    return removed


def restore_stored_config(out_dir: Path) -> None:
    """Write the config stored in ``metrics.json`` back to ``.hydra/config.yaml`` (Hydra
    overwrites that file with the requested config before the job starts; a run refused for
    a changed config must leave the directory describing the results it holds)."""
    import yaml

    stored = json.loads((Path(out_dir) / "metrics.json").read_text()).get("config")
    hydra_dir = Path(out_dir) / ".hydra"
    if isinstance(stored, Mapping) and hydra_dir.is_dir():
        (hydra_dir / "config.yaml").write_text(yaml.safe_dump(stored, sort_keys=False))
