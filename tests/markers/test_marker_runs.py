"""mocap track with the marker tracker on the real Pose2Sim recording, which has no
ground truth: the run reports the keypoint metrics of mocap/eval/keypoint_metrics.py.
(Synthetic marker runs are covered by tests/cli/test_track.py.)"""

import json
import os
from pathlib import Path

import pytest

from tests.cli.in_process import mocap

REPO = Path(__file__).resolve().parents[2]
DEMO = Path(os.environ.get("MOCAP_SHARED_DATA") or REPO.parent / "shared" / "data") / "pose2sim-demo"


def run_track(tmp_path: Path, *overrides: str) -> dict:
    """The run's metrics (``mocap track`` in this process: :mod:`tests.cli.in_process`)."""
    r = mocap("track", f"hydra.run.dir={tmp_path}", "tracker=marker_apf", "recording.enabled=false",
              *overrides)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads((tmp_path / "metrics.json").read_text())


@pytest.mark.skipif(not (DEMO / "Calib.toml").is_file(), reason="Pose2Sim demo data not present")
def test_marker_run_on_the_pose2sim_demo_reports_keypoint_metrics(tmp_path):
    # the default init.mode (auto) starts a run on data without a ground-truth pose by itself
    m = run_track(tmp_path, "data=pose2sim_demo", "frames=4")
    assert m["config"]["init"]["mode"] == "auto" and "init" in m       # the tracker's own start
    assert "mpjpe_mm" not in m and m["frames"] == 4
    per_view = m["reprojection_median_px_per_view"]
    assert set(per_view) == {"cam_01", "cam_02", "cam_03", "cam_04"}
    assert all(0 < v < 60 for v in per_view.values())
    assert m["bone_length_std_mm"] < 1.0                    # a body model: bones of constant length
    assert m["triangulation"]["reprojection_median_px"] < m["reprojection_median_px"] + 20


def test_marker_tracker_on_data_without_detections_fails_before_any_work(tmp_path):
    r = mocap("track", f"hydra.run.dir={tmp_path}", "tracker=marker_apf", "data=walk_small",   # in-process
              "data.frames=2", "recording.enabled=true")
    assert r.returncode != 0
    assert "marker_apf needs 2D detections" in r.stderr and "has none" in r.stderr
    assert "it/s" not in r.stderr and "frame/s" not in r.stderr               # no progress bar: no tracking
    assert not (tmp_path / "recording.rrd").exists() and not (tmp_path / "metrics.json").exists()
