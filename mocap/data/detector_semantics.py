"""A keypoint detector with the semantics of a real one, simulated from 3D joints.

:class:`mocap.data.corruption.DetectionModel` (Canton-Ferrer et al. 2010) corrupts the exact
projections of the joints with misses, Gaussian noise and false positives, all independent.
A real 2D keypoint detector (OpenPose, HRNet, ...) errs in structured ways that per-frame
triangulation cannot average out. :class:`DetectorSemantics` adds them:

* **Systematic offsets**: the detector's keypoint is not the anatomical joint. Each keypoint
  is displaced by a constant 3D offset in a frame that moves with the body: keypoints of the
  torso (hips, mid-hip, shoulders, neck base, head) in the torso frame (x the body's left,
  z from the mid-hip to the neck base, y = x cross z, forward), limb keypoints (elbows,
  wrists, knees, ankles) in their proximal bone's frame (z from the joint towards its parent,
  x the body's left made orthogonal to z, y = x cross z). ``offsets_mm`` gives the mean offset
  per keypoint type (``hip``, ``shoulder``, ...) as (out, forward, up) mm, "out" being the
  body's left for ``l_`` keypoints and its right for ``r_`` ones (mirrored); every sequence
  adds its own draw of N(0, ``offset_jitter_mm``) per keypoint and axis. The hips sit higher
  and wider than the hip joint centres (OpenPose's hips are near the iliac crests), and are
  the largest.
* **Left/right swaps**: an episode starts in a frame with probability ``swap_rate``, in one
  random view, for 1..``swap_frames`` frames: that view labels every left keypoint as its
  right counterpart and vice versa (a person seen from behind).
* **Limbs of another person**: with probability ``foreign_limb_rate`` per frame and view one
  limb's distal pair (elbow + wrist, or knee + ankle) is taken from another person standing
  ``other_distance_m`` away (this sequence, half its length later, moved horizontally in a
  random direction fixed per sequence), with confident scores (bottom-up grouping errors).
* **Confidence that does not match the error**: confidence = ``confidence_informative`` x
  exp(-e / 10 px) + (1 - ``confidence_informative``) x U(0.5, 1), e the detection's pixel
  error from its own (offset) keypoint; a swapped or foreign keypoint is scored as if it
  were right (e = 0 for its own pixel noise), so a confident detection can be 30 cm off.
* Canton-style corruption on top: detection with probability ``detection_rate``, Gaussian
  noise ``noise_px``, with probability ``gross_rate`` a gross error of 10-40 px in a random
  direction (a keypoint on the wrong spot of the limb), and false positives (Poisson,
  ``false_positive_rate`` x keypoints per view and frame, random labels, confidence U(0.1, 0.5)).

Everything is drawn from the ``np.random.Generator`` passed in: the same seed gives the same
detections. ``simulate`` returns the detections together with what it did (the keypoints'
3D positions, the offsets, the swap frames and foreign keypoints), for tests and studies.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from mocap.cameras import Rig, project
from mocap.data.sequence import Detections
from mocap.settings import check

#: mean offsets of a detector's keypoints from the anatomical joints, mm, (out, forward, up)
#: in the keypoint's frame (module docstring); keypoint types missing here get none
REALISTIC_OFFSETS_MM: dict[str, tuple[float, float, float]] = {
    "hip": (22.0, 5.0, 45.0),          # higher and wider than the hip joint centre: ~50 mm
    "mid_hip": (0.0, 5.0, 45.0),
    "shoulder": (12.0, -8.0, 22.0),    # on the top of the shoulder, not the joint centre
    "neck_base": (0.0, 12.0, 15.0),
    "head_centre": (0.0, 25.0, 10.0),  # between the eyes and ears: in front of the centre
    "elbow": (8.0, -12.0, 0.0),        # the outer / back surface of the elbow
    "wrist": (0.0, 8.0, -6.0),
    "knee": (0.0, 18.0, 0.0),          # on the kneecap
    "ankle": (5.0, -5.0, -12.0),
}
#: the proximal neighbour of each limb keypoint type (its bone's frame)
PARENT = {"elbow": "shoulder", "wrist": "elbow", "knee": "hip", "ankle": "knee"}
#: the limb keypoints another person can lend (distal pairs)
LIMBS = (("elbow", "wrist"), ("knee", "ankle"))


@dataclass(frozen=True)
class DetectorSemantics:
    """The simulated detector of the module docstring (defaults: ``realistic``)."""

    offsets_mm: Mapping[str, Sequence[float]] = field(default_factory=lambda: dict(REALISTIC_OFFSETS_MM))
    offset_jitter_mm: float = 5.0
    swap_rate: float = 0.03
    swap_frames: int = 4
    foreign_limb_rate: float = 0.02
    other_distance_m: float = 0.9
    confidence_informative: float = 0.3
    detection_rate: float = 0.95
    noise_px: float = 2.0
    gross_rate: float = 0.02
    false_positive_rate: float = 0.02

    def __post_init__(self) -> None:
        offs = {}
        for k, v in dict(self.offsets_mm).items():
            v = tuple(float(x) for x in v)
            check(self, "offsets_mm", len(v) == 3 and all(np.isfinite(v)),
                  "keypoint type -> (out, forward, up) mm, 3 finite numbers each")
            offs[str(k)] = v
        object.__setattr__(self, "offsets_mm", offs)
        for name in ("swap_rate", "foreign_limb_rate", "confidence_informative", "detection_rate",
                     "gross_rate"):
            check(self, name, 0.0 <= getattr(self, name) <= 1.0, "[0, 1]")
        check(self, "offset_jitter_mm", self.offset_jitter_mm >= 0, ">= 0 mm")
        check(self, "swap_frames", self.swap_frames >= 1, "an integer >= 1")
        check(self, "other_distance_m", self.other_distance_m > 0, "> 0 m")
        check(self, "noise_px", self.noise_px >= 0, ">= 0 px")
        check(self, "false_positive_rate", self.false_positive_rate >= 0, ">= 0")


#: named variants: ``realistic`` (the defaults), ``offsets_only`` (the offsets and pixel noise,
#: no swaps, foreign limbs, gross errors or false positives; confidence informative), ``canton``
#: (Canton-Ferrer et al. 2010's corruption alone, with the rates the real-motion benchmark's
#: detections were made with, mocap_build/mismatch/real_motion.py: no offsets, swaps, foreign limbs
#: or gross errors; 90 % detected, 2 px noise, 0.1 false positives per keypoint; confidence
#: unrelated to the error)
PRESETS: dict[str, dict] = {
    "realistic": {},
    "offsets_only": {"swap_rate": 0.0, "foreign_limb_rate": 0.0, "gross_rate": 0.0,
                     "false_positive_rate": 0.0, "confidence_informative": 1.0, "detection_rate": 1.0},
    "canton": {"offsets_mm": {}, "offset_jitter_mm": 0.0, "swap_rate": 0.0, "foreign_limb_rate": 0.0,
               "gross_rate": 0.0, "confidence_informative": 0.0, "detection_rate": 0.9,
               "false_positive_rate": 0.1, "noise_px": 2.0},
}


def semantics_from(options: Mapping) -> DetectorSemantics:
    """``{"semantics": name, **field overrides}`` -> :class:`DetectorSemantics`."""
    opts = dict(options)
    name = opts.pop("semantics", "realistic")
    if name not in PRESETS:
        raise ValueError(f"detections.semantics must be one of {sorted(PRESETS)} (or null: the folder's "
                         f"detections), got {name!r}")
    unknown = sorted(set(opts) - set(DetectorSemantics.__dataclass_fields__))
    if unknown:
        raise ValueError(f"detections: unknown option(s) {unknown}; allowed: semantics, "
                         f"{', '.join(DetectorSemantics.__dataclass_fields__)}")
    return DetectorSemantics(**{**PRESETS[name], **opts})


@dataclass(frozen=True)
class SimulatedDetections:
    """detections: the simulated 2D detections; keypoints: (F, J, 3) world metres, where the
    detector marks each keypoint (joints + offsets); offsets_local: (J, 3) metres in each
    keypoint's frame (out, forward, up with "out" mirrored for right keypoints: as configured);
    swapped: (F, C) bool, views whose left/right labels are exchanged; foreign: (F, C, J) bool,
    keypoints taken from the other person."""

    detections: Detections
    keypoints: np.ndarray
    offsets_local: np.ndarray
    swapped: np.ndarray
    foreign: np.ndarray


def _kind(name: str) -> tuple[str, float]:
    """keypoint name -> (type, sign of "out" along the body's left)."""
    if name.startswith("l_"):
        return name[2:], 1.0
    if name.startswith("r_"):
        return name[2:], -1.0
    return name, 0.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def keypoint_frames(joints: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Per-frame orthonormal frames of the keypoints (module docstring): joints (F, J, 3)
    named ``names`` (our catalogue's names of the HumanEva-15 joints: mid_hip, neck_base,
    l_hip, l_shoulder, ...) -> (F, J, 3, 3), columns (left, forward, up) world unit vectors."""
    names = list(names)
    need = {"mid_hip", "neck_base", "l_hip", "r_hip", "l_shoulder", "r_shoulder"}
    if not need <= set(names):
        raise ValueError(f"detector semantics need the keypoints {sorted(need)}; got {names}")
    J = lambda n: joints[:, names.index(n)]                        # noqa: E731
    up = _unit(J("neck_base") - J("mid_hip"))
    frames = np.empty(joints.shape[:2] + (3, 3))
    for j, n in enumerate(names):
        kind, _ = _kind(n)
        left = J("l_shoulder") - J("r_shoulder") if kind in ("shoulder", "elbow", "wrist") \
            else J("l_hip") - J("r_hip")
        z = up
        if kind in PARENT:
            parent = n[:2] + PARENT[kind]
            if parent in names:
                z = _unit(J(parent) - joints[:, j])
        x = _unit(left - (left * z).sum(-1, keepdims=True) * z)
        y = np.cross(x, z)
        frames[:, j] = np.stack([x, y, z], axis=-1)
    return frames


def configured_offsets(names: Sequence[str], semantics: DetectorSemantics) -> np.ndarray:
    """(J, 3) metres in the keypoints' frames: the configured mean offsets, "out" mirrored."""
    return local_offsets(names, semantics.offsets_mm)


def local_offsets(names: Sequence[str], table_mm: Mapping[str, Sequence[float]]) -> np.ndarray:
    """(J, 3) metres in the keypoints' frames (left, forward, up) from a table keypoint type ->
    (out, forward, up) mm ("out" mirrored for right keypoints; types not in it: zero)."""
    out = np.zeros((len(names), 3))
    for j, n in enumerate(names):
        kind, sign = _kind(n)
        o = table_mm.get(kind, (0.0, 0.0, 0.0))
        out[j] = (o[0] * (sign if sign else 1.0), o[1], o[2])
    return out / 1e3


def simulate(joints: np.ndarray, names: Sequence[str], rig: Rig, semantics: DetectorSemantics,
             rng: np.random.Generator) -> SimulatedDetections:
    """Detections of joints (F, J, 3) world metres named ``names`` (our catalogue's names)
    in every view of ``rig``, with ``semantics``; labels are ``names``."""
    s = semantics
    names = list(names)
    joints = np.asarray(joints, np.float64)
    F, Jn = joints.shape[:2]
    C = len(rig)
    offsets = configured_offsets(names, s) + rng.normal(0.0, s.offset_jitter_mm / 1e3, (Jn, 3))
    frames = keypoint_frames(joints, names)
    keypoints = joints + np.einsum("fjab,jb->fja", frames, offsets)
    # the other person: this motion half the sequence later, moved horizontally
    phi = rng.uniform(0, 2 * np.pi)
    other = keypoints[(np.arange(F) + F // 2) % F] + s.other_distance_m * np.array(
        [np.cos(phi), np.sin(phi), 0.0])
    mirror = np.arange(Jn)
    for j, n in enumerate(names):
        kind, sign = _kind(n)
        twin = ("r_" if sign > 0 else "l_") + kind
        if sign and twin in names:
            mirror[j] = names.index(twin)
    limbs = [[names.index(side + k) for k in pair] for pair in LIMBS for side in ("l_", "r_")
             if all(side + k in names for k in pair)]
    swapped = np.zeros((F, C), bool)
    f = 0
    while f < F:
        if s.swap_rate and rng.random() < s.swap_rate:
            n = int(rng.integers(1, s.swap_frames + 1))
            swapped[f:f + n, int(rng.integers(C))] = True
            f += n
        else:
            f += 1
    foreign = np.zeros((F, C, Jn), bool)
    if limbs and s.foreign_limb_rate:
        hit = rng.random((F, C)) < s.foreign_limb_rate
        for f_, c in zip(*np.nonzero(hit), strict=True):
            foreign[f_, c, limbs[int(rng.integers(len(limbs)))]] = True
    w, h = (float(x) for x in rig.sizes[0])
    px_self = project(rig, keypoints.reshape(-1, 3)).reshape(C, F, Jn, 2)
    px_other = project(rig, other.reshape(-1, 3)).reshape(C, F, Jn, 2)
    rows = []
    for f in range(F):
        for c in range(C):
            px = np.where(foreign[f, c][:, None], px_other[c, f], px_self[c, f])
            if swapped[f, c]:
                px = px[mirror]
            hit = rng.random(Jn) < s.detection_rate
            noise = rng.normal(0.0, s.noise_px, (Jn, 2))
            gross = rng.random(Jn) < s.gross_rate
            ang = rng.uniform(0, 2 * np.pi, Jn)
            step = rng.uniform(10, 40, Jn)[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
            noise += gross[:, None] * step
            err = np.linalg.norm(noise, axis=1)
            conf = (s.confidence_informative * np.exp(-err / 10.0)
                    + (1 - s.confidence_informative) * rng.uniform(0.5, 1.0, Jn))
            xy = px + noise
            lab = np.arange(Jn)
            n_fp = int(rng.poisson(s.false_positive_rate * Jn)) if s.false_positive_rate else 0
            if n_fp:
                lo, hi = px.min(axis=0), px.max(axis=0)
                pad = 0.3 * (hi - lo) + 10
                xy = np.concatenate([xy[hit], rng.uniform(lo - pad, hi + pad, (n_fp, 2))])
                lab = np.concatenate([lab[hit], rng.integers(0, Jn, n_fp)])
                conf = np.concatenate([conf[hit], rng.uniform(0.1, 0.5, n_fp)])
            else:
                xy, lab, conf = xy[hit], lab[hit], conf[hit]
            inside = (xy[:, 0] >= 0) & (xy[:, 0] <= w - 1) & (xy[:, 1] >= 0) & (xy[:, 1] <= h - 1)
            rows += [(f, c, int(lb), x, y, cf) for lb, (x, y), cf in
                     zip(lab[inside], xy[inside], np.clip(conf[inside], 0.05, 1.0), strict=True)]
    a = np.array(rows, np.float64).reshape(-1, 6)
    det = Detections(labels=tuple(names), frame=a[:, 0].astype(np.int64), view=a[:, 1].astype(np.int64),
                     label=a[:, 2].astype(np.int64), xy=a[:, 3:5], confidence=a[:, 5])
    return SimulatedDetections(det, keypoints, offsets, swapped, foreign)


def gt_keypoint_names(gt) -> list[str]:
    """Our catalogue's names of a ground truth's joints (by its skeleton, e.g. humaneva15)."""
    from mocap.body.skeletons import SKELETONS

    table = SKELETONS.get(gt.skeleton or "", {})
    names = [table.get(str(n), str(n)) for n in gt.joint_names]
    if any(n is None for n in names):
        raise ValueError(f"detector semantics: ground-truth joints {list(gt.joint_names)} include points "
                         "mocap does not model")
    return names
