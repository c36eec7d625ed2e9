"""Video files in the data path: frames decoded on demand, never exploded to disk.

    frames = VideoFrames(["cam01.mp4", ...], calibration_sizes=[(1088, 1920), ...],
                         frames=range(0, 100, 2), scale=0.25)
    frames[f]        # (C, H, W, 3) uint8 RGB of output frame f, all views
    frames[f, c]     # (H, W, 3) one view

:class:`VideoFrames` behaves like the ``(F, C, H, W, 3)`` image array of a
:class:`~mocap.data.sequence.Sequence` (``shape``, ``len``, integer indexing), so the trackers,
the recording sink and the segmentation stage use it unchanged. Each view keeps one
``cv2.VideoCapture`` open and reads forward (``grab`` skips frames exactly; a backwards jump
reopens the file), so the frames are exactly those of OpenCV's sequential reader.

Image size vs calibration: a video whose size differs from its camera's calibrated size by at
most ``size_tolerance`` (a fraction of each side; default 2 %) is padded (black) or cropped at
its right / bottom edge to the calibrated size, with a warning. Pixel coordinates from the top
left corner are unchanged, so the calibration's intrinsics and keypoints made at the
calibrated size still apply. (The Pose2Sim demo's Calib.toml says 1088 px wide for all four
cameras while the videos of cams 1-2 are 1080 wide: the keypoints overlay the padded frames
exactly.) A larger difference is an error: the calibration belongs to another video.
"""

from __future__ import annotations

import re
import warnings
from collections import OrderedDict
from collections.abc import Sequence as Seq
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np


class VideoError(ValueError):
    """A video that cannot be read as asked; names the file and, where known, the frame."""

    def __init__(self, path: str | Path, reason: str, frame: int | None = None):
        where = f"{path}" + (f", frame {frame}" if frame is not None else "")
        super().__init__(f"{where}: {reason}")
        self.path, self.frame, self.reason = str(path), frame, reason


@dataclass(frozen=True)
class VideoInfo:
    path: str
    width: int
    height: int
    frames: int          # as the container reports it (checked when decoding)
    fps: float


def video_info(path: str | Path) -> VideoInfo:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"video not found: {path}")
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise VideoError(path, "OpenCV cannot open this file as a video")
        info = VideoInfo(str(path), int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
                         int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
                         int(cap.get(cv2.CAP_PROP_FRAME_COUNT)), float(cap.get(cv2.CAP_PROP_FPS)))
    finally:
        cap.release()
    if info.width <= 0 or info.height <= 0 or info.frames <= 0:
        raise VideoError(path, f"no video stream ({info.width}x{info.height}, {info.frames} frames)")
    return info


class _Reader:
    """Forward reader of one video; ``read(n)`` returns source frame n (BGR)."""

    def __init__(self, info: VideoInfo):
        self.info, self.cap, self.next = info, None, 0

    def _open(self) -> None:
        if self.cap is not None:
            self.cap.release()
        self.cap = cv2.VideoCapture(self.info.path)
        if not self.cap.isOpened():
            raise VideoError(self.info.path, "OpenCV cannot open this file as a video")
        self.next = 0

    def read(self, n: int) -> np.ndarray:
        if self.cap is None or n < self.next:
            self._open()
        while self.next < n:
            if not self.cap.grab():
                raise self._error(self.next)
            self.next += 1
        ok, img = self.cap.read()
        if not ok or img is None:
            raise self._error(n)
        self.next += 1
        return img

    def _error(self, n: int) -> VideoError:
        self.close()
        return VideoError(self.info.path, f"could not decode frame {n} (the file reports "
                                          f"{self.info.frames} frames: truncated or corrupt?)", frame=n)

    def close(self) -> None:
        if self.cap is not None:
            self.cap.release()
        self.cap, self.next = None, 0


