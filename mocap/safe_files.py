"""Files from others are data, and what is written stays where it belongs.

* :func:`check_name`: a camera, view, person or label name read from a file (a calibration, a
  ``sequence.json``, ``detections.json``, a manifest) becomes a path part only when it is one
  plain path component: no separator, not ``.`` / ``..``, not absolute, no leading dot, at most
  :data:`MAX_NAME` characters of letters, digits and ``_ - . + ( ) @ =`` and inner spaces.
  Otherwise :class:`UnsafeNameError`, one line naming the file and the name.
* :func:`inside`: a path that is about to be written or deleted, checked to resolve (symlinks
  followed) inside its output folder.
* :func:`temporary_beside` / :func:`write_text_atomic` / :func:`write_npz_atomic`: a file is
  written under an unpredictable name created exclusively in its own folder
  (:func:`tempfile.mkstemp`: ``O_CREAT | O_EXCL``, so a planted file or symlink of that name is
  never followed) and renamed over the target.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path

#: the longest name accepted as a path component
MAX_NAME = 128
_NAME = re.compile(r"[\w\-+()@=]([\w\-+.()@= ]*[\w\-+.()@=])?")


class UnsafeNameError(ValueError):
    """A name from a file that cannot safely become a path component, or a path that leaves
    its output folder."""


def name_problem(name: object) -> str | None:
    """Why ``name`` is not a plain path component (None: it is one)."""
    if not isinstance(name, str):
        return f"is a {type(name).__name__}, not a string"
    if not name:
        return "is empty"
    if len(name) > MAX_NAME:
        return f"is {len(name)} characters long (at most {MAX_NAME})"
    if "/" in name or "\\" in name or "\0" in name:
        return "holds a path separator"
    if name in (".", ".."):
        return "is a relative folder"
    if name.startswith("."):
        return "starts with a dot"
    if not _NAME.fullmatch(name):
        return "holds characters other than letters, digits, spaces inside and _ - . + ( ) @ ="
    return None


def check_name(name: object, what: str, source: str | os.PathLike) -> str:
    """``name`` when it is one plain path component; else :class:`UnsafeNameError` naming
    ``source`` (the file it came from) and ``what`` it is (``"camera name"``...)."""
    problem = name_problem(name)
    if problem is not None:
        shown = repr(name)[:80] if isinstance(name, str) else type(name).__name__
        raise UnsafeNameError(f"{source}: {what} {shown} {problem}; refused (names become file names)")
    return name


def check_names(names, what: str, source: str | os.PathLike) -> list[str]:
    """:func:`check_name` of each, and no two the same (they would share a file)."""
    out = [check_name(n, what, source) for n in names]
    seen = set()
    for n in out:
        if n in seen:
            raise UnsafeNameError(f"{source}: {what} {n!r} appears twice; refused")
        seen.add(n)
    return out


def inside(path: str | os.PathLike, root: str | os.PathLike, action: str = "write") -> Path:
    """``path`` when it resolves (symlinks followed) inside ``root``; else
    :class:`UnsafeNameError` (one line) before the ``action`` is done."""
    path, root = Path(path), Path(root)
    resolved, base = path.resolve(), root.resolve()
    if resolved != base and base not in resolved.parents:
        raise UnsafeNameError(f"{path}: outside its output folder {root}; refused to {action} it")
    return path


@contextlib.contextmanager
def temporary_beside(path: str | os.PathLike, suffix: str = ".tmp") -> Iterator[Path]:
    """A new empty file of an unpredictable name in ``path``'s folder (``.<name>.<random><suffix>``,
    created exclusively); yields its path, removed afterwards unless it was renamed away."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file renamed over it (never half written,
    never through a planted symlink)."""
    path = Path(path)
    with temporary_beside(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0))
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """:func:`write_bytes_atomic` of ``text`` (UTF-8)."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_npz_atomic(path: str | os.PathLike, arrays: Mapping[str, object],
                     compress: bool = True) -> Path:
    """``np.savez_compressed`` (``np.savez`` when not ``compress``) of ``arrays`` to ``path``
    through :func:`temporary_beside`: synced, then renamed over ``path`` (a failed write leaves
    no file that looks complete, and no predictable name is ever written through)."""
    import numpy as np  # here: this module is imported by commands that must start without numpy

    path = Path(path)
    save = np.savez_compressed if compress else np.savez
    with temporary_beside(path, suffix=".tmp") as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0))
        with os.fdopen(fd, "wb") as fh:
            save(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    return path


#: patterns of temporary files a killed run leaves in a folder (removed at the next start)
TEMPORARY_PATTERNS = (".*.tmp", ".*.tmp.npz", "*.json.tmp")


def remove_temporaries(folder: str | os.PathLike) -> list[str]:
    """Remove the temporary files (:data:`TEMPORARY_PATTERNS`) a killed writer left directly in
    ``folder``; returns their names. Only regular files (never a link's target)."""
    folder = Path(folder)
    removed = []
    for pattern in TEMPORARY_PATTERNS:
        for p in sorted(folder.glob(pattern)):
            if p.is_symlink() or p.is_file():
                p.unlink(missing_ok=True)
                removed.append(p.name)
    return removed
