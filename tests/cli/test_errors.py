"""Bad input at the command line (issue 23): an unknown command, an unknown tracker key and an
out-of-range value each give one line ``mocap <command>: error: ...`` and exit 2, without a
traceback; ``--debug`` (or HYDRA_FULL_ERROR=1) shows the traceback; a programming error always
does."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from hydra.errors import ConfigCompositionException, InstantiationException, MissingConfigException
from omegaconf.errors import ConfigKeyError

from mocap_cli.errors import user_error_message
from mocap_cli.main import COMMANDS, main

ENV = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"} | {"OPENBLAS_NUM_THREADS": "1"}


def mocap(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocap_cli", *args], capture_output=True, text=True,
                          timeout=300, env=env or ENV)


def lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def test_unknown_command_one_line_and_the_command_list():
    r = mocap("trak", "tracker=hybrid")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    (line,) = lines(r.stderr)
    assert line.startswith("mocap: error: unknown command 'trak'") and "track" in line


def test_help_lists_every_command_with_one_line():
    r = mocap("--help")
    assert r.returncode == 0
    listed = {line.split()[0]: line for line in r.stdout.splitlines() if line.startswith("  ")}
    for name, (_, text) in COMMANDS.items():
        assert text in listed[name], name


def test_unknown_tracker_key_one_line(tmp_path):
    r = mocap("track", "tracker=apf", "tracker.no_such_key=1", f"hydra.run.dir={tmp_path}")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    (line,) = lines(r.stderr)
    assert line.startswith("mocap track: error:") and "tracker.no_such_key" in line
    assert not (tmp_path / "metrics.json").exists()


@pytest.mark.slow        # builds the body and a 2-frame synthetic sequence before the tracker (~10 s)
def test_out_of_range_value_one_line_then_traceback_with_debug(tmp_path):
    args = ("track", "tracker=apf", "tracker.particles=-1", "data=walk_small", "data.frames=2",
            f"hydra.run.dir={tmp_path}")
    r = mocap(*args)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    (line,) = lines(r.stderr)
    assert line.startswith("mocap track: error:") and "particles" in line and "-1" in line
    debug = mocap("--debug", *args)
    assert debug.returncode != 0 and "Traceback" in debug.stderr and "particles" in debug.stderr


def test_hydra_full_error_shows_the_traceback(tmp_path):
    r = mocap("track", "tracker=no_such_tracker", f"hydra.run.dir={tmp_path}",
              env={**ENV, "HYDRA_FULL_ERROR": "1"})
    assert r.returncode != 0 and "Traceback" in r.stderr and "no_such_tracker" in r.stderr
    quiet = mocap("track", "tracker=no_such_tracker", f"hydra.run.dir={tmp_path}")
    (line,) = lines(quiet.stderr)
    assert "Could not find 'tracker/no_such_tracker'" in line and "apf_prior" in line   # the options


def test_argparse_commands_report_a_missing_file_in_one_line(tmp_path):
    r = mocap("export", str(tmp_path / "nothing"), "--format", "bvh")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    (line,) = lines(r.stderr)
    assert line.startswith("mocap export: error:") and "no motion.npz" in line


def test_which_errors_are_the_users():
    assert user_error_message(ValueError("setting particles = -1 is out of range")) == (
        "setting particles = -1 is out of range")
    assert user_error_message(KeyError("no such preset 'x'")) == "no such preset 'x'"   # unquoted
    try:                                           # Hydra wraps a factory's error: the original message
        try:
            raise ValueError("layers must be >= 1, got 0")
        except ValueError as exc:
            raise InstantiationException("Error in call to target 'f':\nValueError(...)") from exc
    except InstantiationException as wrapped:
        assert user_error_message(wrapped) == "layers must be >= 1, got 0"
    try:                                           # a composition error names the key and the reason
        try:
            raise ConfigKeyError("Key 'foo' is not in struct\n    full_key: tracker.foo")
        except ConfigKeyError as exc:
            raise ConfigCompositionException("Could not override 'tracker.foo'.\nTo append use +") from exc
    except ConfigCompositionException as composed:
        assert user_error_message(composed) == (
            "Could not override 'tracker.foo': Key 'foo' is not in struct (To append use +)")
    missing = MissingConfigException("In 'track': Could not find 'tracker/x'\n\nAvailable options in "
                                     "'tracker':\n\tapf\n\tlocal\nConfig search path:\n\tprovider=main")
    assert user_error_message(missing) == (
        "In 'track': Could not find 'tracker/x' (available in 'tracker': apf, local)")
    # programming errors keep their traceback
    for exc in (ZeroDivisionError("division by zero"), AttributeError("x"), TypeError("unsupported operand"),
                IndexError("index 3 is out of bounds")):
        assert user_error_message(exc) is None, exc


def test_main_in_process_prints_one_line_and_returns_2(capsys):
    assert main(["no-such-command"]) == 2
    assert lines(capsys.readouterr().err) == [
        f"mocap: error: unknown command 'no-such-command' (commands: {', '.join(COMMANDS)}; mocap --help)"]
    assert main(["replay", "/nonexistent/run"]) == 2
    assert lines(capsys.readouterr().err) == [
        "mocap replay: error: /nonexistent/run: no such run directory or .rrd file"]
    with pytest.raises(FileNotFoundError):
        main(["--debug", "replay", "/nonexistent/run"])


@pytest.mark.parametrize("value, shown", [("0", "0"), ("-1", "-1"), ("many", "'many'")])
def test_bad_thread_budget_one_line_before_any_work(tmp_path, value, shown):
    (tmp_path / "metrics.json").write_text("{}")      # an earlier run's: a run would clear it first
    r = mocap("track", "tracker=local", "data=walk_small", f"threads={value}", f"hydra.run.dir={tmp_path}")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    (line,) = lines(r.stderr)
    assert line == (f"mocap track: error: setting threads = {shown} is out of range: allowed 'auto' "
                    "(cores / parallel jobs), an integer >= 1, or null (the libraries' defaults)")
    assert (tmp_path / "metrics.json").read_text() == "{}" and not (tmp_path / "motion.npz").exists()
