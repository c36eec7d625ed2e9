"""Honest resume: skip_complete skips only complete runs (a valid manifest: checksums match)
made by the same config (threads resolved); a changed parameter reruns (or is refused, by
flag, leaving the directory describing what it holds); an interrupted run reruns and leaves
no stale failed recording; an interrupted re-run (SIGINT, SIGTERM, SIGKILL) never leaves a
folder that export or ablate accepts, and keeps the old complete run recoverable; a sweep
re-run in another order reruns nothing, a deleted or corrupted motion.npz reruns that job."""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from mocap.run_folder.manifest import manifest_problem, write_manifest
from mocap.run_folder.resume import clear_outputs, config_changes, restore_previous, run_state, set_aside
from tests.cli.in_process import mocap

REPO = Path(__file__).resolve().parents[2]
FAST = ["tracker=apf", "data=walk_small", "frames=2", "tracker.particles=4", "tracker.layers=2",
        "recording.every=5", "recording.particles=false"]
#: the progress bar of a run that has tracked (and recorded) at least one of its 20 frames
TRACKED_A_FRAME = re.compile(r"\b[1-9]\d*/20\b")


def track(run_dir: Path, *args: str) -> subprocess.CompletedProcess:
    """``mocap track`` in this process (:mod:`tests.cli.in_process`): what resume writes and
    prints; the interrupted re-runs below are processes of their own (signals)."""
    return mocap("track", f"hydra.run.dir={run_dir}", *FAST, *args)


