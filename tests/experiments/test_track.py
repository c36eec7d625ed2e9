"""experiments/track.py end to end: every tracker for two frames, and its metrics.json."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TRACKERS = sorted(p.stem for p in (REPO / "conf" / "tracker").glob("*.yaml"))
REQUIRED = {"tracker", "seed", "frames", "mpjpe_mm", "mpjpe_std_mm", "per_joint_mm",
            "sec_per_frame", "energy_evals_per_frame", "per_frame_mm"}


def run_track(tmp_path: Path, *overrides: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(REPO / "experiments" / "track.py"),
                           f"hydra.run.dir={tmp_path}", *overrides],
                          capture_output=True, text=True, cwd=REPO, timeout=600)


# small budgets per tracker family, and the energy evaluations per frame they imply
FAST = {
    "apf": (["tracker.particles=8", "tracker.layers=2"], 16),
    "local": (["tracker.iterations=2"], 0),
    "hybrid": (["tracker.apf.particles=8", "tracker.apf.layers=2", "tracker.local.iterations=2"], None),
    "marker_apf": (["tracker.particles=8", "tracker.layers=2"], 16),
}
# marker trackers need 2D detections
DATA = {"marker_apf": "walk_markers_small"}


def fast_overrides(tracker: str) -> tuple[list[str], int | None]:
    family = "apf" if tracker.startswith("apf") else tracker
    return FAST[family]


@pytest.mark.parametrize("tracker", TRACKERS)
def test_each_tracker_runs_two_frames_and_writes_metrics(tracker, tmp_path):
    overrides, evals = fast_overrides(tracker)
    data = DATA.get(tracker, "walk_small")
    r = run_track(tmp_path, f"tracker={tracker}", f"data={data}", "frames=2", *overrides)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert REQUIRED <= m.keys()
    assert m["tracker"] == tracker and m["frames"] == 2 and len(m["per_frame_mm"]) == 2
    assert len(m["per_joint_mm"]) == 15 and m["mpjpe_mm"] > 0
    if evals is not None:
        assert m["energy_evals_per_frame"] == evals


def test_unknown_tracker_fails_at_configuration_time(tmp_path):
    r = run_track(tmp_path, "tracker=nonexistent")
    assert r.returncode != 0
    assert "Could not find 'tracker/nonexistent'" in r.stderr
    assert not (tmp_path / "metrics.json").exists()