def fit_to_size(img: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pad (black) or crop ``img`` (H, W, ...) at its right / bottom edge to (height, width)."""
    img = img[:height, :width]
    ph, pw = height - img.shape[0], width - img.shape[1]
    if ph or pw:
        img = cv2.copyMakeBorder(img, 0, ph, 0, pw, cv2.BORDER_CONSTANT, value=0)
    return img


def check_sizes(infos: Seq[VideoInfo], sizes: Seq[tuple[int, int]], names: Seq[str],
                tolerance: float = 0.02) -> list[bool]:
    """Per view: True when the video must be padded / cropped to its calibrated size (warns);
    raises ValueError when the difference exceeds ``tolerance`` of a side."""
    out = []
    for info, (w, h), name in zip(infos, sizes, names, strict=True):
        if (info.width, info.height) == (int(w), int(h)):
            out.append(False)
            continue
        if abs(info.width - w) > tolerance * w or abs(info.height - h) > tolerance * h:
            raise ValueError(f"camera {name!r}: video {info.path} is {info.width}x{info.height} but its "
                             f"calibration says {int(w)}x{int(h)} (more than {tolerance:.0%} off: wrong "
                             "calibration or resized video)")
        warnings.warn(f"camera {name!r}: video {info.path} is {info.width}x{info.height}, calibration "
                      f"{int(w)}x{int(h)}: padding / cropping at the right and bottom edges",
                      stacklevel=3)
        out.append(True)
    return out


def check_frame_counts(infos: Seq[VideoInfo], names: Seq[str]) -> int:
    """The common frame count; raises ValueError naming each view's count when they differ."""
    counts = {name: info.frames for info, name in zip(infos, names, strict=True)}
    if len(set(counts.values())) != 1:
        raise ValueError("videos have different frame counts per view: "
                         + ", ".join(f"{n}: {k}" for n, k in counts.items())
                         + " (trim them to the synchronised range first)")
    return infos[0].frames


def frame_range(total: int, start: int = 0, stop: int | None = None, step: int = 1) -> list[int]:
    """Source frame indices of ``start:stop:step`` within ``total`` frames (checked)."""
    stop = total if stop is None else int(stop)
    if step < 1 or not 0 <= start < total or not start < stop <= total:
        raise ValueError(f"frame range start={start} stop={stop} step={step} is empty or outside "
                         f"the video's {total} frames")
    return list(range(int(start), stop, int(step)))


class VideoFrames:
    """Lazy ``(F, C, H, W, 3)`` uint8 RGB frames of C synchronised videos.

    paths: one video per view; sizes: (width, height) per view at full resolution (the
    calibration's; None: the first video's size for all); frames: source frame indices;
    scale: resize factor applied after padding (the size is ``Camera.scaled``'s).
    ``cache`` decoded frames are kept (most recent first out).
    """

    def __init__(self, paths: Seq[str | Path], sizes: Seq[tuple[int, int]] | None = None,
                 frames: Seq[int] | None = None, scale: float = 1.0,
                 names: Seq[str] | None = None, size_tolerance: float = 0.02, cache: int = 4):
        self.paths = [Path(p) for p in paths]
        names = list(names) if names is not None else [p.stem for p in self.paths]
        self.infos = [video_info(p) for p in self.paths]
        total = check_frame_counts(self.infos, names)
        if sizes is None:
            sizes = [(self.infos[0].width, self.infos[0].height)] * len(self.paths)
        self.full_sizes = [(int(w), int(h)) for w, h in sizes]
        if len(set(self.full_sizes)) != 1:
            raise ValueError(f"all views must share one image size, got {self.full_sizes}")
        check_sizes(self.infos, self.full_sizes, names, size_tolerance)
        self.source_frames = list(frames) if frames is not None else list(range(total))
        bad = [n for n in self.source_frames if not 0 <= n < total]
        if bad:
            raise ValueError(f"frames {bad[:5]} outside the videos' {total} frames")
        W, H = self.full_sizes[0]
        self.scale = float(scale)
        self.width, self.height = max(1, round(W * scale)), max(1, round(H * scale))
        self._readers = [_Reader(i) for i in self.infos]
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._cache_size = int(cache)

    @property
    def shape(self) -> tuple[int, int, int, int, int]:
        return (len(self.source_frames), len(self.paths), self.height, self.width, 3)

    ndim = 5
    dtype = np.dtype(np.uint8)

    def __len__(self) -> int:
        return len(self.source_frames)

    def view(self, f: int, c: int) -> np.ndarray:
        """(H, W, 3) RGB of output frame f in view c."""
        n = self.source_frames[f]
        img = self._readers[c].read(n)
        W, H = self.full_sizes[c]
        img = fit_to_size(img, W, H)
        if (self.width, self.height) != (W, H):
            img = cv2.resize(img, (self.width, self.height), interpolation=cv2.INTER_AREA)
        return np.ascontiguousarray(img[..., ::-1])

    def frame(self, f: int) -> np.ndarray:
        """(C, H, W, 3) RGB of output frame f."""
        f = int(f)
        if f < 0:
            f += len(self)
        if not 0 <= f < len(self):
            raise IndexError(f"frame {f} out of range for {len(self)} frames")
        if f not in self._cache:
            self._cache[f] = np.stack([self.view(f, c) for c in range(len(self.paths))])
            while len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return self._cache[f]

    def __getitem__(self, key):
        if isinstance(key, tuple):
            f, rest = key[0], key[1:]
            return self.frame(f)[rest]
        if isinstance(key, slice):
            return np.stack([self.frame(f) for f in range(*key.indices(len(self)))])
        return self.frame(key)

    def __array__(self, dtype=None, copy=None):
        arr = self[:]
        return arr if dtype is None else arr.astype(dtype)

    def close(self) -> None:
        for r in self._readers:
            r.close()


VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm")


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def match_videos(camera_names, folder: Path) -> list[Path]:
    """The video file of each camera (by name, ignoring case and separators)."""
    if not folder.is_dir():
        raise FileNotFoundError(f"video folder not found: {folder}")
    files = {_key(p.stem): p for p in sorted(folder.iterdir()) if p.suffix.lower() in VIDEO_SUFFIXES}
    missing = [n for n in camera_names if _key(n) not in files]
    if missing:
        raise FileNotFoundError(f"{folder}: no video for cameras {missing} (videos: "
                                f"{sorted(p.name for p in files.values())})")
    return [files[_key(n)] for n in camera_names]
