"""Start-up (issue 38): ``mocap --help``, an unknown command and the argument errors and help of
every command that takes flags import none of the numeric stack (numpy, OpenCV, numba, scipy) nor
Hydra, Rerun or matplotlib: a command imports what it needs once its arguments are read. The Hydra
commands' (``mocap track``, ``recovery``, ...) help and override errors compose their configs
(Hydra), the tracker presets' settings included, and still import none of the numeric stack.
Checked in a fresh interpreter (this one has them all loaded)."""

import json
import subprocess
import sys

import pytest

HEAVY = ("numpy", "cv2", "numba", "scipy", "hydra", "omegaconf", "rerun", "matplotlib")
NUMERIC = ("numpy", "cv2", "numba", "scipy")

#: the commands that take flags
FLAG_COMMANDS = ["replay", "export", "ablate", "detect", "rescore", "train-prior", "build-body-model",
                 "show-body", "calibrate", "capture", "convert", "gt-from-joints", "import-motion"]
#: the commands that take Hydra overrides (they compose their configs, settings classes included)
HYDRA_COMMANDS = ["track", "recovery", "make-dataset", "segment", "video-check"]


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


def test_every_command_is_checked():
    from mocap_cli.main import COMMANDS

    assert sorted(FLAG_COMMANDS + HYDRA_COMMANDS) == sorted(COMMANDS)


@pytest.mark.parametrize("command", FLAG_COMMANDS)
def test_a_flag_commands_help_and_bad_flag_import_no_numeric_stack(command):
    assert imported_by([command, "--help"]) == (0, [])
    assert imported_by([command, "--no-such-flag"]) == (2, [])


def test_import_motions_unit_choices_are_the_bvh_readers_units():
    from mocap.clips.bvh import UNITS
    from mocap_cli.commands.import_motion import UNIT_NAMES

    assert list(UNIT_NAMES) == sorted(UNITS)


@pytest.mark.parametrize("command", ["replay", "ablate"])
def test_a_run_or_sweep_folder_that_does_not_exist_imports_no_numeric_stack(command):
    assert imported_by([command, "/no/such/folder"]) == (2, [])


@pytest.mark.parametrize("command", sorted(set(HYDRA_COMMANDS) - {"track"}))   # track: below
def test_a_hydra_commands_help_and_unknown_key_import_no_numeric_stack(command):
    for argv, status in (([command, "--help"], 0), ([command, "bogus=1"], 2)):
        rc, loaded = imported_by(argv)
        assert (rc, [m for m in loaded if m in NUMERIC]) == (status, []), argv


def imported_by_code(code: str) -> list[str]:
    """The NUMERIC modules loaded by running ``code`` in a new interpreter."""
    code += f"\nimport json, sys\nprint(json.dumps(sorted(m for m in {NUMERIC!r} if m in sys.modules)))\n"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv, status", [(["track", "--help"], 0), (["track", "bogus=1"], 2),
                                          (["track", "tracker.partcles=3"], 2),
                                          (["track", "tracker=nope"], 2)],
                         ids=["help", "unknown-key", "unknown-tracker-key", "unknown-tracker"])
def test_track_help_and_override_errors_import_no_numeric_stack(argv, status):
    rc, loaded = imported_by(argv)
    assert (rc, [m for m in loaded if m in NUMERIC]) == (status, [])


def test_track_help_lists_every_tracker_preset():
    from mocap.trackers.presets import PRESETS

    r = subprocess.run([sys.executable, "-m", "mocap_cli", "track", "--help"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    listed = " ".join(r.stdout.split()).split("tracker= ", 1)[1].split(" data=")[0]
    assert sorted(n.strip() for n in listed.split(",")) == sorted(PRESETS)


@pytest.mark.parametrize("module", ["mocap.trackers.presets", "mocap.trackers.tracker_settings",
                                    "mocap.trackers.markers.settings", "mocap_cli.conf_schema"])
def test_the_settings_and_presets_import_no_numeric_stack(module):
    assert imported_by_code(f"import {module}") == []
