"""``mocap <args>`` run in the test's own process: :func:`mocap_cli.main.main`, the entry point's
own function (what the console script runs), without a new interpreter importing the numeric
stack and loading the compiled kernels again (~2.5 CPU s a ``mocap track``). For the tests where
what a command writes and prints is the point, not how it behaves as a process (signals, exit
by ``os._exit``, the console script itself): those keep a real process."""

from __future__ import annotations

import contextlib
import io
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def mocap(*args: str | Path, cwd: Path = REPO) -> subprocess.CompletedProcess:
    """``mocap *args`` from ``cwd`` (default: the checkout's root), its exit code, stdout and
    stderr as :func:`subprocess.run` would give them."""
    from mocap_cli.main import main

    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:           # Hydra's own errors exit
            code = exc.code if isinstance(exc.code, int) else 1
    return subprocess.CompletedProcess(argv, code, out.getvalue(), err.getvalue())
