"""The real-video pipeline end to end on the Pose2Sim demo (skipped where it is absent):
segment -> mask sequence folder -> video_check with the keypoint tracker, and the mask-quality
reference against the segmentation stage."""

from __future__ import annotations

import json
import os
import subprocess
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from mocap.video.segmentation import iou, segment_sequence
from mocap.video.sequence import load_video_sequence
from tests.cli.in_process import mocap

REPO = Path(__file__).resolve().parents[2]
CANDIDATES = [REPO.parent / "shared" / "data" / "pose2sim-demo",
              Path(os.environ.get("POSE2SIM_DEMO", "/nonexistent"))]
DEMO = next((p for p in CANDIDATES if (p / "videos").is_dir()), None)
REF = REPO / "tests" / "data" / "pose2sim_demo_reference"
pytestmark = [pytest.mark.skipif(DEMO is None, reason="Pose2Sim demo not present"),
              pytest.mark.slow]           # ~30 s each on an idle 2-core machine, decoding + GrabCut


def run(command: str, *overrides: str) -> subprocess.CompletedProcess:
    """``mocap <command> *overrides`` in this process (:mod:`tests.cli.in_process`): what it
    writes is the point; one BLAS thread, as the process was given."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        out = mocap(command, *overrides)
    assert out.returncode == 0, out.stderr[-3000:]
    return out


def test_segment_then_video_check_with_the_keypoint_tracker(tmp_path):
    seg = tmp_path / "seg"
    run("segment", f"data.path={DEMO}", "data.start=0", "data.stop=6", "data.step=2", f"out={seg}")
    meta = json.loads((seg / "sequence.json").read_text())
    assert meta["frames"] == 3 and meta["image_size"] == [272, 480]
    assert meta["meta"]["source_frames"] == [0, 2, 4] and meta["meta"]["segmentation"]["multiview"]
    run("video-check", "tracker=marker_apf", f"data.path={DEMO}", f"data.masks={seg}", "data.stop=6",
        "tracker.particles=20", "tracker.layers=3", f"hydra.run.dir={tmp_path / 'run'}")
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["frames"] == 3 and 0.3 < m["silhouette_iou"] <= 1.0
    # the keypoint tracker reprojects onto its own keypoints within a few tens of full-res px
    assert m["reprojection"]["fitted_median_px"] < 40
    assert (tmp_path / "run" / "motion.npz").is_file() and (tmp_path / "run" / "recording.rrd").is_file()


def test_reference_masks_are_complete_and_the_guided_method_beats_the_median():
    ann = json.loads((REF / "annotations.json").read_text())
    assert len(ann["frames"]) >= 5 and len(ann["items"]) >= 20
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = load_video_sequence(DEMO, start=0, stop=100, step=20, scale=ann["scale"])
    ref = np.stack([[cv2.imread(str(REF / f"{cam}_{n:04d}.png"), 0) > 127 for cam in seq.rig.names]
                    for n in seq.meta["source_frames"]])
    assert ref.shape == (5, 4, 480, 272) and (ref.mean(axis=(2, 3)) > 0.03).all()
    guided = segment_sequence(seq, method="keypoint_grabcut", background="none")
    plain = segment_sequence(seq, method="median", keypoints=False)
    score = lambda r: np.mean([iou(r.masks[f, c], ref[f, c]) for f in range(5) for c in range(4)])  # noqa: E731
    assert score(guided) > 0.7 > score(plain)
