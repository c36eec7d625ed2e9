"""Frames tracked without any detection (issue 37: after ``mocap detect --step 2`` the keypoint
tracker ran 9 of 19 frames blind, unflagged): run_metrics lists them in
``frames_without_detections``, and the recording plots the detection count (0 there)."""

from __future__ import annotations

import dataclasses

import numpy as np

import mocap
from mocap.data.sequence import Detections
from mocap.eval.run_metrics import frames_without_detections, run_metrics


def without_frames(det: Detections, drop: list[int]) -> Detections:
    keep = ~np.isin(det.frame, drop)
    return Detections(det.labels, det.frame[keep], det.view[keep], det.label[keep], det.xy[keep],
                      det.confidence[keep], None if det.person is None else det.person[keep])


def test_frames_without_detections_lists_the_frames_no_view_saw():
    det = Detections(("a",), np.array([0, 0, 2, 5]), np.array([0, 1, 1, 0]), np.zeros(4, int),
                     np.zeros((4, 2)), np.ones(4))
    assert frames_without_detections(det, 6) == [1, 3, 4]
    assert frames_without_detections(det, 3) == [1]                 # only the frames tracked


def test_a_run_with_blind_frames_says_which(body):
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=4, seed=0, masks=False,
                                   detections={"enabled": True, "labelled": True, "occlusion": False})
    seq = dataclasses.replace(seq, detections=without_frames(seq.detections, [2]))
    result = mocap.track(seq, "marker_apf", body=body, particles=10, layers=2)
    m = run_metrics(body, seq, result.estimates, result.seconds)
    assert m["frames_without_detections"] == [2]


def test_the_recording_plots_the_detections_per_frame(tmp_path):
    import json

    from mocap.recording.reader import read_recording
    from tests.cli.in_process import mocap as command

    # in this process (tests/cli/in_process.py): the run's recording is the point, not the process
    r = command("track", f"hydra.run.dir={tmp_path}", "tracker=marker_apf", "data=walk_markers_small",
                "frames=3", "tracker.particles=10", "tracker.layers=2")
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads((tmp_path / "metrics.json").read_text())["frames_without_detections"] == []
    series = read_recording(tmp_path / "recording.rrd")["scalars"]["/plots/input/detections"]
    assert sorted(series) == [0, 1, 2] and all(v > 0 for v in series.values())
