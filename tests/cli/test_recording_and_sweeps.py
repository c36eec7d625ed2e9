"""Recordings, replay, multirun sweeps (parallel, resumable) and ablation tables."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mocap.recording.reader import read_recording
from tests.cli.in_process import mocap

REPO = Path(__file__).resolve().parents[2]
FAST = ["data=walk_small", "tracker.particles=6", "tracker.layers=2"]


def track(*args: str, cwd: Path = REPO, process: bool = True) -> subprocess.CompletedProcess:
    """``mocap track *args``: a process of its own, or in this process (``process=False``,
    :mod:`tests.cli.in_process`) where what it writes is the point."""
    if not process:
        return mocap("track", *args, cwd=cwd)
    return subprocess.run([sys.executable, "-m", "mocap_cli", "track", *args],
                          capture_output=True, text=True, cwd=cwd, timeout=900)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    r = track(f"hydra.run.dir={d}", "tracker=apf_prior", "frames=4", *FAST, process=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return d


def test_recording_holds_the_run_and_matches_metrics(run_dir):
    m = json.loads((run_dir / "metrics.json").read_text())
    info = read_recording(run_dir / "recording.rrd")
    for entity in ("/world/body/estimate", "/world/skeleton/estimate", "/world/skeleton/truth",
                   "/world/cams/cam_00", "/views/cam_00/silhouette_diff",
                   "/plots/energy/silhouette", "/plots/error/mpjpe_mm", "/plots/layers/beta",
                   "/run/config", "/run/metadata", "/run/metrics"):
        assert entity in info["entities"], entity
    assert info["num_frames"] == m["frames"] == 4
    errors = info["scalars"]["/plots/error/mpjpe_mm"]
    assert sorted(errors) == [0, 1, 2, 3]
    assert [errors[f] for f in range(4)] == pytest.approx(m["per_frame_mm"], rel=1e-9)
    assert len(info["scalars"]["/plots/energy/silhouette"]) == 3       # tracked frames 1..3
    assert info["metrics"]["mpjpe_mm"] == pytest.approx(m["mpjpe_mm"])
    meta = json.loads(info["texts"]["/run/metadata"])
    assert {"git_revision", "seed", "config_hash", "run_id"} <= meta.keys()


def test_recording_passes_rerun_verify(run_dir):
    rerun = Path(sys.executable).with_name("rerun")
    r = subprocess.run([str(rerun), "rrd", "verify", str(run_dir / "recording.rrd")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr


def test_replay_prints_a_headless_summary(run_dir):
    r = subprocess.run([sys.executable, "-m", "mocap_cli", "replay", str(run_dir),
                        "--summary"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "frames 0..3" in r.stdout and "/world/body/estimate" in r.stdout
    assert "mpjpe_mm" in r.stdout
    bad = subprocess.run([sys.executable, "-m", "mocap_cli", "replay", "/nonexistent"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "no such run directory" in bad.stderr


def test_recording_can_be_switched_off(tmp_path):
    r = track(f"hydra.run.dir={tmp_path}", "tracker=apf_prior", "frames=2", "recording.enabled=false", *FAST,
              process=False)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "metrics.json").is_file() and not list(tmp_path.glob("*.rrd*"))


@pytest.mark.slow
def test_multirun_two_trackers_two_seeds_then_resume_and_ablate(tmp_path):
    sweep = tmp_path / "sweep"
    args = ["--multirun", f"hydra.sweep.dir={sweep}", "tracker=apf,apf_prior", "seed=0,1",
            "frames=2", *FAST]
    r = track(*args)
    assert r.returncode == 0, r.stderr[-3000:]
    runs = sorted(p.parent for p in sweep.rglob("metrics.json"))
    assert len(runs) == 4
    assert all((d / "recording.rrd").is_file() for d in runs)
    stamps = {d: (d / "metrics.json").stat().st_mtime_ns for d in runs}
    # an interrupted sweep re-run with skip_complete does not redo finished jobs
    (runs[0] / "metrics.json").unlink()
    r = track(*args, "skip_complete=true")
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.count("already complete") == 3
    assert all((d / "metrics.json").stat().st_mtime_ns == stamps[d] for d in runs[1:])
    assert (runs[0] / "metrics.json").is_file()
    # ablation table, with one broken run named
    (runs[1] / "metrics.json").write_text("{broken")
    out = subprocess.run([sys.executable, "-m", "mocap_cli", "ablate", str(sweep)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    md = (sweep / "ablation.md").read_text()
    assert "| apf |" in md and "| apf_prior |" in md
    assert str(runs[1]) in md and "unreadable metrics.json" in md
    assert (sweep / "ablation.csv").is_file() and (sweep / "ablation.png").is_file()
    assert (sweep / "ablation_frames.png").is_file()


def test_missing_data_path_fails_before_any_work(tmp_path):
    r = track(f"hydra.run.dir={tmp_path}", "data=folder", "data.path=/nonexistent/seq", process=False)
    assert r.returncode != 0 and "data path not found: /nonexistent/seq" in r.stderr
    assert not (tmp_path / "metrics.json").exists() and not list(tmp_path.glob("*.rrd*"))
