"""The data sources' settings: one frozen dataclass per source, the only place its defaults are
written (``conf/data/*.yaml`` name a source and list only what differs; the default trees are
registered with Hydra by :mod:`mocap_cli.conf_schema`, so every key is overridable as
``data.<key>=...``). The loaders (:mod:`mocap.data.sources`) build them with
:func:`mocap.settings.settings_from_mapping`: an unknown key or a value of the wrong kind is a
one-line error naming the key, before any work. Imports none of the numeric stack.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

from mocap.checks import check_fps
from mocap.settings import settings_from_mapping


@dataclass(frozen=True)
class SyntheticSource:
    """A sequence generated in memory (``data=walk_small``, :func:`mocap.data.generate.make_synthetic`):
    ``cameras`` a camera preset's name (:mod:`mocap.presets`), a calibration file or a rig
    config; ``motion`` a motion of the library (:mod:`mocap.data.motion`) over ``frames`` frames
    at ``fps``; ``seed`` draws the subject's shape (``shape_scale`` times the shape space's
    spread) and the motion's variation; ``split`` the motion library's split; ``radius`` (m) the
    walk's circle; ``masks`` / ``images`` / ``marker_spheres`` what is rendered; ``detections``
    (options of :class:`mocap.data.synthetic.DetectionModel` with ``enabled``, ``occlusion``)
    and ``silhouette_noise`` (options of :class:`mocap.data.corruption.SilhouetteNoise`): null
    for none."""

    cameras: str | dict = "ring4_small"
    motion: str = "walk"
    frames: int = 20
    fps: float = 25.0
    seed: int = 0
    name: str = "synthetic"
    split: str = "test"
    shape_scale: float = 0.8
    radius: float = 1.0
    masks: bool = True
    images: bool = False
    marker_spheres: bool = False
    detections: dict | None = None
    silhouette_noise: dict | None = None

    def __post_init__(self) -> None:
        check_fps(self.fps, "data.fps")


@dataclass(frozen=True)
class FolderSource:
    """A sequence folder (``data=folder``, written by ``mocap make-dataset`` or converted data):
    ``path`` the folder (relative: to the working directory; required); ``images`` load the
    camera images; ``name`` the sequence's (null: the folder's); ``views`` keep only these
    views (indices or camera names, in this order); ``silhouette_noise`` options of
    :class:`mocap.data.corruption.SilhouetteNoise` applied to every mask, deterministically for
    ``seed``; ``nonfinite`` NaN / Inf in the ground truth or detections: refuse or drop them
    (counted in the run's metrics.json); ``gt`` a ground-truth file used instead of the
    folder's gt.npz (``none``: no ground truth); ``detections`` null or ``{semantics: null}``
    the folder's, ``{semantics: realistic}`` (or ``offsets_only``, ``canton``, with fields of
    :class:`mocap.data.detector_semantics.DetectorSemantics`) simulated from the ground truth,
    seeded by ``seed``."""

    path: str | None = None
    images: bool = True
    name: str | None = None
    views: tuple | None = None
    silhouette_noise: dict | None = None
    seed: int = 0
    nonfinite: str = "refuse"
    gt: str | None = None
    detections: dict | None = None


@dataclass(frozen=True)
class CrowdSource:
    """The synthetic crowd (``data=crowd``, :func:`mocap.data.crowd.crowd_sequence`) over
    ``frames`` frames, drawn from ``seed``: ``layout``'s keypoints (BODY_25B: a keypoint
    detector's, grouped per person) with ``noise_px`` pixels of noise; ``gap`` (m) between the
    crossing people's lines; ``cameras`` null: the crowd's 5-view ring
    (:data:`mocap.data.crowd.CROWD_RIG`), else a camera preset or rig config; ``false_people``
    false skeletons (whole walking people a detector sees in 1 to ``false_views`` views only,
    :func:`mocap.data.crowd.false_skeletons`; 0: none, the detections unchanged). The layout,
    the noise and the false people's counts are checked by the loader (their one-line errors)."""

    frames: int = 80
    seed: int = 0
    noise_px: float = 1.0
    gap: float = 0.3
    cameras: str | dict | None = None
    layout: str = "BODY_25B"
    false_people: int = 0
    false_views: int = 2
    name: str = "crowd"


