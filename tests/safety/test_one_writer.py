"""One writer per run folder (issue 36): a process holding the folder's lock
(:mod:`mocap.run_folder.lock`) makes every other one refuse at once, in one line naming the
holder; a manifest is written only by the holder; what an interrupted run left is put right at
the next start. Processes synchronise on the lock file's content, never on sleeps."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from mocap.run_folder.lock import LOCK, RunFolderBusy, holds, run_lock
from mocap.run_folder.manifest import manifest_problem, write_manifest

REPO = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(REPO), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
       "NUMBA_NUM_THREADS": "1"}


def wait_for_holder(folder: Path, pid: int, proc: subprocess.Popen, timeout: float = 600) -> None:
    """Until the lock file names ``pid`` (it is written once the lock is held)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            if json.loads((folder / LOCK).read_text() or "{}").get("pid") == pid:
                return
        except (OSError, ValueError):
            pass
        if proc.poll() is not None:
            raise AssertionError(f"the first process ended ({proc.returncode}) before holding the lock: "
                                 + proc.stderr.read()[-2000:])
        time.sleep(0.01)
    raise AssertionError("the lock was never taken")


@pytest.fixture
def holder(tmp_path):
    """Another process holding ``tmp_path/run``'s lock until its stdin closes."""
    run = tmp_path / "run"
    code = ("import sys; from mocap.run_folder.lock import run_lock\n"
            f"with run_lock({str(run)!r}):\n    sys.stdin.read()\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV, cwd=REPO)
    wait_for_holder(run, proc.pid, proc, 120)
    yield run, proc
    proc.stdin.close()
    proc.wait(60)


def test_a_second_writer_is_refused_naming_the_holder(holder):
    run, proc = holder
    t = time.perf_counter()
    with pytest.raises(RunFolderBusy, match=rf"pid {proc.pid} on \S+ since \d{{4}}-") as info:
        with run_lock(run):
            pass
    assert time.perf_counter() - t < 1.0 and "\n" not in str(info.value)
    (run / "motion.npz").write_bytes(b"m")
    (run / "metrics.json").write_text("{}")
    with pytest.raises(RunFolderBusy, match="its manifest is not written by this one"):
        write_manifest(run, ["motion.npz", "metrics.json"])
    assert not (run / "manifest.json").exists()


def test_the_lock_goes_with_its_holder_however_it_ends(tmp_path):
    run = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-c", f"from mocap.run_folder.lock import run_lock\n"
                             f"import os, sys\nwith run_lock({str(run)!r}):\n    sys.stdin.read()\n"],
                            stdin=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV, cwd=REPO)
    wait_for_holder(run, proc.pid, proc, 120)
    proc.kill()                                        # SIGKILL: no clean-up of its own
    proc.wait(60)
    with run_lock(run):
        assert holds(run)
        with run_lock(run):                            # re-entrant within a process
            assert holds(run)
    assert not holds(run)


def test_a_planted_link_as_lock_file_is_refused(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (tmp_path / "elsewhere").write_text("keep")
    (run / LOCK).symlink_to(tmp_path / "elsewhere")
    with pytest.raises(RunFolderBusy, match="symbolic link"):
        with run_lock(run):
            pass
    assert (tmp_path / "elsewhere").read_text() == "keep"


#: a ``mocap`` program holding a run folder's lock in a loop that swallows every Ctrl-C (as a
#: library's native code that never returns to Python would keep it): only the interrupt watchdog
#: (:mod:`mocap_cli.interrupt`, shortened to 0.5 s) ends it, with ``os._exit``
SWALLOWED = """
import sys, time
from mocap_cli import interrupt
interrupt.install()
interrupt.GRACE_S = 0.5
interrupt.set_command("mocap held")
from mocap.run_folder.lock import run_lock
with run_lock(sys.argv[1]):
    held = False
    while True:
        try:        # "held" printed inside the try: the test's Ctrl-C cannot land outside it
            if not held:
                print("held", flush=True)
                held = True
            time.sleep(0.01)
        except KeyboardInterrupt:
            pass
"""


def test_a_process_ended_by_the_interrupt_watchdog_leaves_no_lock_file(tmp_path):
    run = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-c", SWALLOWED, str(run)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV, cwd=REPO)
    assert proc.stdout.readline().strip() == "held", proc.stderr.read()[-2000:]
    assert (run / LOCK).is_file()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-2000:]
    assert err.strip().splitlines() == ["mocap held: interrupted (Ctrl-C); nothing more is written"]
    assert not (run / LOCK).exists()                   # the watchdog removed it before os._exit
    with run_lock(run):                                # and the lock went with the process
        pass


TRACK = ["tracker=apf", "data=walk_small", "data.frames=2", "tracker.particles=4", "tracker.layers=2",
         "recording.enabled=false"]


