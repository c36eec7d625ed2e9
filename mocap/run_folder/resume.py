"""Resuming a sweep honestly: a run directory counts as complete only when it holds a complete
run (a valid ``manifest.json``: every result file has the size and checksum it lists,
:mod:`mocap.run_folder.manifest`) made by the configuration asked for now.

The resolved configuration a finished run used is stored in its ``metrics.json``
(``"config"``); its thread budget as resolved (``"threads"``: ``auto`` became a number) is
compared with the requested one's resolved budget. Keys that do not change results
(:data:`IGNORED`) are left out of the comparison. Anything else reruns; before it does, an
earlier complete run is moved into ``previous_run/`` (kept until the new run is complete) and
what an incomplete attempt left is removed (:func:`set_aside`), so nothing in the directory
can describe another configuration or pass for the new run.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Mapping
from pathlib import Path

from mocap.run_folder.manifest import MANIFEST, PREVIOUS, manifest_problem, read_manifest
from mocap.safe_files import write_text_atomic

#: top-level keys that do not change a run's results (resume bookkeeping)
IGNORED = ("skip_complete", "resume_on_change")
#: what a run writes; removed before a rerun (a complete run is moved aside instead)
OUTPUTS = (MANIFEST, "motion.npz", "metrics.json", "metrics.json.tmp", "manifest.json.tmp",
           "recording.rrd", "recording.rrd.part", "recording.failed.rrd")
#: the results a complete run keeps in previous_run/
KEPT = (MANIFEST, "motion.npz", "metrics.json", "recording.rrd")


def comparable(config: Mapping, threads: object = None) -> dict:
    """The config without bookkeeping keys; ``threads`` (when given): the resolved budget."""
    out = {k: v for k, v in config.items() if k not in IGNORED}
    if threads is not None:
        out["threads"] = threads
    return out


def _stored(out_dir: Path) -> tuple[Mapping | None, object]:
    """(stored config, resolved thread budget) of the run in ``out_dir``'s metrics.json."""
    metrics = json.loads((Path(out_dir) / "metrics.json").read_text())
    return metrics.get("config"), metrics.get("threads")


def run_state(out_dir: Path, config: Mapping, recording: bool, threads: object = None) -> str:
    """"complete", "missing" (nothing of a run), "incomplete" (an attempt without a valid
    manifest), "corrupt" (a manifest whose files no longer match), "changed" (complete, with
    another config) or "unreadable" (metrics.json cannot be read). config: the requested
    config; threads: its resolved thread budget (None: compare ``threads`` as written)."""
    out_dir = Path(out_dir)
    manifest = read_manifest(out_dir)
    if manifest is None:
        return "incomplete" if any((out_dir / n).exists() for n in OUTPUTS) else "missing"
    if manifest_problem(out_dir) is not None:
        return "corrupt"
    try:
        stored, stored_threads = _stored(out_dir)
    except (OSError, ValueError, AttributeError):
        return "unreadable"
    stored_threads = stored_threads if threads is not None else None
    if not isinstance(stored, Mapping) or comparable(stored, stored_threads) != comparable(config, threads):
        return "changed"
    if recording and "recording.rrd" not in manifest["files"]:
        return "changed"
    return "complete"


def config_changes(out_dir: Path, config: Mapping, threads: object = None) -> list[str]:
    """Dotted keys whose stored value differs from ``config`` (for messages)."""
    try:
        stored, stored_threads = _stored(out_dir)
    except (OSError, ValueError, AttributeError):
        return ["metrics.json"]
    return _diff(comparable(stored or {}, stored_threads if threads is not None else None),
                 comparable(config, threads))


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


def set_aside(out_dir: Path) -> list[str]:
    """Before a run: a complete run in ``out_dir`` moves into ``previous_run/`` (replacing an
    older one there); what an incomplete attempt left is removed. Returns lines to report."""
    out_dir = Path(out_dir)
    notes = []
    if manifest_problem(out_dir) is None:
        prev = out_dir / PREVIOUS
        if prev.exists():
            shutil.rmtree(prev)
        tmp = out_dir / (PREVIOUS + ".tmp")
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        manifest = read_manifest(out_dir) or {}
        for name in KEPT[1:]:
            if name in manifest.get("files", {}):
                (out_dir / name).replace(tmp / name)
        (out_dir / MANIFEST).replace(tmp / MANIFEST)     # the manifest last: complete there, gone here
        tmp.rename(prev)
        notes.append(f"the earlier complete run is kept in {prev} until this one is complete")
    if (out_dir / "recording.rrd.part").exists():
        notes.append("removing recording.rrd.part (the recording of a killed run; it does not verify)")
    removed = clear_outputs(out_dir)
    if removed:
        notes.append(f"removed what an incomplete attempt left: {', '.join(removed)}")
    return notes


def restore_previous(out_dir: Path, config: Mapping, recording: bool, threads: object = None) -> bool:
    """When ``previous_run/`` holds a complete run of ``config`` (an interrupted re-run with
    another setting, now asked for the old one again), move it back into place; True if so."""
    out_dir = Path(out_dir)
    prev = out_dir / PREVIOUS
    if run_state(prev, config, recording, threads) != "complete":
        return False
    clear_outputs(out_dir)
    for name in KEPT[1:]:
        if (prev / name).is_file():
            (prev / name).replace(out_dir / name)
    (prev / MANIFEST).replace(out_dir / MANIFEST)
    shutil.rmtree(prev)
    return True


def drop_previous(out_dir: Path) -> None:
    """After a complete run: the earlier run kept aside is no longer needed."""
    shutil.rmtree(Path(out_dir) / PREVIOUS, ignore_errors=True)


def restore_stored_config(out_dir: Path) -> None:
    """Write the config stored in ``metrics.json`` back to ``.hydra/config.yaml`` and the
    overrides its manifest keeps back to ``.hydra/overrides.yaml`` (Hydra overwrites both with
    the requested ones before the job starts; a run refused for a changed config must leave
    the directory describing the results it holds)."""
    stored = json.loads((Path(out_dir) / "metrics.json").read_text()).get("config")
    manifest = read_manifest(out_dir) or {}
    describe_run(out_dir, stored, manifest.get("overrides"))


def describe_run(out_dir: Path, config: Mapping | None, overrides: list[str] | None) -> None:
    """``.hydra/config.yaml`` = ``config`` and ``.hydra/overrides.yaml`` = ``overrides`` (each
    where given), when the folder has a ``.hydra/``: Hydra writes them as a job starts. A single
    run takes the folder's lock before that (``mocap_cli.hydra_edge.RunFolderLock``: a refused
    one writes nothing there); a --multirun job only as its task starts, so a second process
    refused by the lock has overwritten them (and ``hydra.yaml``) with its own request: the
    holder writes its own back as it seals the run (and a run refused for a changed config
    writes back the stored one)."""
    import yaml

    hydra_dir = Path(out_dir) / ".hydra"
    if not hydra_dir.is_dir():
        return
    if isinstance(config, Mapping):
        write_text_atomic(hydra_dir / "config.yaml", yaml.safe_dump(dict(config), sort_keys=False))
    if overrides is not None:
        write_text_atomic(hydra_dir / "overrides.yaml", yaml.safe_dump(list(overrides)))
