"""mocap track tracker=marker_people end to end on the synthetic crowd: per-person motion,
metrics and recording; what it refuses, in one line."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mocap.export.motion import MotionFileError, load_motion
from mocap.export.people_motion import load_people_motion
from mocap.recording.reader import read_recording
from tests.cli.in_process import mocap

FAST = ["tracker.particles=20", "tracker.layers=3", "tracker.init.particles=60", "tracker.init.passes=2",
        "tracker.init.layers=5"]


def run_track(tmp_path: Path, *overrides: str) -> subprocess.CompletedProcess:
    """``mocap track`` in this process (:mod:`tests.cli.in_process`): what the run writes is the
    point, not the process."""
    return mocap("track", f"hydra.run.dir={tmp_path}", *overrides)


@pytest.mark.slow
def test_the_crowd_is_tracked_person_by_person(tmp_path):
    # 20 frames: people 0-2 from the start (0 and 1 cross at frame 10), 2 leaves after frame 9,
    # 3 enters at frame 3 and 4 at frame 10
    r = run_track(tmp_path, "tracker=marker_people", "data=crowd", "data.frames=20", "init.mode=tracker",
                  "tracker.people.max_missed=3", *FAST)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["people"] == [0, 1, 2, 3, 4] and m["identity_switches"] == 0
    per = m["per_person"]
    assert [p["first_frame"] for p in per] == [0, 0, 0, 3, 10]
    assert all(p["latency_frames"] is not None and p["latency_frames"] <= 10 for p in per)
    assert all(p["pcp"] >= 0.9 and p["mpjpe_mm"] < 60 for p in per)
    leaver = m["assignment"]["2"]
    assert m["deaths"] == {"9": [leaver]} and m["ended_at"] == {"13": [leaver]}
    assert sorted(int(f) for f in m["births"]) == [0, 5, 12]
    a = load_people_motion(tmp_path)
    assert a["joints"].shape[:2] == (20, 5) and list(a["person_ids"]) == m["people"]
    p = list(a["person_ids"]).index(leaver)
    assert a["live"][:10, p].all() and not a["live"][10:, p].any() and a["ended"][p]
    assert np.isnan(a["joints"][10:, p]).all() and np.isfinite(a["joints"][:10, p]).all()
    with pytest.raises(MotionFileError, match="holds several people"):
        load_motion(tmp_path)
    assert (tmp_path / "manifest.json").is_file()
    entities = set(read_recording(tmp_path / "recording.rrd")["entities"])
    assert {f"/world/people/{i}/skeleton" for i in m["people"]} <= entities     # one entity (colour) each


@pytest.mark.slow           # the crowd is made before it is refused (~1 CPU s each, in this process)
@pytest.mark.parametrize(("overrides", "message"), [
    (["data=crowd", "init.mode=gt_noise"], "has no ground-truth pose chi: use init.mode=tracker"),
    (["data=walk_markers_small", "init.mode=tracker"], "has no skeleton grouping (Detections.person)"),
    (["data=crowd", "init.mode=tracker", "tracker.people.confirm_frames=0"],
     "setting people.confirm_frames = 0 is out of range"),
])
def test_what_it_refuses_is_said_in_one_line(tmp_path, overrides, message):
    r = mocap("track", f"hydra.run.dir={tmp_path}", "tracker=marker_people", *overrides)   # in this process
    assert r.returncode != 0 and message in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "metrics.json").exists()
