"""One writer per run folder: an advisory lock (:func:`fcntl.flock`) on ``<run>/.mocap.lock``,
held for the whole run (tracking, resume, sealing) and by ``mocap rescore`` while it rewrites a
run. A second process on the same folder is refused at once, in one line naming the holder (pid,
host, start time, command), instead of mixing its files with the first one's. The operating
system drops the lock when the holder exits, however it exits (a killed run leaves no stale
lock; the holder removes the file when done, a killed one leaves it, unlocked, with its line; a
``mocap`` process ended by its interrupt watchdog removes it first: :func:`drop_files`).
The manifest is written only by the holder
(:func:`require_held`, called by :func:`mocap.run_folder.manifest.write_manifest`).

    with run_lock(out_dir):          # RunFolderBusy when another process holds it
        ...
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path

#: the lock file, inside the run folder
LOCK = ".mocap.lock"
_held: dict[Path, tuple[Path, int]] = {}   # folders this process holds -> (lock file, its descriptor)


class RunFolderBusy(FileExistsError):
    """Another process holds the run folder's lock (the message names it)."""


def _holder(path: Path) -> str:
    try:
        info = json.loads(path.read_text() or "{}")
    except (OSError, ValueError):
        info = {}
    if not isinstance(info, dict) or "pid" not in info:
        return "another process (it has not written its name yet)"
    return (f"pid {info.get('pid')} on {info.get('host')} since {info.get('started')}"
            f" ({str(info.get('command', ''))[:120]})")


@contextlib.contextmanager
def run_lock(out_dir: str | os.PathLike) -> Iterator[Path]:
    """Hold ``out_dir``'s lock inside the block (the folder is made if missing); re-entrant in
    one process. :class:`RunFolderBusy` (one line naming the holder) when another holds it."""
    out_dir = Path(out_dir)
    key = out_dir.resolve()
    if key in _held:
        yield out_dir / LOCK
        return
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / LOCK
    fd = _acquire(out_dir, path)
    try:
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "command": " ".join(sys.argv)[:500]}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(info).encode(), 0)
        _held[key] = (path, fd)
        yield path
    finally:
        _held.pop(key, None)
        with contextlib.suppress(OSError):
            path.unlink()     # while still held: a waiting process then sees another file (below)
        os.close(fd)          # releases the lock


def _acquire(out_dir: Path, path: Path) -> int:
    """The lock file's descriptor, locked. The file is removed by its holder when done, so a
    lock taken on a file that is no longer the one at ``path`` is let go and taken again."""
    for _ in range(100):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise RunFolderBusy(f"{path} is a symbolic link: not a run folder mocap wrote; "
                                    "refused") from None
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise RunFolderBusy(f"{out_dir}: another mocap process is writing this run folder "
                                f"({_holder(path)}); refused (wait for it, or choose another "
                                "folder)") from None
        except BaseException:
            os.close(fd)
            raise
        try:
            same = os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)            # the holder before us removed it as we locked it: again
    raise RunFolderBusy(f"{path}: the lock file keeps changing; refused")


def drop_files() -> None:
    """Remove the lock files of every folder this process holds, the locks kept: for a process
    about to end without running its clean-up (``os._exit``: the interrupt watchdog of
    :mod:`mocap_cli.interrupt`), which would leave them behind, unlocked. A file that is no
    longer the one this process locked (its block already ended) is left alone. Safe from
    another thread than the one holding the locks."""
    for path, fd in list(_held.values()):
        with contextlib.suppress(OSError):
            if os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino:
                path.unlink()


def holds(out_dir: str | os.PathLike) -> bool:
    """Whether this process holds ``out_dir``'s lock."""
    return Path(out_dir).resolve() in _held


def require_held(out_dir: str | os.PathLike) -> None:
    """Refuse (:class:`RunFolderBusy`) to seal ``out_dir`` when another process holds its lock
    (a folder nobody locks, e.g. one written by a test or an older mocap, is let through)."""
    out_dir = Path(out_dir)
    if holds(out_dir) or not (out_dir / LOCK).is_file():
        return
    try:
        fd = os.open(out_dir / LOCK, os.O_RDONLY | os.O_CLOEXEC | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        raise RunFolderBusy(f"{out_dir}: another mocap process is writing this run folder "
                            f"({_holder(out_dir / LOCK)}); its manifest is not written by this one") from None
    finally:
        os.close(fd)