def complete(d: Path, config: dict, threads=None, motion: bytes = b"motion") -> Path:
    """A complete run folder of ``config`` (files and their manifest)."""
    d.mkdir(parents=True, exist_ok=True)
    (d / "motion.npz").write_bytes(motion)
    (d / "metrics.json").write_text(json.dumps({"config": config, "threads": threads}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


def test_run_state_checks_the_manifest_and_the_stored_config(tmp_path):
    config = {"seed": 0, "tracker": {"layers": 2}, "skip_complete": False}
    assert run_state(tmp_path, config, recording=False) == "missing"
    (tmp_path / "metrics.json").write_text(json.dumps({"config": config}))
    assert run_state(tmp_path, config, recording=False) == "incomplete"    # metrics alone: not complete
    complete(tmp_path, {**config, "skip_complete": True})
    assert run_state(tmp_path, config, recording=False) == "complete"    # bookkeeping key ignored
    assert run_state(tmp_path, config, recording=True) == "changed"      # no recording in the manifest
    changed = {**config, "tracker": {"layers": 3}}
    assert run_state(tmp_path, changed, recording=False) == "changed"
    assert config_changes(tmp_path, changed) == ["tracker.layers"]
    (tmp_path / "motion.npz").write_bytes(b"motiom")                   # same size, other bytes
    assert run_state(tmp_path, config, recording=False) == "corrupt"
    (tmp_path / "motion.npz").write_bytes(b"mot")                      # half size
    assert run_state(tmp_path, config, recording=False) == "corrupt"
    (tmp_path / "motion.npz").unlink()
    assert run_state(tmp_path, config, recording=False) == "corrupt"
    (tmp_path / "recording.failed.rrd").write_text("x")
    assert sorted(clear_outputs(tmp_path)) == ["manifest.json", "metrics.json", "recording.failed.rrd"]


def test_threads_are_compared_as_resolved(tmp_path):
    """threads: auto ran with 2 threads: the same as threads=2 asked for, not as auto on 1 core."""
    config = {"seed": 0, "threads": "auto"}
    complete(tmp_path, config, threads=2)
    assert run_state(tmp_path, {"seed": 0, "threads": 2}, recording=False, threads=2) == "complete"
    assert run_state(tmp_path, config, recording=False, threads=1) == "changed"
    assert config_changes(tmp_path, config, threads=1) == ["threads"]


def test_set_aside_keeps_a_complete_run_until_restored(tmp_path):
    old = {"seed": 0, "tracker": {"layers": 2}}
    complete(tmp_path, old)
    notes = set_aside(tmp_path)
    assert "previous_run" in notes[0] and not (tmp_path / "manifest.json").exists()
    assert manifest_problem(tmp_path / "previous_run") is None          # complete, verifiable there
    assert "previous_run/" in manifest_problem(tmp_path)                  # and said so here
    (tmp_path / "recording.rrd.part").write_bytes(b"killed")              # a killed re-run's leftovers
    (tmp_path / "motion.npz").write_bytes(b"new, half written")
    assert not restore_previous(tmp_path, {"seed": 0, "tracker": {"layers": 3}}, recording=False)
    notes = set_aside(tmp_path)                                           # incomplete: removed, old kept
    assert any("recording.rrd.part" in n for n in notes) and (tmp_path / "previous_run").is_dir()
    assert not (tmp_path / "recording.rrd.part").exists() and not (tmp_path / "motion.npz").exists()
    assert restore_previous(tmp_path, old, recording=False)
    assert manifest_problem(tmp_path) is None and not (tmp_path / "previous_run").exists()
    assert (tmp_path / "motion.npz").read_bytes() == b"motion"


@pytest.mark.slow
def test_resume_reruns_changed_and_interrupted_runs_only(tmp_path):
    r = track(tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    first = (tmp_path / "metrics.json").stat().st_mtime_ns
    # same config: skipped
    r = track(tmp_path, "skip_complete=true")
    assert r.returncode == 0 and "already complete" in r.stdout
    assert (tmp_path / "metrics.json").stat().st_mtime_ns == first
    # a changed parameter, refused by flag: the directory still describes the old run
    r = track(tmp_path, "skip_complete=true", "tracker.layers=3", "resume_on_change=fail")
    assert r.returncode != 0 and "changed: tracker.layers" in r.stderr
    assert "layers: 2" in (tmp_path / ".hydra" / "config.yaml").read_text()
    # a changed parameter: reruns, and the results are those of the new config
    r = track(tmp_path, "skip_complete=true", "tracker.layers=3")
    assert r.returncode == 0 and "already complete" not in r.stdout, r.stderr[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["config"]["tracker"]["layers"] == 3 and m["layers"] == 3
    # an interrupted run (no metrics, a failed recording): reruns, the stale file is gone
    (tmp_path / "metrics.json").unlink()
    (tmp_path / "recording.rrd").replace(tmp_path / "recording.failed.rrd")
    r = track(tmp_path, "skip_complete=true", "tracker.layers=3")
    assert r.returncode == 0 and "already complete" not in r.stdout, r.stderr[-3000:]
    assert (tmp_path / "recording.rrd").is_file() and not (tmp_path / "recording.failed.rrd").exists()


@pytest.fixture(scope="module")
def old_run(tmp_path_factory) -> Path:
    """A complete run (tracker.layers=2, 2 frames, no recording) to re-run and interrupt."""
    d = tmp_path_factory.mktemp("old") / "run"
    r = track(d, "recording.enabled=false")
    assert r.returncode == 0, r.stderr[-3000:]
    return d


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=lambda s: s.name)
def test_an_interrupted_rerun_is_never_taken_for_the_new_run(old_run, sig, tmp_path):
    from mocap.run_folder.export import export_run
    from mocap.run_folder.sweep import collect

    run = tmp_path / "run"
    shutil.copytree(old_run, run)
    old_motion = (run / "motion.npz").read_bytes()
    # the re-run: another setting, long enough to be caught tracking
    env = {k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"}     # its progress is the state
    proc = subprocess.Popen([sys.executable, "-m", "mocap_cli", "track", f"hydra.run.dir={run}", *FAST,
                             "recording.enabled=true", "frames=20", "tracker.particles=150",
                             "tracker.layers=4"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=REPO, env=env,
                            # a user's Ctrl-C reaches a foreground run: a suite started in the
                            # background (`cmd &`) hands its children SIGINT ignored
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    chunks: list[str] = []

    def read_stderr():
        while text := proc.stderr.read(1):
            chunks.append(text)

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    # interrupted in the frame loop: wait for its progress bar to count a tracked frame (a state,
    # not a time: a loaded machine only makes the wait longer)
    t0 = time.time()
    while not TRACKED_A_FRAME.search("".join(chunks)):
        assert proc.poll() is None and time.time() - t0 < 300, "the re-run ended before it was interrupted"
        time.sleep(0.05)
    proc.send_signal(sig)
    proc.wait(timeout=120)
    reader.join(timeout=30)
    err = "".join(chunks)
    assert proc.returncode != 0
    # nothing in the folder passes for the new run, nor for the old one beside the new config
    assert manifest_problem(run) is not None and not (run / "manifest.json").exists()
    assert not (run / "motion.npz").exists() or (run / "motion.npz").read_bytes() != old_motion
    with pytest.raises(ValueError, match="not a complete run"):
        export_run(run, "bvh", tmp_path / "m.bvh")
    got = collect(tmp_path)
    assert not got.runs and [p[0] for p in got.problems] == [str(run)]
    if sig != signal.SIGKILL:           # cleaned up: the recording closed as failed, said so
        assert (run / "recording.failed.rrd").is_file() and not (run / "recording.rrd.part").exists()
        assert "not complete, no manifest.json written" in err and "previous_run" in err
    else:
        assert (run / "recording.rrd.part").is_file()
    # the old complete run is kept, verifiable, and taken back when asked for again
    assert manifest_problem(run / "previous_run") is None
    assert (run / "previous_run" / "motion.npz").read_bytes() == old_motion
    r = track(run, "recording.enabled=false", "skip_complete=true")
    assert r.returncode == 0 and "previous_run/ restored" in r.stdout, r.stderr[-3000:]
    assert ("removed recording.rrd.part" in r.stderr) == (sig == signal.SIGKILL)
    assert manifest_problem(run) is None and (run / "motion.npz").read_bytes() == old_motion
    assert not (run / "recording.rrd.part").exists() and not (run / "previous_run").exists()
    assert export_run(run, "bvh", tmp_path / "m.bvh").is_file()


def sweep(sweep_dir: Path, *args: str) -> subprocess.CompletedProcess:
    """``mocap track --multirun`` (Hydra's basic launcher: the jobs one after the other) in this
    process."""
    return mocap("track", "--multirun", "hydra/launcher=basic", f"hydra.sweep.dir={sweep_dir}", *FAST,
                 "recording.enabled=false", "skip_complete=true", *args)


def ran(r: subprocess.CompletedProcess) -> list[str]:
    """The run folders a sweep tracked (their closing lines "<tracker>: ... -> <dir>")."""
    return sorted(Path(line.rsplit("-> ", 1)[1]).name for line in r.stdout.splitlines() if " -> " in line)


@pytest.mark.slow
def test_resumed_sweeps_rerun_the_right_jobs_and_count_seeds(tmp_path):
    from mocap.run_folder.sweep import collect, table_rows

    r = sweep(tmp_path, "seed=0,1")
    assert r.returncode == 0, r.stderr[-3000:]
    first = ran(r)
    assert len(first) == 2
    assert first[0].startswith("apf_walk_small_s0_") and first[1].startswith("apf_walk_small_s1_")
    # the same sweep, seeds in another order: the same folders, nothing tracked
    r = sweep(tmp_path, "seed=1,0")
    assert r.returncode == 0 and ran(r) == [] and r.stdout.count("already complete") == 2, r.stderr[-3000:]
    # a deleted motion.npz: exactly that job runs again; a corrupted one likewise
    (tmp_path / first[0] / "motion.npz").unlink()
    r = sweep(tmp_path, "seed=1,0")
    assert r.returncode == 0 and ran(r) == [first[0]], r.stderr[-3000:]
    motion = tmp_path / first[1] / "motion.npz"
    motion.write_bytes(motion.read_bytes()[: motion.stat().st_size // 2])
    r = sweep(tmp_path, "seed=0,1")
    assert r.returncode == 0 and ran(r) == [first[1]], r.stderr[-3000:]
    # a changed setting: new folders (another hash), the old runs stay
    r = sweep(tmp_path, "seed=0,1", "tracker.layers=3")
    assert r.returncode == 0 and len(ran(r)) == 2 and not set(ran(r)) & set(first), r.stderr[-3000:]
    got = collect(tmp_path)
    assert not got.problems and len(got.runs) == 4
    rows = table_rows(got.runs)
    assert sorted((row["overrides"], row["seeds"]) for row in rows) == [("tracker.layers=2", 2),
                                                                        ("tracker.layers=3", 2)]
