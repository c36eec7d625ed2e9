"""A multi-view sequence in memory: calibration, per-view observations and ground truth."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mocap.cameras import Rig


@dataclass(frozen=True)
class Detections:
    """2D detections of a sequence as flat arrays (N detections in all).

    frame, view: (N,) int; label: (N,) int index into ``labels`` (-1: unlabelled);
    xy: (N, 2) float pixels; confidence: (N,) float in [0, 1].
    Several detections may share (frame, view, label): false positives, other people.
    person: (N,) int or None: which person of its (frame, view) a detection belongs to (the
    detector's grouping of keypoints into skeletons, -1: unknown); identities are per
    frame and view, not across them.
    """

    labels: tuple[str, ...]
    frame: np.ndarray
    view: np.ndarray
    label: np.ndarray
    xy: np.ndarray
    confidence: np.ndarray
    person: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.frame)
        for name in ("view", "label", "confidence", "person"):
            if getattr(self, name) is not None and len(getattr(self, name)) != n:
                raise ValueError(f"detections: field '{name}' has {len(getattr(self, name))} "
                                 f"entries, expected {n}")
        if self.xy.shape != (n, 2):
            raise ValueError(f"detections: field 'xy' must be ({n}, 2), got {self.xy.shape}")
        if n and (self.label.min() < -1 or self.label.max() >= len(self.labels)):
            raise ValueError("detections: label index out of range")

    def select(self, frame: int, view: int | None = None) -> Detections:
        keep = self.frame == frame
        if view is not None:
            keep &= self.view == view
        return Detections(self.labels, self.frame[keep], self.view[keep], self.label[keep],
                          self.xy[keep], self.confidence[keep],
                          None if self.person is None else self.person[keep])

    def __len__(self) -> int:
        return len(self.frame)


@dataclass(frozen=True)
class GroundTruth:
    """alpha: (K,) shape; chi: (F, D) poses; joints: (F, J, 3) and markers: (F, L, 3) world
    metres; names of the DOFs, joints and markers; ``body``: the body configuration's name.

    Ground truth of a real dataset may be joints by name only: ``alpha``, ``chi`` and
    ``markers`` None (empty names), ``joint_names`` in any order and any skeleton
    (``skeleton``: a key of :data:`mocap.body.skeletons.SKELETONS`, "" for mocap's own names),
    ``joint_valid`` (F, J) bool where a joint was measured (None: everywhere).

    Several people: ``person_names`` (P,) non-empty, ``joints`` (F, P, J, 3) and ``joint_valid``
    (F, P, J) (a person absent in a frame: invalid there); no ``chi``, ``alpha`` or ``markers``.
    :meth:`person` gives one person's ground truth (scored per person with the best assignment
    of tracks to people, :mod:`mocap.eval.people`).

    The true body surface (optional, one person): ``surface`` (F, N, 3) world metres, points on
    it per frame, and ``surface_faces`` (M, 3) int when the points are a mesh's vertices
    (scored by :mod:`mocap.eval.surface`)."""

    alpha: np.ndarray | None
    chi: np.ndarray | None
    joints: np.ndarray
    markers: np.ndarray | None
    dof_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    marker_names: tuple[str, ...]
    body: str = ""
    joint_valid: np.ndarray | None = None
    skeleton: str = ""
    person_names: tuple[str, ...] = ()
    surface: np.ndarray | None = None
    surface_faces: np.ndarray | None = None

    def __post_init__(self) -> None:
        s, faces = self.surface, self.surface_faces
        if s is None:
            if faces is not None:
                raise ValueError("ground truth: field 'surface_faces' needs 'surface'")
            return
        if s.ndim != 3 or s.shape[2] != 3 or s.shape[1] < 1 or len(s) != len(self.joints):
            raise ValueError(f"ground truth: field 'surface' must be ({len(self.joints)}, N, 3), "
                             f"got {s.shape}")
        if faces is not None and (faces.ndim != 2 or faces.shape[1] != 3
                                  or (faces.size and (faces.min() < 0 or faces.max() >= s.shape[1]))):
            raise ValueError(f"ground truth: field 'surface_faces' must be (M, 3) indices of the "
                             f"{s.shape[1]} surface points, got {faces.shape}")

    @property
    def num_frames(self) -> int:
        return len(self.joints)

    @property
    def num_people(self) -> int:
        """People with a ground truth: len(person_names), 1 without a person axis."""
        return len(self.person_names) or 1

    def person(self, p: int) -> GroundTruth:
        """Person p's ground truth, joints (F, J, 3) (without a person axis: itself, p = 0)."""
        if not self.person_names:
            if p != 0:
                raise IndexError(f"ground truth has one person, asked for person {p}")
            return self
        valid = None if self.joint_valid is None else self.joint_valid[:, p]
        return GroundTruth(alpha=None, chi=None, joints=self.joints[:, p], markers=None, dof_names=(),
                           joint_names=self.joint_names, marker_names=(), body=self.body,
                           joint_valid=valid, skeleton=self.skeleton)


@dataclass(frozen=True)
class Sequence:
    """masks: (F, C, H, W) bool silhouettes at camera resolution (None if absent);
    images: (F, C, H, W, 3) uint8 RGB (None if absent). All views share one image size.
    frames: the recording's frame count where no array carries it (keypoint recordings whose
    last frames have no detection); None: from the masks, images, ground truth or detections."""

    name: str
    rig: Rig
    fps: float
    masks: np.ndarray | None = None
    images: np.ndarray | None = None
    detections: Detections | None = None
    gt: GroundTruth | None = None
    meta: dict = field(default_factory=dict)
    frames: int | None = None

    def __post_init__(self) -> None:
        from mocap.checks import MAX_FRAMES, check_fps, check_int

        check_fps(self.fps, f"sequence {self.name!r}: fps")           # finite, > 0 (issue 36)
        if self.frames is not None:
            check_int(self.frames, f"sequence {self.name!r}: frames", 0, MAX_FRAMES)
            held = [len(a) for a in (self.masks, self.images) if a is not None]
            if self.detections is not None and len(self.detections):
                last = int(self.detections.frame.max()) + 1
                if last > self.frames:
                    raise ValueError(f"sequence {self.name!r}: detections reach frame {last - 1}, "
                                     f"beyond its {self.frames} frames")
            if any(n != self.frames for n in held):
                raise ValueError(f"sequence {self.name!r}: {self.frames} frames, its arrays have {held}")
        sizes = {tuple(s) for s in np.asarray(self.rig.sizes)}
        if len(sizes) != 1:
            raise ValueError(f"sequence {self.name!r}: all views must share one image size, "
                             f"got {sorted(sizes)}")
        (w, h), = sizes
        C = len(self.rig)
        for what, arr, tail in (("masks", self.masks, (h, w)), ("images", self.images, (h, w, 3))):
            if arr is not None and (arr.shape[1] != C or arr.shape[2:] != tail):
                raise ValueError(f"sequence {self.name!r}: {what} must be (F, {C}, "
                                 f"{', '.join(map(str, tail))}), got {arr.shape}")
        if self.gt is not None and self.num_frames and self.gt.num_frames != self.num_frames:
            raise ValueError(f"sequence {self.name!r}: ground truth has {self.gt.num_frames} "
                             f"frames, observations {self.num_frames}")

    @property
    def num_frames(self) -> int:
        if self.frames is not None:
            return self.frames
        for arr in (self.masks, self.images):
            if arr is not None:
                return len(arr)
        if self.gt is not None:
            return self.gt.num_frames
        if self.detections is not None and len(self.detections):
            return int(self.detections.frame.max()) + 1
        return 0

    @property
    def num_views(self) -> int:
        return len(self.rig)

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height)."""
        return tuple(int(x) for x in self.rig.sizes[0])
