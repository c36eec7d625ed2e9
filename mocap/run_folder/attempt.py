"""One attempt at a run folder, shared by the one-person and the several-people runs: what happens
when tracking fails (the recording closed as failed, no manifest, a line naming the folder, the
exception marked as raised during the work), and the order in which a finished run is sealed
(metrics, recording, then the manifest that makes the folder a complete run)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path

from mocap.run_folder.manifest import write_manifest
from mocap.run_folder.read import write_json
from mocap.run_folder.resume import drop_previous

#: the note added to an exception raised after every check passed (while tracking or writing the
#: outputs): the command line shows such errors with their traceback (mocap_cli/errors.py)
DURING_WORK_NOTE = "mocap: raised while tracking, after every setting and input was checked"


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
    """After motion.npz is written: metrics.json, the recording, and last the manifest."""
    write_json(out_dir / "metrics.json", metrics)
    sink.finish(metrics)
    write_manifest(out_dir, ["motion.npz", "metrics.json", *(["recording.rrd"] if recording else [])],
                   overrides)
