"""A run folder is complete or visibly not: ``manifest.json``, written last and atomically,
lists the size and SHA-256 of every result file of the run (``motion.npz``, ``metrics.json``
and, when recording, ``recording.rrd``). A folder without it, or whose files no longer match
it, is not a complete run: ``mocap export``, ``rescore``, ``replay`` and ``ablate`` refuse or
flag it (:func:`require_complete`).

    manifest.json   {"format": "mocap-run-v1", "files": {name: {"bytes": n, "sha256": hex}},
                     "overrides": [the command line's overrides], "written": ISO time}

A re-run first moves an earlier complete run into ``previous_run/`` (:data:`PREVIOUS`) with
its manifest; it is removed once the new run is complete, and kept (complete, verifiable)
when the new run fails, is interrupted or killed. A resumed sweep takes it back when it is
the configuration asked for (:func:`mocap.run_folder.resume.restore_previous`).
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

from mocap.run_folder.read import write_json
from mocap.safe_files import check_name, name_problem

FORMAT = "mocap-run-v1"
MANIFEST = "manifest.json"
#: where a re-run keeps the earlier complete run until the new one is complete
PREVIOUS = "previous_run"
#: result files of a run, in the order they are written
RESULTS = ("motion.npz", "metrics.json", "recording.rrd")


class IncompleteRunError(ValueError):
    """A run folder without a valid manifest (interrupted, failed, killed or altered)."""


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_manifest(run_dir: str | Path, files: list[str], overrides: list[str] | None = None) -> dict:
    """Checksum ``files`` of ``run_dir`` and write manifest.json (atomically, last)."""
    from mocap.run_folder.lock import require_held

    run_dir = Path(run_dir)
    require_held(run_dir)           # only the process holding the folder's lock seals it
    for name in files:
        check_name(name, "result file", run_dir / MANIFEST)
    manifest = {"format": FORMAT,
                "files": {name: {"bytes": (run_dir / name).stat().st_size, "sha256": sha256(run_dir / name)}
                          for name in files},
                "overrides": list(overrides or []),
                "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    write_json(run_dir / MANIFEST, manifest)
    return manifest


def read_manifest(run_dir: str | Path) -> dict | None:
    """The manifest of ``run_dir`` (None: none, or not a readable manifest)."""
    path = Path(run_dir) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT \
            or not isinstance(manifest.get("files"), dict):
        return None
    return manifest


def manifest_problem(run_dir: str | Path) -> str | None:
    """Why ``run_dir`` is not a complete run (None: its manifest is valid and every file
    it lists has the size and checksum it records)."""
    run_dir = Path(run_dir)
    manifest = read_manifest(run_dir)
    if manifest is None:
        if (run_dir / MANIFEST).exists():
            return f"{MANIFEST} is unreadable"
        why = f"no {MANIFEST}: the run was interrupted, failed or is still running"
        if read_manifest(run_dir / PREVIOUS) is not None:
            why += f"; the last complete run is kept in {PREVIOUS}/"
        return why
    for name in manifest["files"]:
        if name_problem(name) is not None or not isinstance(manifest["files"][name], dict):
            return f"{MANIFEST} lists {str(name)[:240]!r}, not a plain file name of the folder"
    if "metrics.json" not in manifest["files"]:
        return f"{MANIFEST} does not list metrics.json"
    for name in RESULTS:
        if name not in manifest["files"] and (run_dir / name).exists():
            return f"{name} is not listed in {MANIFEST} (written after the run)"
    for name, entry in manifest["files"].items():
        path = run_dir / name
        if path.is_symlink():
            return f"{name} is a symbolic link (a run's files are plain files of its folder)"
        if not path.is_file():
            return f"{name} is missing (listed in {MANIFEST})"
        if path.stat().st_size != entry.get("bytes"):
            return f"{name} has {path.stat().st_size} bytes, {MANIFEST} says {entry.get('bytes')}"
        if sha256(path) != entry.get("sha256"):
            return f"{name} does not match its checksum in {MANIFEST} (changed after the run)"
    return None


def require_complete(run_dir: str | Path) -> None:
    """Raise :class:`IncompleteRunError` (one line, naming the folder and why) unless
    ``run_dir`` holds a complete run."""
    problem = manifest_problem(run_dir)
    if problem is not None:
        raise IncompleteRunError(f"{run_dir}: not a complete run ({problem})")
