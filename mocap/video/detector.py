"""The built-in offline 2D detector: MediaPipe's BlazePose (legacy ``solutions.pose``), whose
models ship inside the ``mediapipe==0.10.14`` wheel, for 33 keypoints (the ``MEDIAPIPE_33``
layout of :mod:`mocap.data.openpose`) with confidences and a soft person mask per image.

    detector = PoseDetector()                    # model_complexity=1, segmentation head on
    det = detector(rgb)                          # rgb (H, W, 3) uint8
    det.keypoints                                # (33, 3) x, y (pixels, OpenCV's pixel centres), confidence
    det.mask                                     # (H, W) float32 person probability in [0, 1]
    detector.close()

One detector follows one person through one video (tracking mode: the previous frame's
landmarks give the next frame's region of interest); use one detector per view. ``mediapipe``
is an optional dependency (``scripts/setup_env.sh`` installs it: see requirements-detect.txt);
:func:`detector_available` says whether it imports.
"""

from __future__ import annotations

import contextlib
import io
import os
import warnings
from dataclasses import dataclass

import numpy as np

#: number of BlazePose landmarks (the MEDIAPIPE_33 layout)
NUM_KEYPOINTS = 33


def detector_available() -> bool:
    """True when ``mediapipe`` (with its legacy ``solutions.pose``) imports."""
    try:
        _import_mediapipe()
    except ImportError:
        return False
    return True


def _import_mediapipe():
    os.environ.setdefault("GLOG_minloglevel", "2")        # no INFO lines from the graph per detector
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    # mediapipe 0.10.14 calls protobuf's deprecated GetPrototype on every frame
    warnings.filterwarnings("ignore", message="SymbolDatabase.GetPrototype", category=UserWarning)
    try:
        from mediapipe.python.solutions import pose as mp_pose
    except ImportError as exc:
        raise ImportError("the detector needs mediapipe==0.10.14 (bash scripts/setup_env.sh installs it; "
                          f"by hand: see requirements-detect.txt): {exc}") from None
    return mp_pose


@dataclass(frozen=True)
class Detection:
    """One image's detection. keypoints: (33, 3) x, y in pixels of the image given
    (OpenCV's convention: integer coordinates at pixel centres), confidence = MediaPipe's
    visibility in [0, 1]; all zero when no person was found (``found`` False).
    mask: (H, W) float32 person probability (None without the segmentation head)."""

    keypoints: np.ndarray
    mask: np.ndarray | None
    found: bool


@dataclass(frozen=True)
class DetectorSettings:
    model_complexity: int = 1            # 0 lite, 1 full (the wheel ships these two), 2 heavy (not shipped)
    segmentation: bool = True            # the person-mask head
    min_detection_confidence: float = 0.5
    min_tracking_confidence: float = 0.5
    smooth: bool = True                  # MediaPipe's landmark / mask smoothing across frames

    def __post_init__(self):
        if self.model_complexity not in (0, 1):
            raise ValueError(f"detector model_complexity must be 0 or 1 (the models shipped in the "
                             f"mediapipe wheel), got {self.model_complexity!r}")
        for name in ("min_detection_confidence", "min_tracking_confidence"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"detector {name} must be in [0, 1], got {v!r}")


class PoseDetector:
    """BlazePose on a stream of RGB images of one view (see the module's docstring)."""

    def __init__(self, settings: DetectorSettings | None = None):
        self.settings = settings or DetectorSettings()
        mp_pose = _import_mediapipe()
        s = self.settings
        # the graph's start-up prints TensorFlow Lite lines on stderr: keep the terminal clean
        with contextlib.redirect_stderr(io.StringIO()):
            self._pose = mp_pose.Pose(static_image_mode=False, model_complexity=s.model_complexity,
                                      smooth_landmarks=s.smooth, enable_segmentation=s.segmentation,
                                      smooth_segmentation=s.smooth,
                                      min_detection_confidence=s.min_detection_confidence,
                                      min_tracking_confidence=s.min_tracking_confidence)

    def __call__(self, rgb: np.ndarray) -> Detection:
        rgb = np.ascontiguousarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"detector input must be (H, W, 3) uint8 RGB, got {rgb.shape} {rgb.dtype}")
        H, W = rgb.shape[:2]
        res = self._pose.process(rgb)
        if res.pose_landmarks is None:
            return Detection(np.zeros((NUM_KEYPOINTS, 3)), np.zeros((H, W), np.float32)
                             if self.settings.segmentation else None, False)
        lm = res.pose_landmarks.landmark
        kp = np.array([(p.x, p.y, p.visibility) for p in lm], np.float64)
        kp[:, 0] = kp[:, 0] * W - 0.5               # normalised [0, 1] image edges -> pixel centres
        kp[:, 1] = kp[:, 1] * H - 0.5
        kp[:, 2] = np.clip(kp[:, 2], 1e-3, 1.0)     # 0 means "not found" in OpenPose files
        mask = None
        if self.settings.segmentation:
            mask = (np.zeros((H, W), np.float32) if res.segmentation_mask is None
                    else np.asarray(res.segmentation_mask, np.float32).reshape(H, W))
        return Detection(kp, mask, True)

    def close(self) -> None:
        self._pose.close()

    def __enter__(self) -> PoseDetector:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
