"""What a person reads (issue 37): an unknown setting gets a did-you-mean; a warning is one line,
once per cause, without Python's source line; native libraries' writes to file descriptor 2 go
to a log file while Python's own stderr still reaches the terminal; a run's track.log holds what
the run printed."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from mocap_cli.quiet import native_logs_to, one_line_warnings

REPO = Path(__file__).resolve().parents[2]


def mocap(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocap_cli", *args], capture_output=True, text=True,
                          cwd=REPO, timeout=600, env={**os.environ, "TQDM_DISABLE": "1"})


@pytest.mark.parametrize(("override", "suggestion"), [
    ("frame=3", "did you mean frames?"),
    ("tracker.particle=3", "did you mean tracker.particles"),
    ("trackr=apf", "did you mean tracker?"),
])
def test_an_unknown_setting_gets_a_did_you_mean(override, suggestion):
    r = mocap("track", override)
    key = override.split("=")[0]
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"mocap track: error: unknown setting {key!r} ({suggestion}")
    assert "`mocap track --cfg job` lists the settings" in r.stderr and "+" + key not in r.stderr


def test_an_unknown_setting_without_a_close_one_names_where_the_settings_are():
    r = mocap("track", "zzzz=1")
    assert r.returncode == 2
    assert r.stderr.strip() == ("mocap track: error: unknown setting 'zzzz'; `mocap track --cfg job` "
                                "lists the settings")


def test_an_unknown_option_of_a_flag_command_gets_a_did_you_mean(tmp_path):
    r = mocap("convert", str(tmp_path), str(tmp_path / "out"), "--fsp", "60")
    assert r.returncode == 2
    assert r.stderr.strip() == ("mocap convert: error: unrecognized arguments: --fsp 60; did you mean "
                                "--fps? (mocap convert --help)")


def test_track_help_is_short_with_the_full_config_one_flag_away():
    r = mocap("track", "--help")
    lines = r.stdout.strip().splitlines()
    assert r.returncode == 0 and len(lines) <= 30          # Hydra's own: 254 lines of config
    assert lines[0].startswith("``mocap track``: track a sequence")
    assert any(line.startswith("tracker=  apf,") for line in lines)
    assert "mocap track --cfg job" in r.stdout and "init.mode=auto" in r.stdout


def emit(text: str, category=UserWarning):
    warnings.warn(text, category, stacklevel=1)


def test_each_warning_is_one_line_once_per_cause(capsys):
    with warnings.catch_warnings():         # restores showwarning and the filters
        one_line_warnings()
        for _ in range(3):
            emit("camera 'a': padded")                      # one cause, from a loop
        warnings.warn("camera 'a': padded", UserWarning, stacklevel=1)     # the same cause, another line
        emit("camera 'b': padded")                          # another cause
        emit("camera 'a': padded", RuntimeWarning)          # another category: another cause
    err = capsys.readouterr().err.splitlines()
    assert err == ["warning: camera 'a': padded (UserWarning)", "warning: camera 'b': padded (UserWarning)",
                   "warning: camera 'a': padded (RuntimeWarning)"]


def test_native_writes_go_to_the_log_and_python_stderr_to_the_terminal(tmp_path, capfd):
    log = tmp_path / "native.log"
    with native_logs_to(log):
        os.write(2, b"W0000 absl line\n")                   # what a C++ library writes
        print("progress", file=sys.stderr)
    os.write(2, b"after\n")
    err = capfd.readouterr().err
    assert "progress" in err and "after" in err and "absl" not in err
    assert log.read_text() == "W0000 absl line\n"


@pytest.mark.slow
def test_track_log_holds_what_the_run_printed(tmp_path):
    r = mocap("track", f"hydra.run.dir={tmp_path}", "tracker=apf", "data=walk_small", "frames=2",
              "tracker.particles=4", "tracker.layers=2", "recording.enabled=false")
    assert r.returncode == 0, r.stderr[-3000:]
    summary = r.stdout.strip().splitlines()[-1]
    assert summary.startswith("apf: MPJPE") and str(tmp_path) in summary
    log = (tmp_path / "track.log").read_text()
    assert f"[INFO] - {summary}" in log


def test_outside_pytest_a_cause_shows_once_and_library_deprecations_stay_hidden():
    code = ("import warnings\nfrom mocap_cli.quiet import one_line_warnings\none_line_warnings()\n"
            "warnings.warn('old api', PendingDeprecationWarning)\n"
            "for i in range(3):\n    warnings.warn('padded')\nwarnings.warn('padded')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60,
                       env={k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"})
    assert r.returncode == 0 and r.stderr == "warning: padded (UserWarning)\n"
