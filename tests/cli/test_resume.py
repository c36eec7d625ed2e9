"""Honest resume: skip_complete skips only runs made by the same config; a changed parameter
reruns (or is refused, by flag, leaving the directory describing what it holds); an
interrupted run reruns and leaves no stale failed recording."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mocap.eval.resume import clear_outputs, config_changes, run_state

REPO = Path(__file__).resolve().parents[2]
FAST = ["tracker=apf", "data=walk_small", "frames=2", "tracker.particles=4", "tracker.layers=2",
        "recording.every=5", "recording.particles=false"]


def track(run_dir: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocap_cli", "track",
                           f"hydra.run.dir={run_dir}", *FAST, *args],
                          capture_output=True, text=True, cwd=REPO, timeout=600)


def test_run_state_compares_the_stored_config(tmp_path):
    config = {"seed": 0, "tracker": {"layers": 2}, "skip_complete": False}
    assert run_state(tmp_path, config, recording=False) == "missing"
    (tmp_path / "metrics.json").write_text(json.dumps({"config": {**config, "skip_complete": True}}))
    assert run_state(tmp_path, config, recording=False) == "complete"    # bookkeeping key ignored
    assert run_state(tmp_path, config, recording=True) == "missing"      # no recording.rrd
    changed = {**config, "tracker": {"layers": 3}}
    assert run_state(tmp_path, changed, recording=False) == "changed"
    assert config_changes(tmp_path, changed) == ["tracker.layers"]
    (tmp_path / "recording.failed.rrd").write_text("x")
    assert sorted(clear_outputs(tmp_path)) == ["metrics.json", "recording.failed.rrd"]
    (tmp_path / "metrics.json").write_text("{broken")
    assert run_state(tmp_path, config, recording=False) == "unreadable"


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
