"""The lazy video loader against OpenCV's own sequential reader, and its errors on bad input."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from mocap.video.frames import VideoError, VideoFrames, fit_to_size, frame_range
from mocap.video.sequence import load_video_sequence

DEMO_CANDIDATES = [Path(__file__).resolve().parents[2].parent / "shared" / "data" / "pose2sim-demo",
                   Path(os.environ.get("POSE2SIM_DEMO", "/nonexistent"))]
DEMO = next((p for p in DEMO_CANDIDATES if (p / "videos").is_dir()), None)


def write_clip(path: Path, frames: int = 12, size=(64, 48), seed: int = 0) -> Path:
    """A short MJPG clip of noisy numbered frames."""
    rng = np.random.default_rng(seed)
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, size)
    for i in range(frames):
        img = rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)
        cv2.putText(img, str(i), (5, 30), cv2.FONT_HERSHEY_SIMPLEX, 1, (255, 255, 255), 2)
        w.write(img)
    w.release()
    return path


def opencv_frames(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, img = cap.read()
        if not ok:
            return out
        out.append(img[..., ::-1])


def test_video_frames_equal_opencv_sequential_reader_with_range_and_jumps(tmp_path):
    a, b = write_clip(tmp_path / "cam_a.avi", seed=1), write_clip(tmp_path / "cam_b.avi", seed=2)
    ref_a, ref_b = opencv_frames(a), opencv_frames(b)
    assert len(ref_a) == 12
    frames = frame_range(12, start=1, stop=11, step=3)                # 1, 4, 7, 10
    vid = VideoFrames([a, b], frames=frames)
    assert vid.shape == (4, 2, 48, 64, 3) and len(vid) == 4
    for f in [0, 2, 1, 3, 3, 0]:                                      # backwards jumps reopen
        np.testing.assert_array_equal(vid[f, 0], ref_a[frames[f]])
        np.testing.assert_array_equal(vid[f][1], ref_b[frames[f]])


def test_downscale_matches_cv2_resize_and_scaled_camera_size(tmp_path):
    a = write_clip(tmp_path / "a.avi")
    vid = VideoFrames([a], scale=0.5)
    assert vid.shape[2:4] == (24, 32)
    want = cv2.resize(np.ascontiguousarray(opencv_frames(a)[5]), (32, 24), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(vid[5, 0], want)


def test_truncated_video_error_names_file_and_frame(tmp_path):
    a = write_clip(tmp_path / "a.avi")
    data = a.read_bytes()
    bad = tmp_path / "cut.avi"
    bad.write_bytes(data[: len(data) // 2])
    vid = VideoFrames([bad])                     # the header still claims 12 frames
    with pytest.raises(VideoError) as err:
        for f in range(len(vid)):
            vid[f]
    assert "cut.avi" in str(err.value) and f"frame {err.value.frame}" in str(err.value)
    assert 0 < err.value.frame < 12


def test_unreadable_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "noise.mp4"
    bad.write_bytes(os.urandom(2000))
    with pytest.raises(VideoError, match="noise.mp4"):
        VideoFrames([bad])
    with pytest.raises(FileNotFoundError, match="missing.avi"):
        VideoFrames([tmp_path / "missing.avi"])


def test_different_frame_counts_per_view_are_rejected(tmp_path):
    a, b = write_clip(tmp_path / "a.avi", frames=12), write_clip(tmp_path / "b.avi", frames=10)
    with pytest.raises(ValueError, match=r"different frame counts.*a: 12.*b: 10"):
        VideoFrames([a, b])


def test_calibration_size_small_mismatch_pads_large_mismatch_errors(tmp_path):
    a = write_clip(tmp_path / "a.avi", size=(64, 48))
    with pytest.warns(UserWarning, match="padding"):
        vid = VideoFrames([a], sizes=[(65, 48)], size_tolerance=0.02)
    img = vid[0, 0]
    assert img.shape == (48, 65, 3)
    np.testing.assert_array_equal(img[:, :64], opencv_frames(a)[0])
    assert not img[:, 64:].any()
    with pytest.raises(ValueError, match=r"a.avi is 64x48 but its calibration says 80x48"):
        VideoFrames([a], sizes=[(80, 48)])


def test_fit_to_size_crops_and_pads_at_right_and_bottom():
    img = np.arange(12, dtype=np.uint8).reshape(3, 4)
    np.testing.assert_array_equal(fit_to_size(img, 3, 2), img[:2, :3])
    out = fit_to_size(img, 5, 4)
    np.testing.assert_array_equal(out[:3, :4], img)
    assert out.shape == (4, 5) and not out[3].any() and not out[:, 4].any()


@pytest.mark.skipif(DEMO is None, reason="Pose2Sim demo not present")
def test_demo_video_sequence_scales_rig_and_keypoints():
    with pytest.warns(UserWarning, match="1080x1920"):
        seq = load_video_sequence(DEMO, start=10, stop=20, step=5, scale=0.25)
    assert seq.num_frames == 2 and seq.images.shape == (2, 4, 480, 272, 3)
    assert tuple(seq.rig.sizes[0]) == (272, 480) and seq.fps == 12.0
    full = load_video_sequence(DEMO, start=15, stop=16, scale=1.0)
    a = full.detections.select(0)
    b = seq.detections.select(1)
    np.testing.assert_allclose((a.xy + 0.5) * 0.25 - 0.5, b.xy)
