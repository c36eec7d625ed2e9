"""Start-up (issue 38): ``mocap --help``, an unknown command and the argument errors and help of the
commands that take flags import none of the numeric stack (numpy, OpenCV, numba, scipy) nor Hydra,
Rerun or matplotlib: a command imports what it needs once its arguments are read. Checked in a
fresh interpreter (this one has them all loaded)."""

import json
import subprocess
import sys

import pytest

HEAVY = ("numpy", "cv2", "numba", "scipy", "hydra", "omegaconf", "rerun", "matplotlib")

#: the commands that take flags (the Hydra commands compose their configs, settings classes included)
FLAG_COMMANDS = ["replay", "export", "ablate", "detect", "rescore", "train-prior", "build-body-model",
                 "show-body"]


def imported_by(argv: list[str]) -> tuple[int, list[str]]:
    """(exit status, the HEAVY modules loaded) of ``mocap <argv>`` in a new interpreter."""
    code = ("import contextlib, io, json, sys\n"
            "from mocap_cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n"
            "    try:\n"
            f"        rc = main({argv!r})\n"
            "    except SystemExit as exc:\n"
            "        rc = exc.code\n"
            f"print(json.dumps([rc, sorted(m for m in {HEAVY!r} if m in sys.modules)]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    rc, loaded = json.loads(r.stdout.strip().splitlines()[-1])
    return rc, loaded


@pytest.mark.parametrize("argv, status", [(["--help"], 0), ([], 2), (["no-such-command"], 2),
                                          (["export"], 2), (["export", "--bogus"], 2),
                                          (["export", "/no/such/run", "--format", "fbx"], 2)],
                         ids=["help", "nothing", "unknown-command", "missing-args", "unknown-flag",
                              "bad-format"])
def test_help_and_argument_errors_import_no_numeric_stack(argv, status):
    assert imported_by(argv) == (status, [])


@pytest.mark.parametrize("command", FLAG_COMMANDS)
def test_a_flag_commands_help_and_bad_flag_import_no_numeric_stack(command):
    assert imported_by([command, "--help"]) == (0, [])
    assert imported_by([command, "--no-such-flag"]) == (2, [])
