"""One attempt at a run folder, shared by the one-person and the several-people runs: what happens
when tracking fails (the recording closed as failed, no manifest, a line naming the folder, the
exception marked as raised during the work), and the order in which a finished run is sealed
(metrics, recording, then the manifest that makes the folder a complete run)."""

from __future__ import annotations

import contextlib
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path

from mocap.run_folder.lock import run_lock
from mocap.run_folder.manifest import manifest_problem, write_manifest
from mocap.run_folder.read import write_json
from mocap.run_folder.resume import PREVIOUS, describe_run, drop_previous
from mocap.safe_files import name_problem, remove_temporaries

#: the note added to an exception raised after every check passed (while tracking or writing the
#: outputs): the command line shows such errors with their traceback (mocap_cli/errors.py)
DURING_WORK_NOTE = "mocap: raised while tracking, after every setting and input was checked"


def tidy_leftovers(out_dir: Path) -> list[str]:
    """What an interrupted or killed run left, put right before the next one starts (under the
    folder's lock): temporary files removed; a run caught half way into ``previous_run.tmp/``
    moved back into the folder (it is complete again, and resume can restore or skip it); a
    ``previous_run/`` beside a complete newer run dropped. Returns lines to report."""
    out_dir = Path(out_dir)
    notes = []
    removed = remove_temporaries(out_dir)
    if removed:
        notes.append(f"{out_dir}: removed temporary files of an interrupted run: {', '.join(removed)}")
    half = out_dir / (PREVIOUS + ".tmp")
    if half.is_dir() and not half.is_symlink():
        back = []
        for p in sorted(half.iterdir()):
            if name_problem(p.name) is None and p.is_file() and not p.is_symlink() \
                    and not (out_dir / p.name).exists():
                p.replace(out_dir / p.name)
                back.append(p.name)
        shutil.rmtree(half, ignore_errors=True)
        if back:
            notes.append(f"{out_dir}: moved back {', '.join(back)} from {half.name}/ (a run interrupted "
                         "while setting the earlier one aside)")
    if (out_dir / PREVIOUS).is_dir() and manifest_problem(out_dir) is None:
        drop_previous(out_dir)
        notes.append(f"{out_dir}: dropped {PREVIOUS}/ (the run beside it is complete and newer)")
    return notes


@contextlib.contextmanager
def own_run_folder(out_dir: str | Path) -> Iterator[None]:
    """Hold the run folder's lock (:func:`mocap.run_folder.lock.run_lock`; a second process is
    refused in one line) for the whole block, after putting right what an interrupted run left
    (:func:`tidy_leftovers`)."""
    with run_lock(out_dir):
        for note in tidy_leftovers(Path(out_dir)):
            print(note, file=sys.stderr)
        yield


@contextlib.contextmanager
def run_attempt(out_dir: Path, sink) -> Iterator[None]:
    """Track inside this block. On any exception the recording is closed as failed, a line says
    the folder is not complete (and where an earlier complete run is kept), and the exception goes
    on, marked with :data:`DURING_WORK_NOTE` unless it is an OSError (disk full, permissions: the
    user's to fix, shown in one line). On success the earlier run kept in previous_run/ is dropped."""
    try:
        yield
    except BaseException as exc:
        if isinstance(exc, Exception) and not isinstance(exc, OSError):
            exc.add_note(DURING_WORK_NOTE)
        sink.finish(None, failed=True)
        kept = (" (the earlier complete run is kept in previous_run/)"
                if (out_dir / "previous_run").is_dir() else "")
        print(f"{out_dir}: not complete, no manifest.json written ({type(exc).__name__}){kept}",
              file=sys.stderr)
        raise
    drop_previous(out_dir)


def seal_run(out_dir: Path, sink, metrics: dict, recording: bool, overrides) -> None:
    """After motion.npz is written: metrics.json, the recording, and last the manifest (and the
    folder's ``.hydra/`` describing this run, whatever a refused process wrote there)."""
    write_json(out_dir / "metrics.json", metrics)
    describe_run(out_dir, metrics.get("config"), overrides)
    sink.finish(metrics)
    write_manifest(out_dir, ["motion.npz", "metrics.json", *(["recording.rrd"] if recording else [])],
                   overrides)
