"""The recording holds the motion (chi per DOF), the hybrid's decisions, and the annealing
layers on their own timeline only."""

import numpy as np
import rerun as rr

from mocap.recording.columns import Columns
from mocap.recording.motion_log import MotionLogger
from mocap.recording.reader import read_recording
from mocap.trackers.base import Estimate


def test_decisions_and_motion_are_logged(tmp_path, body):
    path = tmp_path / "r.rrd"
    rec = rr.RecordingStream("t")
    rec.save(path)
    log = MotionLogger(body.dof_names)
    cols = Columns()
    chi = np.zeros(body.num_dofs)
    chi[7] = 0.5
    diags = [{"apf_called": 0, "misaligned_limbs": [], "limb_errors": {"l_knee": 0.1},
              "unexplained": {"l_hip": 0.001}, "unexplained_limit": {"l_hip": 0.005}},
             {"apf_called": 1, "misaligned_limbs": ["l_knee"], "limb_errors": {"l_knee": 0.4},
              "unexplained": {"l_hip": 0.02}, "unexplained_limit": {"l_hip": 0.006},
              "shape_update": {"energy_before": 0.2, "energy_after": 0.15, "accepted": True,
                               "shift_m": (0.0, 0.0, 0.01), "keyframes": (0, 1)}}]
    for f, d in enumerate(diags):
        rec.set_time("frame", sequence=f)
        log.frame(rec, cols, f, Estimate(chi * (f + 1), np.zeros(body.num_shape), d))
    cols.send(rec)
    rec.flush()
    rec.disconnect()
    info = read_recording(path)
    s = info["scalars"]
    assert s["/plots/decisions/apf_called"] == {0: 0.0, 1: 1.0}
    assert s["/plots/decisions/misaligned"] == {0: 0.0, 1: 1.0}
    assert s["/plots/decisions/limb_error/l_knee"] == {0: 0.1, 1: 0.4}
    assert s["/plots/decisions/unexplained/l_hip/share"] == {0: 0.001, 1: 0.02}
    assert s["/plots/decisions/unexplained/l_hip/limit"] == {0: 0.005, 1: 0.006}
    texts = {}
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        if chunk.entity_path == "/log/decisions":
            rb = chunk.to_record_batch()
            for f, t in zip(rb.column("frame").to_pylist(), rb.column("TextLog:text").to_pylist(),
                            strict=True):
                texts[f] = t[0]
    shapes = {}
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        if chunk.entity_path == "/log/shape":
            rb = chunk.to_record_batch()
            shapes.update(zip(rb.column("frame").to_pylist(),
                              [t[0] for t in rb.column("TextLog:text").to_pylist()], strict=True))
    assert shapes == {1: "frame 1: shape searched on keyframes 0, 1: E_S 0.2000 -> 0.1500, kept"}
    assert "unexplained" not in texts[0]
    assert texts[1] == "frame 1: APF on l_knee (unexplained pixels: l_hip 2.00% > 0.60%)"
    dof = body.dof_names[7]
    assert s[f"/plots/motion/chi/{dof}"][1] == np.rad2deg(1.0)
    assert "/log/decisions" in info["entities"] and "/run/shape" in info["entities"]


def test_annealing_layers_are_not_on_the_frame_timeline(short_run):
    for chunk in rr.chunk.RrdReader(str(short_run / "recording.rrd")).stream():
        if chunk.entity_path.startswith("/plots/layers"):
            names = chunk.to_record_batch().schema.names
            assert "anneal_step" in names and "frame" not in names


def test_a_patrol_search_is_named_in_the_decision_log(tmp_path, body):
    path = tmp_path / "r.rrd"
    rec = rr.RecordingStream("t")
    rec.save(path)
    d = {"apf_called": 1, "misaligned_limbs": [], "limb_errors": {"l_elbow": 0.05}, "patrol": True,
         "apf_free_dofs": ["l_shoulder_flex", "l_elbow_flex"]}
    rec.set_time("frame", sequence=4)
    cols = Columns()
    est = Estimate(np.zeros(body.num_dofs), np.zeros(body.num_shape), d)
    MotionLogger(body.dof_names).frame(rec, cols, 4, est)
    cols.send(rec)
    rec.flush()
    rec.disconnect()
    texts = [t[0] for chunk in rr.chunk.RrdReader(str(path)).stream() if chunk.entity_path == "/log/decisions"
             for t in chunk.to_record_batch().column("TextLog:text").to_pylist()]
    assert texts == ["frame 4: all limbs aligned; patrol search of l_shoulder_flex, l_elbow_flex"]
