"""Faults end cleanly (issue 36): a recording writer that blocks (a full disk) or fails ends the
run within a bounded time with one error line and a non-zero code, the folder visibly incomplete
(no manifest, ``recording.rrd.part`` left); Ctrl-C at any moment of start-up ends ``mocap`` with
one line and code 130 (the moments are states of the process: which libraries it has loaded,
read from /proc, never fixed sleeps); what an interrupted run left is put right at the next
start (:func:`mocap.run_folder.attempt.tidy_leftovers`)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mocap.run_folder.attempt import tidy_leftovers
from mocap.run_folder.manifest import MANIFEST, manifest_problem, write_manifest

REPO = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(REPO), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
       "NUMBA_NUM_THREADS": "1"}
TRACK = ["tracker=apf", "data=walk_small", "data.frames=2", "tracker.particles=4", "tracker.layers=2",
         "recording.level=summary"]

#: ``mocap track`` with the recording's writer made to fail: argv[1] = block_start | block_finish
#: | enospc_finish | enospc_metrics; the bounded wait shortened to 2 s
FAULTY = """
import errno, sys, threading, time
import rerun as rr
import mocap.recording.rerun_sink as sink
sink.WRITE_TIMEOUT_S = 2.0
how, calls, real = sys.argv[1], [], rr.RecordingStream.flush
def flush(self, *a, **k):
    calls.append(1)
    if how == "block_start" or (how == "block_finish" and len(calls) > 1):
        threading.Event().wait()                    # a writer that never returns (a full disk)
    if how == "enospc_finish" and len(calls) > 1:
        raise OSError(errno.ENOSPC, "No space left on device")
    return real(self, *a, **k)
rr.RecordingStream.flush = flush
if how == "enospc_metrics":
    import mocap.run_folder.attempt as attempt
    def write_json(path, data):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))
    attempt.write_json = write_json
from mocap_cli.main import main
sys.argv = ["mocap", *sys.argv[2:]]
sys.exit(main())                                    # as the program (not in-process)
"""


@pytest.mark.parametrize("how", ["block_start", "block_finish", "enospc_finish", "enospc_metrics"])
def test_a_failing_or_blocked_write_ends_the_run_in_bounded_time_with_one_line(how, tmp_path):
    run = tmp_path / "run"
    t = time.monotonic()
    r = subprocess.run([sys.executable, "-c", FAULTY, how, "track", f"hydra.run.dir={run}", *TRACK],
                       capture_output=True, text=True, env=ENV, cwd=REPO, timeout=600)
    took = time.monotonic() - t
    lines = [line for line in r.stderr.splitlines() if line.strip() and "frame/s" not in line
             and "it/s" not in line and "%|" not in line]
    assert r.returncode == 1, r.stderr[-3000:]
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    assert lines[-1].startswith("mocap track: error:"), lines
    assert ("within 2 s" in lines[-1]) == how.startswith("block"), lines[-1]
    assert "No space left" in lines[-1] or how.startswith("block")
    assert len(lines) <= 2                      # (the run's own "not complete" line, and the error)
    assert not (run / MANIFEST).exists() and manifest_problem(run) is not None
    if how != "enospc_metrics":
        assert (run / "recording.rrd.part").exists()      # visibly incomplete
    assert took < 300


STAGES = ["yaml/_yaml", "numpy/_core/_multiarray_umath", "llvmlite/binding", "numba/_dispatcher",
          "cv2/cv2", "scipy/sparse"]


def _loaded(pid: int, marker: str) -> bool:
    try:
        return marker in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs /proc to see the process's state")
@pytest.mark.parametrize("stage", STAGES)
def test_ctrl_c_at_start_up_ends_mocap_with_one_line(stage, tmp_path):
    run = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-m", "mocap_cli", "track", f"hydra.run.dir={run}", *TRACK],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV, cwd=REPO)
    while not _loaded(p.pid, stage):
        assert p.poll() is None, f"ended before loading {stage}: {p.stderr.read()[-2000:]}"
        time.sleep(0.002)
    t = time.monotonic()
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    latency = time.monotonic() - t
    lines = [line for line in err.splitlines() if line.strip()]
    assert p.returncode == 130, err[-3000:]
    assert len(lines) == 1 and "interrupted" in lines[0], lines
    assert latency < 6.0
    assert not (run / MANIFEST).exists()


def _complete(d: Path, content: bytes = b"m") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "motion.npz").write_bytes(content)
    (d / "metrics.json").write_text(json.dumps({"config": {}}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


def test_temporary_files_of_a_killed_run_are_removed_at_the_next_start(tmp_path):
    run = _complete(tmp_path / "run")
    for name in (".motion.npz.1234.tmp", ".metrics.json.x1y2.tmp", "metrics.json.tmp", ".m.npz.ab.tmp.npz"):
        (run / name).write_bytes(b"half")
    (tmp_path / "kept.tmp").write_text("not in the run folder")
    notes = tidy_leftovers(run)
    assert sorted(p.name for p in run.iterdir()) == ["manifest.json", "metrics.json", "motion.npz"]
    assert (tmp_path / "kept.tmp").exists() and len(notes) == 1


@pytest.mark.parametrize("moved", [0, 1, 2, 3])
def test_a_run_caught_half_way_into_previous_run_is_moved_back_complete(moved, tmp_path):
    """A kill while the earlier run was being set aside (set_aside moves motion.npz,
    metrics.json, then the manifest into previous_run.tmp/): the next start moves them back and
    the folder is the complete earlier run again (resume can skip or restore it)."""
    run = _complete(tmp_path / "run", b"earlier run")
    half = run / "previous_run.tmp"
    half.mkdir()
    for name in ["motion.npz", "metrics.json", MANIFEST][:moved]:
        (run / name).replace(half / name)
    assert (manifest_problem(run) is None) == (moved == 0)
    tidy_leftovers(run)
    assert manifest_problem(run) is None and not half.exists()
    assert (run / "motion.npz").read_bytes() == b"earlier run"


def test_previous_run_beside_a_complete_newer_run_is_dropped(tmp_path):
    run = _complete(tmp_path / "run", b"new")
    _complete(run / "previous_run", b"old")
    tidy_leftovers(run)
    assert not (run / "previous_run").exists() and manifest_problem(run) is None


def test_previous_run_beside_an_incomplete_run_is_kept(tmp_path):
    run = _complete(tmp_path / "run", b"new")
    (run / MANIFEST).unlink()
    _complete(run / "previous_run", b"old")
    tidy_leftovers(run)
    assert manifest_problem(run / "previous_run") is None
