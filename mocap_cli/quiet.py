"""What a command prints besides its own lines: warnings once per cause on one line, native
libraries' logs (TensorFlow Lite, absl) out of the terminal, the printed lines of a Hydra job in its
log file. ``mocap --debug`` (:func:`debug`) keeps Python's own warning format and the native logs.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

#: set by ``mocap --debug`` (mocap_cli/main.py); read by the commands
DEBUG_ENV = "MOCAP_DEBUG"


def debug() -> bool:
    return bool(os.environ.get(DEBUG_ENV))


def one_line_warnings() -> None:
    """Warnings as ``warning: <message> (<Category>)`` on stderr, each cause (category and text)
    once per process, without the source line Python's format adds."""
    seen: set[tuple[type, str]] = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = " ".join(str(message).split())
        if (category, text) in seen:
            return
        seen.add((category, text))
        stream = file if file is not None else sys.stderr
        with contextlib.suppress(OSError, ValueError):
            stream.write(f"warning: {text} ({category.__name__})\n")

    warnings.showwarning = show         # the filters stay Python's (deprecations of libraries hidden)


@contextlib.contextmanager
def native_logs_to(path: str | Path | None) -> Iterator[None]:
    """Inside the block what native code writes to file descriptor 2 (TensorFlow Lite's INFO line,
    absl's W0000 lines) goes to ``path`` (None: nowhere); Python's sys.stderr (progress bars,
    warnings, errors) still reaches the terminal through a copy of the descriptor."""
    sys.stderr.flush()
    saved = os.dup(2)
    target = os.open(os.devnull if path is None else str(path), os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    old_stderr = sys.stderr
    sys.stderr = io.TextIOWrapper(os.fdopen(os.dup(saved), "wb", buffering=0), encoding=old_stderr.encoding,
                                  errors="backslashreplace", line_buffering=True, write_through=True)
    os.dup2(target, 2)
    os.close(target)
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        sys.stderr.close()
        sys.stderr = old_stderr


class _LogTee(io.TextIOBase):
    """A text stream that writes through to ``stream`` and hands each complete line (the last
    state of a progress bar's carriage-return updates) to ``handlers``."""

    def __init__(self, stream, handlers: list[logging.Handler], level: int):
        self.stream, self.handlers, self.level = stream, handlers, level
        self.pending = ""

    def write(self, text: str) -> int:
        n = self.stream.write(text)
        self.pending += text
        *lines, self.pending = self.pending.split("\n")
        for line in lines:
            line = next((seg.rstrip() for seg in reversed(line.split("\r")) if seg.strip()), "")
            if line:
                level = logging.WARNING if line.lower().startswith(("warning", "error")) else self.level
                record = logging.LogRecord("mocap", level, "", 0, line, None, None)
                for h in self.handlers:
                    h.handle(record)
        return n

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:
        return self.stream.isatty()

    @property
    def encoding(self):
        return getattr(self.stream, "encoding", "utf-8")

    def fileno(self) -> int:
        return self.stream.fileno()

    def __getattr__(self, name):            # buffer, errors, ...: the wrapped stream's
        return getattr(self.stream, name)


@contextlib.contextmanager
def printed_lines_logged() -> Iterator[None]:
    """Inside a Hydra job: every line printed to stdout or stderr (a progress bar: its last state)
    also goes to the job's log file (track.log, video_check.log, recovery.log, ...) through Hydra's
    file handler; warnings and errors at WARNING, the rest at INFO."""
    handlers = [h for h in logging.getLogger().handlers if isinstance(h, logging.FileHandler)]
    if not handlers:
        yield
        return
    out, err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _LogTee(out, handlers, logging.INFO), _LogTee(err, handlers, logging.INFO)
    try:
        yield
    finally:
        sys.stdout, sys.stderr = out, err