#: ``mocap track`` that, once it holds the lock and runs, says so in the file argv[1] + ".ready"
#: and waits for the file argv[1] before going on
HELD_TRACK = """
import pathlib, sys, time
import mocap.run_folder.attempt as attempt
go, tidy = pathlib.Path(sys.argv[1]), attempt.tidy_leftovers
def waiting(out_dir):
    go.with_suffix(".ready").touch()
    while not go.exists():
        time.sleep(0.01)
    return tidy(out_dir)
attempt.tidy_leftovers = waiting
from mocap_cli.main import main
sys.exit(main(sys.argv[2:]))
"""


def folder_files(run: Path) -> dict[Path, bytes]:
    """Every file under ``run`` but the lock file: its content."""
    return {p.relative_to(run): p.read_bytes() for p in sorted(run.rglob("*"))
            if p.is_file() and p.name != LOCK}


def test_two_track_processes_on_one_folder_the_second_refuses_the_first_completes(tmp_path):
    run, go = tmp_path / "run", tmp_path / "go"
    first = subprocess.Popen([sys.executable, "-c", HELD_TRACK, str(go), "track", f"hydra.run.dir={run}",
                              "seed=0", *TRACK], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=ENV, cwd=REPO)
    try:
        wait_for_holder(run, first.pid, first)
        while not go.with_suffix(".ready").exists():                # Hydra's files written, the run begun
            assert first.poll() is None, first.stderr.read()[-2000:]
            time.sleep(0.01)
        files = folder_files(run)
        assert {Path(".hydra/hydra.yaml"), Path(".hydra/config.yaml"), Path("track.log")} <= set(files)
        second = subprocess.run([sys.executable, "-m", "mocap_cli", "track", f"hydra.run.dir={run}", "seed=1",
                                 *TRACK], capture_output=True, text=True, env=ENV, cwd=REPO, timeout=600)
        # the refused process wrote nothing into the folder: the first run's files as they were
        # (Hydra's .hydra/ and the job's log included), nothing added
        after = folder_files(run)
        assert after.keys() == files.keys() and all(after[k] == files[k] for k in files), \
            [str(k) for k in after if after[k] != files.get(k)]
    finally:
        go.touch()                                               # (the first goes on, whatever failed)
    first_out, first_err = first.communicate(timeout=900)
    assert second.returncode == 2
    lines = [line for line in second.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and f"pid {first.pid}" in lines[0] and "refused" in lines[0], second.stderr
    assert first.returncode == 0, first_err[-3000:]
    assert manifest_problem(run) is None
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["config"]["seed"] == 0                        # the first one's run, whole
    manifest = json.loads((run / "manifest.json").read_text())
    assert "seed=0" in manifest["overrides"] and "seed=1" not in manifest["overrides"]
    assert not (run / LOCK).exists()                             # removed by its holder
    # the folder describes the results it holds: .hydra/ is the first run's, the log has no refusal
    hydra_config = yaml.safe_load((run / ".hydra" / "config.yaml").read_text())
    assert hydra_config["seed"] == 0 and hydra_config == metrics["config"]
    hydra_overrides = yaml.safe_load((run / ".hydra" / "overrides.yaml").read_text())
    assert "seed=0" in hydra_overrides and "seed=1" not in hydra_overrides
    hydra_yaml = yaml.safe_load((run / ".hydra" / "hydra.yaml").read_text())["hydra"]
    assert "seed=0" in hydra_yaml["overrides"]["task"] and "seed=1" not in hydra_yaml["overrides"]["task"]
    assert "refused" not in (run / "track.log").read_text()


def test_a_second_sweep_into_a_held_sweep_folder_is_refused_before_it_writes(tmp_path):
    """A --multirun holds its sweep folder from before Hydra writes there: another process
    holding it (a first sweep) makes the second refuse at once, in one line naming the holder,
    with nothing written (no multirun.yaml, no job folder); once it is free, the sweep runs and
    lets go of it."""
    sweep = tmp_path / "sweep"
    code = ("import sys; from mocap.run_folder.lock import run_lock\n"
            f"with run_lock({str(sweep)!r}):\n    sys.stdin.read()\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV, cwd=REPO)
    command = [sys.executable, "-m", "mocap_cli", "track", "--multirun", f"hydra.sweep.dir={sweep}",
               "seed=0,1", *TRACK]
    try:
        wait_for_holder(sweep, proc.pid, proc, 120)
        second = subprocess.run(command, capture_output=True, text=True, env=ENV, cwd=REPO, timeout=600)
        assert folder_files(sweep) == {} and sorted(p.name for p in sweep.iterdir()) == [LOCK]
    finally:
        proc.stdin.close()
        proc.wait(60)
    assert second.returncode == 2, second.stderr[-2000:]
    lines = [line for line in second.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and f"pid {proc.pid}" in lines[0] and "refused" in lines[0], second.stderr
    done = subprocess.run(command, capture_output=True, text=True, env={**ENV, "TQDM_DISABLE": "1"}, cwd=REPO,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (sweep / "multirun.yaml").is_file() and not (sweep / LOCK).exists()
    assert sorted(json.loads(p.read_text())["config"]["seed"] for p in sweep.glob("*/metrics.json")) == [0, 1]
