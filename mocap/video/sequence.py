"""A recording given as videos + calibration (+ keypoints, + masks) as a :class:`Sequence`
whose images are decoded lazily (:class:`mocap.video.frames.VideoFrames`).

    seq = load_video_sequence("../shared/data/pose2sim-demo", start=0, stop=100, step=2,
                              scale=0.25, segmentation={"method": "keypoint_grabcut"})

Videos are matched to cameras by name like keypoint folders (``cam01.mp4`` <-> ``cam_01``).
The rig is the calibration scaled by ``scale``; keypoints (when a folder is given) are
rescaled to it and renumbered to the selected frames. Masks come from a sequence folder made
by ``mocap segment`` (``masks=``) or are computed at load time (``segmentation=``,
see :func:`mocap.video.segmentation.segment_sequence`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocap.cameras import load_calibration
from mocap.data.openpose import _find_calibration, load_openpose_sequence
from mocap.data.sequence import Detections, Sequence
from mocap.data.sequence_io import gt_opted_out
from mocap.data.source_settings import VideoSource, recording_settings
from mocap.video.frames import VideoFrames, frame_range, match_videos, video_info

_S = VideoSource()      # the defaults


def rescale_detections(det: Detections, frames: list[int], sx: float, sy: float) -> Detections:
    """Keep detections of source ``frames`` (renumbered 0..), pixel coordinates scaled by
    (sx, sy) in OpenCV's pixel-centre convention."""
    index = {n: i for i, n in enumerate(frames)}
    keep = np.array([f in index for f in det.frame], bool)
    xy = det.xy[keep].copy()
    xy[:, 0] = sx * (xy[:, 0] + 0.5) - 0.5
    xy[:, 1] = sy * (xy[:, 1] + 0.5) - 0.5
    return Detections(det.labels, np.array([index[f] for f in det.frame[keep]], np.int64),
                      det.view[keep], det.label[keep], xy, det.confidence[keep])


def load_video_sequence(path: str | Path, *, videos: str = _S.videos,
                        calibration: str | None = _S.calibration, keypoints: str | None = _S.keypoints,
                        layout: str = _S.layout,
                        person: str = _S.person, fps: float | None = _S.fps, start: int = _S.start,
                        stop: int | None = _S.stop, step: int = _S.step, scale: float = _S.scale,
                        size_tolerance: float = _S.size_tolerance, masks: str | None = _S.masks,
                        segmentation: Mapping | None = _S.segmentation,
                        refine_masks: Mapping | None = _S.refine_masks,
                        name: str | None = _S.name, gt: str | None = _S.gt) -> Sequence:
    """A :class:`Sequence` with lazy video images, the scaled rig, keypoint detections (if
    ``keypoints``) and masks (if ``masks`` or ``segmentation``). refine_masks: options of
    :func:`mocap.video.person_masks.combine_masks` (e.g. ``{grabcut: true, background:
    masked_median}``) applied to the person probabilities of a ``mocap detect`` masks folder
    (``masks=<out>/masks``), guided by the sequence's keypoints. gt: a ground-truth file (default:
    the folder's gt.npz, when there is one), one frame per keypoint frame as for
    :func:`mocap.data.openpose.load_openpose_sequence`; the tracked frames are taken from it."""
    root = Path(path)
    if not root.is_dir():
        raise FileNotFoundError(f"recording folder not found: {root}")
    calib = root / calibration if calibration is not None else _find_calibration(root)
    full_rig = load_calibration(calib)
    paths = match_videos(full_rig.names, root / videos)
    total = min(video_info(p).frames for p in paths)
    frames = frame_range(total, start, stop, step)
    images = VideoFrames(paths, [tuple(s) for s in full_rig.sizes], frames, scale,
                         names=full_rig.names, size_tolerance=size_tolerance)
    rig = full_rig.scaled(scale)
    W, H = (int(x) for x in full_rig.sizes[0])
    w, h = images.width, images.height
    fps = float(fps) if fps else images.infos[0].fps
    det = truth = None
    resolved = {"layout": layout, "person": person}
    if keypoints:
        op = load_openpose_sequence(root, calibration=calibration, keypoints=keypoints, layout=layout,
                                    fps=fps, person=person, gt=gt)
        first = op.meta["first_frame"]
        det = rescale_detections(op.detections, [n - first for n in frames], w / W, h / H)
        resolved = {"layout": op.meta["layout"], "layout_setting": layout, "person": person}
        if op.gt is not None:
            truth = _ground_truth_frames(op.gt, [n - first for n in frames], op.meta["gt"])
            resolved["gt"] = op.meta["gt"]
    elif not gt_opted_out(gt) and (gt is not None or (root / "gt.npz").is_file()):
        raise ValueError(f"ground truth {gt or root / 'gt.npz'} needs keypoints (its frame 0 is the first "
                         "keypoint frame): set keypoints, or data.gt=none to track without it")
    meta = {"source": str(root), "calibration": str(calib), "videos": [str(p) for p in paths],
            "source_frames": frames, "scale": float(scale), **resolved}
    seq = Sequence(name=name or root.name, rig=rig, fps=fps / step, images=images, detections=det,
                   gt=truth, meta=meta)
    if refine_masks is not None and masks is None:
        raise ValueError("refine_masks needs masks=<mocap detect output>/masks (the detector's "
                         "probabilities)")
    if masks is not None and refine_masks is not None:
        seq = replace(seq, masks=refined_detector_masks(Path(masks), seq, dict(refine_masks)),
                      meta={**meta, "refine_masks": dict(refine_masks)})
    elif masks is not None:
        seq = replace(seq, masks=masks_from_folder(Path(masks), seq))
    elif segmentation is not None:
        from mocap.video.segmentation import segment_sequence

        seg = segment_sequence(seq, **dict(segmentation))
        seq = replace(seq, masks=seg.masks, meta={**meta, "segmentation": seg.info})
    return seq


