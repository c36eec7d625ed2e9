"""Calibration input on disk: per camera, board images or a video, found in a folder.

A folder holds either one sub-folder per camera (named as the camera; its images, or one
video) or the files themselves: a video per camera (``cam01.mp4`` -> camera ``cam01``) or
images named ``<camera>_<number>.<ext>`` (``cam01_03.jpg`` -> camera ``cam01``, frame 3).
Frames with the same number in several cameras are the same moment (board extrinsics).
Every input is opened before any work: a video that does not open, images of different sizes
or (where frames must be synchronous) videos of different lengths are refused with the camera.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from mocap.calibration.errors import CalibrationInputError

IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")
VIDEO_EXTENSIONS = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")


@dataclass(frozen=True)
class CameraSource:
    """camera name; images (sorted) or one video; size (width, height); frames: frame count
    (videos) or number of images."""

    name: str
    images: tuple[Path, ...] = ()
    video: Path | None = None
    size: tuple[int, int] = (0, 0)
    frames: int = 0


def _frame_number(path: Path) -> int:
    nums = re.findall(r"\d+", path.stem)
    return int(nums[-1]) if nums else 0


def _probe_video(name: str, path: Path) -> CameraSource:
    cap = cv2.VideoCapture(str(path))
    try:
        ok, frame = cap.read() if cap.isOpened() else (False, None)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if ok else 0
    finally:
        cap.release()
    if not ok:
        raise CalibrationInputError(name, f"video {path} does not open or has no frame: check the file "
                                          "(re-encode it, e.g. ffmpeg -i IN -c:v libx264 OUT.mp4)")
    return CameraSource(name, video=path, size=(frame.shape[1], frame.shape[0]), frames=max(count, 1))


def _probe_images(name: str, paths: list[Path]) -> CameraSource:
    size = None
    for p in paths:
        img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise CalibrationInputError(name, f"image {p} does not open: remove or replace it")
        s = (img.shape[1], img.shape[0])
        if size is not None and s != size:
            raise CalibrationInputError(name, f"image {p.name} is {s[0]}x{s[1]}, the camera's first image is "
                                              f"{size[0]}x{size[1]}: one camera's images must share a size")
        size = s
    return CameraSource(name, images=tuple(paths), size=size, frames=len(paths))


def find_sources(folder: str | Path) -> list[CameraSource]:
    """The cameras of a folder (see the module docstring), sorted by name, every file opened."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"calibration input folder not found: {folder}")
    groups: dict[str, list[Path]] = {}
    subdirs = sorted(p for p in folder.iterdir() if p.is_dir())
    if subdirs:
        for d in subdirs:
            groups[d.name] = sorted(p for p in d.iterdir()
                                    if p.suffix.lower() in IMAGE_EXTENSIONS + VIDEO_EXTENSIONS)
    else:
        for p in sorted(folder.iterdir()):
            ext = p.suffix.lower()
            if ext in VIDEO_EXTENSIONS:
                groups.setdefault(p.stem, []).append(p)
            elif ext in IMAGE_EXTENSIONS:
                groups.setdefault(re.sub(r"[_\-. ]?\d+$", "", p.stem) or p.stem, []).append(p)
    if not groups:
        raise FileNotFoundError(f"{folder}: no images ({', '.join(IMAGE_EXTENSIONS)}) or videos "
                                f"({', '.join(VIDEO_EXTENSIONS)}) found")
    out = []
    for name, paths in sorted(groups.items()):
        videos = [p for p in paths if p.suffix.lower() in VIDEO_EXTENSIONS]
        if not paths:
            raise CalibrationInputError(name, f"{folder / name} holds no image or video")
        if videos and len(paths) > 1:
            raise CalibrationInputError(name, f"give one video or images, not {len(paths)} files and a video")
        out.append(_probe_video(name, videos[0]) if videos else _probe_images(name, paths))
    return out


def check_same_length(sources: list[CameraSource]) -> None:
    """Synchronous videos must have the same number of frames."""
    videos = [s for s in sources if s.video is not None]
    if not videos:
        return
    counts = [s.frames for s in videos]
    common = max(set(counts), key=counts.count)
    for s in videos:
        if s.frames != common:
            raise CalibrationInputError(s.name, f"video {s.video.name} has {s.frames} frames, the others "
                                                f"{common}: the videos must be synchronised and of one "
                                                "length (trim them to the same frames)")


def frames(source: CameraSource, max_frames: int = 60) -> Iterator[tuple[str, str, np.ndarray]]:
    """(frame key, label, grayscale image): every image (key: the number in its name, label:
    the file name), or up to ``max_frames`` frames evenly spread through a video (key: the
    frame index, label: ``<video> frame N``)."""
    if source.video is None:
        for p in source.images:
            yield f"{_frame_number(p):06d}", p.name, cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        return
    picks = np.linspace(0, source.frames - 1, min(max_frames, source.frames)).round().astype(int)
    wanted = set(picks.tolist())
    cap = cv2.VideoCapture(str(source.video))
    try:
        i = 0
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            if i in wanted:
                yield f"{i:06d}", f"{source.video.name} frame {i}", cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
            i += 1
    finally:
        cap.release()