@dataclass(frozen=True)
class OpenPoseSource:
    """A keypoint recording in Pose2Sim's layout (``data=pose2sim_demo``,
    :func:`mocap.data.openpose.load_openpose_sequence`): ``path`` the project folder (required);
    ``calibration`` a file relative to it (null: the single ``*.toml`` in it or in
    ``calibration/``); ``keypoints`` the folder of per-camera OpenPose JSON folders (null:
    ``pose``); ``layout`` a name of :data:`mocap.body.skeletons.LAYOUTS` or ``auto`` (detected
    from the files); ``fps``; ``person`` ``subject`` (one person picked per frame) or ``all``
    (everyone kept); ``min_confidence`` drops keypoints below it (confidence 0 is always
    dropped); ``frames`` keep the first N; ``name`` the sequence's; ``gt`` a ground-truth file
    (gt.npz, joints by name, optionally several people; null: the folder's gt.npz when there is
    one; ``none``: no ground truth); ``nonfinite`` NaN / Inf ground-truth joints: refuse or drop.
    Checked by the loader (its one-line errors)."""

    path: str | None = None
    calibration: str | None = None
    keypoints: str | None = None
    layout: str = "BODY_25B"
    fps: float = 30.0
    person: str = "subject"
    min_confidence: float = 0.0
    frames: int | None = None
    name: str | None = None
    gt: str | None = None
    nonfinite: str = "refuse"


@dataclass(frozen=True)
class VideoSource:
    """A recording from its videos (``data=pose2sim_demo_video``,
    :func:`mocap.video.sequence.load_video_sequence`): ``path`` the folder (required) holding
    ``videos`` (one video per camera, matched to the calibration's names) and ``calibration``
    (null: the single ``*.toml``); ``keypoints`` its OpenPose JSON folders (null: no detections)
    in ``layout`` with ``person`` as for :class:`OpenPoseSource`; ``fps`` (null: the videos'
    own); source frames ``start``:``stop``:``step``; images at ``scale`` of the calibrated size,
    padded or cropped within ``size_tolerance`` of a side; silhouettes from ``masks`` (a ``mocap
    segment`` folder or ``mocap detect``'s ``masks``, refined by ``refine_masks``: options of
    :func:`mocap.video.person_masks.combine_masks`) or made at load time by ``segmentation``
    (options of :func:`mocap.video.segmentation.segment_sequence`; null: no masks); ``gt`` as
    for :class:`OpenPoseSource`."""

    path: str | None = None
    videos: str = "videos"
    calibration: str | None = None
    keypoints: str | None = "pose"
    layout: str = "BODY_25B"
    person: str = "subject"
    fps: float | None = None
    start: int = 0
    stop: int | None = None
    step: int = 1
    scale: float = 1.0
    size_tolerance: float = 0.02
    masks: str | None = None
    segmentation: dict | None = None
    refine_masks: dict | None = None
    name: str | None = None
    gt: str | None = None


#: a loader's ``_target_`` -> its settings class (:mod:`mocap.presets` checks a stored config's
#: keys against its fields)
SOURCES = {"mocap.data.sources.synthetic_sequence": SyntheticSource,
           "mocap.data.sources.folder_sequence": FolderSource,
           "mocap.data.crowd.crowd_sequence": CrowdSource,
           "mocap.data.openpose.openpose_sequence": OpenPoseSource,
           "mocap.video.sequence.video_sequence": VideoSource}


def recording_settings(cls: type, keys: Mapping, what: str) -> tuple[str, dict]:
    """(path, the other settings as keyword arguments) of a recording-folder source ``cls``
    (:class:`OpenPoseSource`, :class:`VideoSource`) from a config's keys that differ from its
    defaults: an unknown key refused by name (``what``: the kind of recording, for the message),
    a missing ``path`` named, before any file is read."""
    known = [f.name for f in fields(cls) if f.name != "path"]
    unknown = sorted(set(keys) - {"path", *known})
    if unknown:
        raise ValueError(f"unknown data setting(s) {', '.join(unknown)} for a {what} "
                         f"(settings: path, {', '.join(known)})")
    s = settings_from_mapping(cls, keys)
    if s.path is None:
        raise ValueError("setting data.path is missing: the recording folder (data.path=/path/to/recording)")
    return s.path, {k: getattr(s, k) for k in known}