def refined_detector_masks(folder: Path, seq: Sequence, options: dict) -> np.ndarray:
    """(F, C, H, W) bool: ``mocap detect``'s person probabilities in ``folder`` combined with
    GrabCut / a background model / carving (:func:`mocap.video.person_masks.combine_masks`)."""
    from mocap.video.detect import read_masks
    from mocap.video.person_masks import combine_masks
    from mocap.video.segmentation import keypoint_dict

    if not (folder / seq.rig.names[0]).is_dir():
        raise ValueError(f"refine_masks: {folder} is not a mocap detect masks folder "
                         f"(no {seq.rig.names[0]}/ inside)")
    prob = read_masks(folder, seq.rig.names, seq.meta["source_frames"], seq.image_size, probability=True)
    images = np.stack([np.asarray(seq.images[f]) for f in range(seq.num_frames)])
    det = seq.detections
    kps = [[keypoint_dict(det.select(f, c)) if det is not None else {} for c in range(seq.num_views)]
           for f in range(seq.num_frames)]
    return combine_masks(images, prob, kps, seq.rig, **options)


def masks_from_folder(folder: Path, seq: Sequence) -> np.ndarray:
    """(F, C, H, W) bool masks of a segmented sequence folder, checked against ``seq``; or of
    the ``masks/`` folder of ``mocap detect`` (per-camera folders of PNGs, resized to ``seq``)."""
    from mocap.data.sequence_io import load_sequence

    if (folder / seq.rig.names[0]).is_dir() and not (folder / "sequence.json").is_file():
        from mocap.video.detect import read_masks

        return read_masks(folder, seq.rig.names, seq.meta["source_frames"], seq.image_size)

    seg = load_sequence(folder, images=False)
    if seg.masks is None:
        raise ValueError(f"{folder}: the sequence folder has no masks")
    src = seg.meta.get("source_frames")
    want = seq.meta.get("source_frames")
    if src is not None and want is not None and list(src) != list(want):
        raise ValueError(f"{folder}: masks are for source frames {src[:3]}...{src[-1]} "
                         f"({len(src)}), the sequence asks for {want[:3]}...{want[-1]} ({len(want)})")
    if seg.masks.shape[1:] != (seq.num_views, seq.image_size[1], seq.image_size[0]):
        raise ValueError(f"{folder}: masks are {seg.masks.shape[1:]} (C, H, W), the sequence needs "
                         f"{(seq.num_views, seq.image_size[1], seq.image_size[0])}: same scale?")
    return seg.masks


def _ground_truth_frames(gt, idx: list[int], path: str):
    """The ground truth of the tracked frames ``idx`` (indices into its frames)."""
    bad = [i for i in idx if not 0 <= i < gt.num_frames]
    if bad:
        raise ValueError(f"{path}: field 'joints' has {gt.num_frames} frames, the video frames tracked need "
                         f"frame {bad[0]} (frame 0: the first keypoint frame)")
    return replace(gt, **{k: None if getattr(gt, k) is None else getattr(gt, k)[idx]
                          for k in ("joints", "joint_valid", "chi", "markers", "surface")})


def video_sequence(*, body=None, **keys) -> Sequence:
    """Hydra entry point (``conf/data/pose2sim_demo_video.yaml``); ``body`` is unused; ``keys``:
    the settings that differ from :class:`~mocap.data.source_settings.VideoSource`'s defaults.
    An unknown setting is refused by name (before any file is read)."""
    path, options = recording_settings(VideoSource, keys, "video recording")
    return load_video_sequence(path, **options)


def load_background_clip(folder: str | Path, seq: Sequence, max_frames: int = 60) -> np.ndarray:
    """(B, C, H, W, 3) RGB frames of an empty-scene clip (one video per camera in ``folder``,
    matched by name like the recording's), at ``seq``'s calibration and scale."""
    folder = Path(folder)
    meta = seq.meta
    from mocap.cameras import load_calibration as _load

    full = _load(meta["calibration"])
    paths = match_videos(full.names, folder)
    total = min(video_info(p).frames for p in paths)
    step = max(1, total // max_frames)
    frames = VideoFrames(paths, [tuple(s) for s in full.sizes], list(range(0, total, step)),
                         meta.get("scale", 1.0), names=full.names)
    return np.asarray(frames)
