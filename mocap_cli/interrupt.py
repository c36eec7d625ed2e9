"""Ctrl-C (SIGINT) honoured at any moment of ``mocap``, start-up included.

Installed first thing when ``mocap`` starts (:mod:`mocap_cli` ``__init__``, before Hydra, numpy
or any other library is imported), the handler ends the process at once (one line, exit code
130) until the command starts (:func:`set_command`); from then on it raises KeyboardInterrupt
in the main thread, which runs the command's clean-up (a run folder is left visibly
incomplete) and which :func:`mocap_cli.main.main` turns into the same line and code.
Two things could still keep a run going: an interrupt raised inside the import machinery can be
dropped ("Exception ignored" in importlib's module-lock callback) or caught and printed by an
extension's own import code, so during an import the handler only records it, and :func:`check`
raises it after the command's module is imported and around every config build;
and native code that never returns to Python (a watchdog thread started by the first signal
ends the process :data:`GRACE_S` seconds later, with the same line, removing the lock files of
the run folders it holds: :func:`mocap.run_folder.lock.drop_files`). A second Ctrl-C ends it at
once. Only a process that runs ``mocap`` as its program installs it (:func:`install`, not on
import by a test or a notebook)."""

from __future__ import annotations

import os
import signal
import sys
import threading

#: seconds between a Ctrl-C and the end of the process when the interrupt does not end it
#: (swallowed, or the main thread stuck in native code); a run's own clean-up fits in it
GRACE_S = 5.0
EXIT_CODE = 130
_state = {"installed": False, "signals": 0, "command": "mocap", "guarded": False}


def _line() -> bytes:
    return f"{_state['command']}: interrupted (Ctrl-C); nothing more is written\n".encode()


def _exit_now() -> None:
    lock = sys.modules.get("mocap.run_folder.lock")      # (never imported here for this)
    if lock is not None:
        lock.drop_files()       # os._exit skips the run folders' clean-up: their lock files go now
    try:
        sys.stdout.flush()
    except Exception:       # noqa: BLE001 (stdout may be closed or broken)
        pass
    os.write(2, _line())
    os._exit(EXIT_CODE)


def _handler(signum, frame) -> None:
    _state["signals"] += 1
    if _state["signals"] > 1 or not _state["guarded"]:
        _exit_now()         # a second Ctrl-C, or one before the command started: nothing to clean up
    timer = threading.Timer(GRACE_S, _exit_now)
    timer.daemon = True
    timer.start()
    if _inside_import(frame):
        return      # raised here it would be printed as "Exception ignored" and lost: check() raises it
    raise KeyboardInterrupt("interrupted")


def _inside_import(frame) -> bool:
    """Whether the main thread is inside the import machinery: there an exception can be dropped
    ("Exception ignored" in importlib's module-lock callback) or caught and printed by an
    extension module's own import code, and the run would go on."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def install() -> None:
    """Take over SIGINT for this process (main thread only; once)."""
    if _state["installed"] or threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGINT, _handler)
    _state["installed"] = True


def is_program() -> bool:
    """Whether this process runs ``mocap`` as its program (console script or ``python -m
    mocap_cli``), judged from argv[0] while the package is imported."""
    arg0 = sys.argv[0] if sys.argv else ""
    return os.path.basename(arg0) == "mocap" or arg0 == "-m" or arg0.endswith(os.path.join("mocap_cli",
                                                                                           "__main__.py"))


def set_command(name: str) -> None:
    """From now on a Ctrl-C raises KeyboardInterrupt (the command's clean-up runs) instead of
    ending the process at once; ``name`` heads the line printed."""
    _state["command"] = name
    _state["guarded"] = True


def interrupted() -> bool:
    return _state["signals"] > 0


def check() -> None:
    """Raise KeyboardInterrupt when a Ctrl-C came and was swallowed (by a library's
    ``except BaseException`` around its imports)."""
    if _state["signals"] > 0:
        raise KeyboardInterrupt("interrupted")
