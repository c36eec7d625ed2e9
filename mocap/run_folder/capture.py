"""``mocap capture``'s stage plan: one output folder, one sub-folder per stage, and
``capture.json`` recording what each finished stage was run with.

    DIR/capture.json        {"format": "mocap-capture-v1", "stages": {name: {"settings": ...,
                             "seconds": ..., "outputs": [...]}}, "summary": {...}}
    DIR/calibrate/ DIR/detect/ DIR/track/ DIR/export/

A stage is skipped when its record holds the same settings and its outputs exist; a stage that
runs invalidates every stage after it (their records are dropped, in the file, before it starts:
an interrupted stage leaves no record that a later run could trust). Plain values in, no work
done here: :mod:`mocap_cli.commands.capture` runs the stages.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mocap.run_folder.lock import LOCK
from mocap.safe_files import write_text_atomic

FORMAT = "mocap-capture-v1"
RECORD = "capture.json"


@dataclass(frozen=True)
class Stage:
    """One stage: its name (also its sub-folder), the settings its outputs depend on (plain
    JSON values) and the files (relative to the capture folder) that must exist once it is done."""

    name: str
    settings: dict
    outputs: tuple[str, ...] = field(default_factory=tuple)


def check_capture_folder(out: str | Path) -> dict:
    """The record of an existing capture folder (``{}`` for a new or empty folder); raises
    FileExistsError (one line) for a file, or a non-empty folder ``mocap capture`` did not write."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"output {out} is a file: choose another --out")
    if not out.is_dir() or not any(p.name != LOCK for p in out.iterdir()):
        return {}           # (a lock file alone: a capture killed before its first stage)
    head = out / RECORD
    if not head.is_file():
        raise FileExistsError(f"output {out} is not empty and was not written by mocap capture "
                              f"(no {RECORD}): choose another --out")
    try:
        record = json.loads(head.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise FileExistsError(f"{head}: unreadable ({exc}): remove it to start the capture again") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise FileExistsError(f"{head}: not a {FORMAT} record: choose another --out")
    record.setdefault("stages", {})
    return record


def _plain(value):
    """Settings as JSON would read them back (tuples as lists), so that records compare equal."""
    return json.loads(json.dumps(value))


def stages_to_run(out: str | Path, record: dict, stages: Sequence[Stage],
                  invalid: Mapping[str, bool] | None = None) -> list[bool]:
    """Per stage, whether it must run: its record is missing or holds other settings, one of its
    outputs is missing, ``invalid[name]`` says its outputs do not verify, or a stage before it
    runs."""
    out = Path(out)
    done = record.get("stages", {})
    run, dirty = [], False
    for stage in stages:
        rec = done.get(stage.name)
        same = (isinstance(rec, dict) and rec.get("settings") == _plain(stage.settings)
                and all((out / o).exists() for o in rec.get("outputs", stage.outputs)))
        dirty = dirty or not same or bool((invalid or {}).get(stage.name))
        run.append(dirty)
    return run


def changed_settings(record: dict, stage: Stage) -> list[str]:
    """The settings of ``stage`` that differ from its record (all of them when there is none)."""
    old = (record.get("stages", {}).get(stage.name) or {}).get("settings") or {}
    new = _plain(stage.settings)
    return sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))


def write_record(out: str | Path, record: dict) -> None:
    write_text_atomic(Path(out) / RECORD, json.dumps({**record, "format": FORMAT}, indent=1))


def start_stage(out: str | Path, record: dict, stages: Sequence[Stage], index: int) -> dict:
    """Drop the records of stage ``index`` and every later one, write the file; the new record."""
    names = {s.name for s in stages[index:]}
    record = {**record, "format": FORMAT,
              "stages": {k: v for k, v in record.get("stages", {}).items() if k not in names}}
    record.pop("summary", None)
    write_record(out, record)
    return record


def finish_stage(out: str | Path, record: dict, stage: Stage, seconds: float,
                 outputs: Sequence[str] | None = None, **extra) -> dict:
    """Record ``stage`` as done (its settings, wall time, outputs), written atomically."""
    entry = {"settings": _plain(stage.settings), "seconds": round(float(seconds), 3),
             "outputs": list(stage.outputs if outputs is None else outputs), **extra}
    record = {**record, "format": FORMAT, "stages": {**record.get("stages", {}), stage.name: entry}}
    write_record(out, record)
    return record
