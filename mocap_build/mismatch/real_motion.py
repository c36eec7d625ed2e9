"""The real-motion benchmark: motion-capture clips drive anny's own skeleton (``data/real_motion``).

A clip of the Bandai Namco Research Motion Dataset 1 (``../shared/data/real-motion``, read with
:func:`mocap.clips.read_bvh`: joint positions in metres, z up) poses the full-resolution anny
mesh with anny's OWN 104-bone linear blend skinning (not the tracker's PCA body), for subjects
whose phenotypes were not among the bodies the shipped PCA was built from. The pose comes from
the clip's joint POSITIONS, bone by bone (directions from the clip, lengths from anny):

- pelvis and chest: frames from the hip line / shoulder line (primary, lateral) and the spine
  (secondary, up); the five spine bones share the rotation from pelvis to chest (slerp);
- neck: the chest's rotation, then the swing onto the clip's neck -> head direction;
- upper arm / thigh: the swing onto the clip's bone direction, twisted so that anny's elbow /
  knee flexion axis becomes the clip's (the normal of the shoulder-elbow-wrist /
  hip-knee-ankle plane); where the limb is nearly straight the twist falls back to the
  chest's (arms) or to the foot's heading (legs), blended by the bend angle;
- forearm / shin: the swing from the posed upper bone onto the clip's direction (a pure hinge
  about the flexion axis: forearms are never twisted, elbows and knees bend the natural way);
- foot: the swing onto the clip's ankle -> toes direction, turned about the ankle's axis by one
  constant per clip and side so that the clip's flat foot (its ankle -> toes drop below
  horizontal when on the floor) is anny's flat foot (its rest drop);
- toes: bent up towards level while the clip's ball of the foot is on the floor (toe-off;
  anny's rigid toes would otherwise dig into it);
- clavicles, hands, fingers, eyes follow their parents (the clip has no data for them).

The root follows the clip's hip centre scaled by the leg-length ratio (anny / clip),
horizontally; vertically, each frame's lowest vertex is put at the clip's contact height (how
far its lowest foot is above the floor: 0 while a foot is down, > 0 in flight, so jumps stay
jumps): anny's feet (other ankle height, foot length, rigid heel) would otherwise float or sink
by up to 4 cm where the clip's feet roll. The sequence is turned about the vertical (the first
frame faces -y, or a walk travels between two cameras) and centred on the ring. The 60-frame
window is the one with the most joint motion (sum of the root-relative joint speeds) among
those whose joints stay inside every view.

Ground truth: the 15 joints of :data:`~mocap_build.mismatch.procedural.GT_JOINTS` (HumanEva-15
names, anatomical definitions on anny's posed skeleton), Canton-style corrupted 2D detections
of them (:class:`mocap.data.corruption.DetectionModel`, seeded by the sequence name), exact
silhouettes on the 8-view ring at 500x500. Licences: Anny (Apache-2.0) and the motion data
(CC BY-NC 4.0): the renders are adapted material, non-commercial use only (NOTICE.txt).
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocap_build.mismatch.procedural import (
    GT_JOINTS,
    HEAD_WEIGHT,
    _anny_version,
    benchmark_rig,
    gt_joints,
    load_anny,
    rotvec_to_matrix,
)

GENERATOR_VERSION = "real-motion-v1"
FRAMES = 60
FPS = 30.0
# Canton-Ferrer et al. 2010, Sec. 4.1, as data=walk_markers: misses, false detections, noise
DETECTION = {"detection_rate": 0.9, "false_positive_rate": 0.1, "noise_px": 2.0, "labelled": True}
MARGIN_PX = 30.0        # the chosen window keeps every clip joint this far inside every view
SPLITS = ("dev", "test")


@dataclass(frozen=True)
class Subject:
    name: str
    phenotype: Mapping[str, float]     # anny phenotype parameters in [0, 1]
    description: str


# hand-chosen phenotypes (round values; the PCA's bodies were random draws), none of the
# data/mismatch subjects; statures 1.56-1.93 m (measured on anny's rest mesh, in index.json)
SUBJECTS: dict[str, Subject] = {s.name: s for s in (
    Subject("petite_woman", {"gender": 0.0, "age": 0.5, "muscle": 0.4, "weight": 0.45,
                             "height": 0.375, "proportions": 0.4}, "short woman, average build"),
    Subject("athletic_woman", {"gender": 0.15, "age": 0.35, "muscle": 0.6, "weight": 0.3,
                               "height": 0.825, "proportions": 0.65}, "tall slim athletic woman"),
    Subject("heavy_man", {"gender": 0.85, "age": 0.7, "muscle": 0.75, "weight": 0.9,
                          "height": 0.41, "proportions": 0.35}, "older heavy man, average height"),
    Subject("tall_man", {"gender": 1.0, "age": 0.45, "muscle": 0.5, "weight": 0.45,
                         "height": 0.925, "proportions": 0.55}, "very tall man, average build"),
)}


@dataclass(frozen=True)
class RealMotionSpec:
    split: str          # "dev" (motion types the prior trains on) or "test" (held-out types)
    motion: str         # the motion type (mocap/clips/split.yaml)
    clip: str           # BVH file, relative to the clip folder
    subject: str        # a key of SUBJECTS

    @property
    def name(self) -> str:
        return f"{self.motion}_{self.subject}"

    @property
    def key(self) -> str:
        return f"{self.split}/{self.name}"


def _clip(motion: str, style: str = "normal", take: int = 1) -> str:
    return f"bandai_namco/dataset-1/dataset-1_{motion}_{style}_{take:03d}.bvh"


# dev: motion types of split.yaml's `train`; test: one sequence per `held_out` type. Every
# split sees all four subjects (both sexes).
SEQUENCES: tuple[RealMotionSpec, ...] = (
    RealMotionSpec("dev", "walk", _clip("walk", "old"), "heavy_man"),
    RealMotionSpec("dev", "bow", _clip("bow"), "tall_man"),
    RealMotionSpec("dev", "bye", _clip("bye"), "petite_woman"),
    RealMotionSpec("dev", "call", _clip("call"), "athletic_woman"),
    RealMotionSpec("dev", "slash", _clip("slash"), "heavy_man"),
    RealMotionSpec("dev", "dance-short", _clip("dance-short"), "petite_woman"),
    RealMotionSpec("test", "byebye", _clip("byebye"), "petite_woman"),
    RealMotionSpec("test", "guide", _clip("guide"), "athletic_woman"),
    RealMotionSpec("test", "walk-left", _clip("walk-left", "not-confident"), "heavy_man"),
    RealMotionSpec("test", "walk-right", _clip("walk-right", "not-confident"), "tall_man"),
    RealMotionSpec("test", "punch", _clip("punch"), "tall_man"),
    RealMotionSpec("test", "kick", _clip("kick"), "athletic_woman"),
)


def sequence_spec(key: str) -> RealMotionSpec:
    """The spec called ``key`` ("test/byebye_petite_woman")."""
    for s in SEQUENCES:
        if s.key == key:
            return s
    raise KeyError(f"no real-motion sequence {key!r} (known: {', '.join(s.key for s in SEQUENCES)})")


# --- rotations (batch-first) -------------------------------------------------------------------


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def frames_from(primary: np.ndarray, secondary: np.ndarray) -> np.ndarray:
    """(..., 3, 3) orthonormal frames, columns (e1, e2, e1 x e2): e1 along ``primary``, e2 the
    part of ``secondary`` orthogonal to it. primary, secondary: (..., 3)."""
    e1 = _unit(primary)
    e2 = _unit(secondary - np.sum(secondary * e1, axis=-1, keepdims=True) * e1)
    return np.stack([e1, e2, np.cross(e1, e2)], axis=-1)


def swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the smallest rotations taking directions ``a`` to ``b`` (..., 3)."""
    a, b = _unit(a), _unit(b)
    c = np.cross(a, b)
    s = np.linalg.norm(c, axis=-1, keepdims=True)
    ang = np.arctan2(s, np.sum(a * b, axis=-1, keepdims=True))
    return rotvec_to_matrix(c / np.maximum(s, 1e-12) * ang)


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations -> (..., 3) rotation vectors."""
    from scipy.spatial.transform import Rotation

    shape = R.shape[:-2]
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(shape + (3,))


def slerp(Ra: np.ndarray, Rb: np.ndarray, t: float) -> np.ndarray:
    """(..., 3, 3) rotations a fraction ``t`` of the way from Ra to Rb (world-frame products)."""
    rel = matrix_to_rotvec(Rb @ np.swapaxes(Ra, -1, -2))
    return rotvec_to_matrix(t * rel) @ Ra


def _signed_angle(a: np.ndarray, b: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(...,) angle from ``a`` to ``b`` about ``axis`` (all (..., 3), a and b orthogonal to it)."""
    return np.arctan2(np.sum(np.cross(a, b) * axis, axis=-1), np.sum(a * b, axis=-1))


def _twist_normal(u: np.ndarray, n_bend: np.ndarray, bend: np.ndarray, n_fallback: np.ndarray,
                  lo: float = np.deg2rad(8.0), hi: float = np.deg2rad(25.0)) -> np.ndarray:
    """(F, 3) the flexion axis of a limb along ``u`` (F, 3): ``n_bend`` (the plane's normal)
    where the limb is bent by ``bend`` (F,) rad > ``hi``, ``n_fallback`` where it is nearly
    straight (< ``lo``), the angle about ``u`` blended in between (no cancellation)."""
    u = _unit(u)
    fb = _unit(n_fallback - np.sum(n_fallback * u, -1, keepdims=True) * u)
    nb = _unit(n_bend - np.sum(n_bend * u, -1, keepdims=True) * u)
    x = np.clip((bend - lo) / (hi - lo), 0.0, 1.0)
    w = x * x * (3 - 2 * x)
    phi = w * _signed_angle(fb, nb, u)
    return np.einsum("fij,fj->fi", rotvec_to_matrix(phi[:, None] * u), fb)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(np.sum(_unit(a) * _unit(b), -1), -1.0, 1.0))


# --- the clip ---------------------------------------------------------------------------------

# clip joints used (Bandai Namco names, mocap/clips/maps/bandai_namco.yaml)
CLIP_JOINTS = ("Hips", "Spine", "Chest", "Neck", "Head", "UpperArm_L", "LowerArm_L", "Hand_L",
               "UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
               "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R")


def load_clip(path: Path) -> tuple[dict[str, np.ndarray], float]:
    """The clip's joints by name, (F, 3) metres z up, and its frame rate."""
    from mocap.clips import read_bvh

    clip = read_bvh(path)
    return {n: clip.joint(n) for n in CLIP_JOINTS}, float(clip.fps)


def leg_length(J: Mapping[str, np.ndarray]) -> float:
    """Mean hip-knee-ankle length of both legs over all frames (m)."""
    out = [np.linalg.norm(J[f"LowerLeg_{s}"] - J[f"UpperLeg_{s}"], axis=-1)
           + np.linalg.norm(J[f"Foot_{s}"] - J[f"LowerLeg_{s}"], axis=-1) for s in "LR"]
    return float(np.mean(out))


def _hip_centre(J) -> np.ndarray:
    return 0.5 * (J["UpperLeg_L"] + J["UpperLeg_R"])


def _front(J) -> np.ndarray:
    """(F, 2) horizontal facing direction: the subject's left x up (front -y when left is +x)."""
    left = J["UpperLeg_L"] - J["UpperLeg_R"] + J["UpperArm_L"] - J["UpperArm_R"]
    f = np.cross(left, [0.0, 0.0, 1.0])[:, :2]
    return f / np.linalg.norm(f, axis=-1, keepdims=True)


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def place_clip(J: Mapping[str, np.ndarray], scale: float, start: int, frames: int):
    """The window ``start:start+frames`` of the clip, turned about z and moved so that it is
    centred on the ring: every joint scaled about the floor by ``scale``; returns (joints by
    name (frames, 3), yaw rad). The yaw makes the first frame face -y, or, when the hip centre
    travels more than 0.25 m, makes the travel direction point between two cameras (azimuth
    -112.5 deg, between cam_05 and cam_06)."""
    W = {n: v[start:start + frames] * scale for n, v in J.items()}
    hips = _hip_centre(W)
    travel = hips[-1, :2] - hips[0, :2]
    if np.linalg.norm(travel) > 0.25:
        yaw = np.deg2rad(-112.5) - np.arctan2(travel[1], travel[0])
    else:
        f = _front(W)[0]
        yaw = -np.pi / 2 - np.arctan2(f[1], f[0])
    R = _rot_z(float(yaw))
    W = {n: v @ R.T for n, v in W.items()}
    xy = _hip_centre(W)[:, :2]
    centre = 0.5 * (xy.min(axis=0) + xy.max(axis=0))
    floor = min(float(v[:, 2].min()) for v in W.values())
    shift = np.array([-centre[0], -centre[1], -floor])
    return {n: v + shift for n, v in W.items()}, float(yaw)


def choose_window(J: Mapping[str, np.ndarray], scale: float, rig, frames: int = FRAMES,
                  margin_px: float = MARGIN_PX) -> int:
    """The first frame of the ``frames``-frame window with the most joint motion (sum over
    frames and joints of the root-relative joint speed) among the windows whose (placed) joints
    project at least ``margin_px`` inside every view; ties: the earliest. Raises ValueError
    when no window fits or the clip is too short."""
    from mocap.cameras import project

    F = len(J["Hips"])
    if F < frames:
        raise ValueError(f"the clip has {F} frames, {frames} asked")
    hips = _hip_centre(J)
    rel = np.stack([v - hips for v in J.values()], axis=1)                # (F, J, 3)
    speed = np.linalg.norm(np.diff(rel, axis=0), axis=-1).sum(axis=1)     # (F-1,)
    csum = np.concatenate([[0.0], np.cumsum(speed)])
    score = csum[frames - 1:] - csum[:F - frames + 1]                     # (F-frames+1,)
    w, h = (int(x) for x in rig.sizes[0])
    for start in np.argsort(-score, kind="stable"):
        W, _ = place_clip(J, scale, int(start), frames)
        pts = np.concatenate(list(W.values()))
        px, depth = project(rig, pts, return_depth=True)
        if (depth > 0.1).all() and (px >= margin_px).all() and (px[..., 0] <= w - 1 - margin_px).all() \
                and (px[..., 1] <= h - 1 - margin_px).all():
            return int(start)
    raise ValueError(f"no {frames}-frame window of the clip stays {margin_px} px inside every view")


def foot_drop(ankle: np.ndarray, toes: np.ndarray) -> np.ndarray:
    """(...,) the angle (rad) by which the ankle -> toes direction points below horizontal."""
    d = toes - ankle
    return np.arcsin(np.clip(-d[..., 2] / np.linalg.norm(d, axis=-1), -1.0, 1.0))


def contact_height(J: Mapping[str, np.ndarray], start: int, frames: int) -> np.ndarray:
    """(frames,) how high the clip's lowest foot is above the floor in the window (clip units):
    per side the lower of the toes' and the ankle's heights above their lowest over the whole
    clip, the lower side; 0 while a foot is on the floor, > 0 in flight (jumps stay jumps)."""
    sides = []
    for s in "LR":
        toe, ank = J[f"Toes_{s}"][:, 2], J[f"Foot_{s}"][:, 2]
        sides.append(np.minimum(toe - min(J["Toes_L"][:, 2].min(), J["Toes_R"][:, 2].min()),
                                ank - min(J["Foot_L"][:, 2].min(), J["Foot_R"][:, 2].min())))
    return np.minimum(*sides)[start:start + frames]


def ankle_offsets(J: Mapping[str, np.ndarray], rest_drop: Mapping[str, float]) -> dict[str, float]:
    """Per side, rad: the clip's median foot drop over its flat-foot frames (ankle and toes
    both within 2 cm of their lowest heights over the clip) minus anny's rest foot drop (its
    flat foot, :func:`foot_drop`): the angle the clip's foot is turned up by (dorsiflexion,
    about the ankle's axis) so that a flat foot of the clip is a flat foot of anny; 0 where
    the clip has fewer than 5 such frames."""
    out = {}
    for s in "LR":
        ank, toe = J[f"Foot_{s}"], J[f"Toes_{s}"]
        flat = (ank[:, 2] < ank[:, 2].min() + 0.02) & (toe[:, 2] < toe[:, 2].min() + 0.02)
        out[s] = float(np.median(foot_drop(ank, toe)[flat]) - rest_drop[s]) if flat.sum() >= 5 else 0.0
    return out


# --- anny's rest skeleton and the pose ------------------------------------------------------


@dataclass(frozen=True)
class AnnyRest:
    labels: tuple[str, ...]
    parents: np.ndarray         # (B,) parent index, -1 for the root
    heads: np.ndarray           # (B, 3) rest bone heads (reference pose, root head at 0)

    def __getitem__(self, bone: str) -> np.ndarray:
        return self.heads[self.labels.index(bone)]

    def toes(self, s: str) -> np.ndarray:
        return np.mean([self[f"toe{k}-1.{s}"] for k in range(1, 6)], axis=0)

    def leg_length(self) -> float:
        return float(np.mean([np.linalg.norm(self[f"lowerleg01.{s}"] - self[f"upperleg01.{s}"])
                              + np.linalg.norm(self[f"foot.{s}"] - self[f"lowerleg01.{s}"])
                              for s in "LR"]))

    def toe_direction(self, s: str) -> np.ndarray:
        """(3,) mean direction of the proximal toe phalanges (about level at rest)."""
        return np.mean([self[f"toe{k}-2.{s}"] - self[f"toe{k}-1.{s}"] for k in range(1, 6)], axis=0)

    def foot_drops(self) -> dict[str, float]:
        return {s: float(foot_drop(self[f"foot.{s}"], self.toes(s))) for s in "LR"}


SPINE = ("spine05", "spine04", "spine03", "spine02", "spine01")


def world_rotations(J: Mapping[str, np.ndarray], rest: AnnyRest,
                    ankle_offset: Mapping[str, float]) -> dict[str, np.ndarray]:
    """(F, 3, 3) world rotations (relative to anny's reference pose) of the driven bones from
    the clip's joints J (F, 3) by name; the other bones follow their parents."""
    r = rest
    F = len(J["Hips"])
    Wr: dict[str, np.ndarray] = {}
    hip_r = 0.5 * (r["upperleg01.L"] + r["upperleg01.R"])
    # pelvis: hip line (primary) and hips -> lower spine; chest: shoulder line and chest -> neck
    Fp_r = frames_from(r["upperleg01.L"] - r["upperleg01.R"], r["spine02"] - hip_r)
    Fp = frames_from(J["UpperLeg_L"] - J["UpperLeg_R"], J["Spine"] - _hip_centre(J))
    Fc_r = frames_from(r["upperarm01.L"] - r["upperarm01.R"], r["neck01"] - r["spine01"])
    Fc = frames_from(J["UpperArm_L"] - J["UpperArm_R"], J["Neck"] - J["Chest"])
    Wp, Wc = Fp @ Fp_r.T, Fc @ Fc_r.T
    Wr["root"] = Wp
    for i, b in enumerate(SPINE):
        Wr[b] = slerp(Wp, Wc, i / (len(SPINE) - 1))
    # neck (carries the head): swing from the chest-posed rest direction onto neck -> head
    h_r = r["head"] - r["neck01"]
    Wr["neck01"] = swing(np.einsum("fij,j->fi", Wc, h_r), J["Head"] - J["Neck"]) @ Wc
    for s in "LR":
        # arm
        u_r = r[f"lowerarm01.{s}"] - r[f"upperarm01.{s}"]
        f_r = r[f"wrist.{s}"] - r[f"lowerarm01.{s}"]
        n_r = np.cross(u_r, f_r)
        u, f = J[f"LowerArm_{s}"] - J[f"UpperArm_{s}"], J[f"Hand_{s}"] - J[f"LowerArm_{s}"]
        fb = np.einsum("fij,fjk,k->fi", swing(np.einsum("fij,j->fi", Wc, u_r), u), Wc, n_r)
        n = _twist_normal(u, np.cross(u, f), _angle(u, f), fb)
        Wu = frames_from(u, n) @ frames_from(u_r, n_r).T
        Wr[f"upperarm01.{s}"] = Wu
        Wr[f"lowerarm01.{s}"] = swing(np.einsum("fij,j->fi", Wu, f_r), f) @ Wu
        # leg: knee flexion axis of the rest pose from the foot (the rest knee is straight)
        u_r = r[f"lowerleg01.{s}"] - r[f"upperleg01.{s}"]
        f_r = r[f"foot.{s}"] - r[f"lowerleg01.{s}"]
        t_r = r.toes(s) - r[f"foot.{s}"]
        n_r = np.cross(t_r, u_r)
        u, f = J[f"LowerLeg_{s}"] - J[f"UpperLeg_{s}"], J[f"Foot_{s}"] - J[f"LowerLeg_{s}"]
        t = J[f"Toes_{s}"] - J[f"Foot_{s}"]
        # straight knee: the foot's heading (toes x thigh), or the pelvis's where the foot
        # points along the thigh
        pel = np.einsum("fij,fjk,k->fi", swing(np.einsum("fij,j->fi", Wp, u_r), u), Wp, n_r)
        foot_n = _twist_normal(u, np.cross(t, u), _angle(t, u), pel, np.deg2rad(20), np.deg2rad(45))
        n = _twist_normal(u, np.cross(u, f), _angle(u, f), foot_n)
        Wt = frames_from(u, n) @ frames_from(u_r, n_r).T
        Wr[f"upperleg01.{s}"] = Wt
        Ws = swing(np.einsum("fij,j->fi", Wt, f_r), f) @ Wt
        Wr[f"lowerleg01.{s}"] = Ws
        # foot: turned up by the clip's stance offset about the ankle's axis (f x t: a positive
        # angle takes the toes away from the shin)
        m = np.cross(f, t)
        t_c = np.einsum("fij,fj->fi", rotvec_to_matrix(_unit(m) * ankle_offset[s]), t)
        Wf = swing(np.einsum("fij,j->fi", Ws, t_r), t_c) @ Ws
        Wr[f"foot.{s}"] = Wf
        # toes: bent up towards level while the ball of the foot is on the floor (toe-off),
        # fully within 1 cm of the clip's lowest ball height, not at all from 4 cm up
        d = np.einsum("fij,j->fi", Wf, r.toe_direction(s))
        level = d * np.array([1.0, 1.0, 0.0]) + np.maximum(d[:, 2:], 0.0) * np.array([0.0, 0.0, 1.0])
        ball = J[f"Toes_{s}"][:, 2] - J[f"Toes_{s}"][:, 2].min()
        w = np.clip((0.04 - ball) / 0.03, 0.0, 1.0)
        c = np.cross(_unit(d), _unit(level))
        sn = np.linalg.norm(c, axis=-1, keepdims=True)
        ang = np.arctan2(sn, np.sum(_unit(d) * _unit(level), -1, keepdims=True))
        Wtoe = rotvec_to_matrix(c / np.maximum(sn, 1e-12) * ang * w[:, None]) @ Wf
        for k in range(1, 6):
            Wr[f"toe{k}-1.{s}"] = Wtoe
    assert all(v.shape == (F, 3, 3) for v in Wr.values())
    return Wr


def local_deltas(W: Mapping[str, np.ndarray], rest: AnnyRest) -> np.ndarray:
    """(F, B, 4, 4) anny local-ref deltas D_b = W_parent^T W_b (anny composes W_b = W_parent D_b
    in the reference pose's world-aligned axes); undriven bones keep their parent's rotation."""
    F = len(next(iter(W.values())))
    B = len(rest.labels)
    Wall = np.empty((F, B, 3, 3))
    out = np.tile(np.eye(4), (F, B, 1, 1))
    for b in range(B):                           # parents precede children in anny's order
        p = int(rest.parents[b])
        parent = Wall[:, p] if p >= 0 else np.tile(np.eye(3), (F, 1, 1))
        Wall[:, b] = W.get(rest.labels[b], parent)
        out[:, b, :3, :3] = np.swapaxes(parent, -1, -2) @ Wall[:, b]
    return out


# --- rendering (build extra: torch + anny, imported lazily) -----------------------------------


@dataclass(frozen=True)
class Rendered:
    vertices: np.ndarray        # (F, V, 3) posed anny mesh, world metres (F: the window)
    faces: np.ndarray           # (T, 3)
    joints: np.ndarray          # (F, 15, 3) ground truth, GT_JOINTS order
    masks: np.ndarray           # (len(render_frames), C, H, W) bool
    stature_m: float            # rest-pose height of the subject
    start: int                  # first clip frame of the window
    yaw: float                  # turn about z applied to the clip, rad
    scale: float                # anny leg length / clip leg length
    ankle_offset: dict          # per side, rad
    floor_gap: np.ndarray       # (F,) lowest vertex height per frame (m)
    lift: np.ndarray            # (F,) vertical shift beyond the scaled clip's hip height (m)


def _phenotype(model, subject: Subject):
    import torch

    return {k: torch.tensor([float(subject.phenotype.get(k, 0.5))], dtype=model.dtype)
            for k in model.phenotype_labels}


def anny_rest(model, subject: Subject) -> tuple[AnnyRest, np.ndarray]:
    """anny's reference-pose skeleton of ``subject`` and its rest (bind) vertices."""
    import torch

    with torch.no_grad():
        ref = model(phenotype_kwargs=_phenotype(model, subject))
    return (AnnyRest(tuple(model.bone_labels), np.asarray(model.bone_parents, dtype=np.int64),
                     ref["bone_poses"][0, :, :3, 3].double().numpy()),
            ref["rest_vertices"][0].double().numpy())


def render(spec: RealMotionSpec, clips: Path, model=None, rig=None,
           render_frames: list[int] | None = None) -> Rendered:
    """Pose anny's mesh of ``spec.subject`` with the clip's chosen window; rasterise the
    silhouettes of ``render_frames`` (indices into the window; None: all)."""
    import torch

    from mocap.cameras import project
    from mocap.render.silhouette import rasterize_silhouettes

    model = load_anny() if model is None else model
    rig = benchmark_rig() if rig is None else rig
    subject = SUBJECTS[spec.subject]
    J, fps = load_clip(Path(clips) / spec.clip)
    if abs(fps - FPS) > 1e-6:
        raise ValueError(f"{spec.clip}: {fps} fps, the benchmark expects {FPS}")
    rest, rest_verts = anny_rest(model, subject)
    scale = rest.leg_length() / leg_length(J)
    offsets = ankle_offsets(J, rest.foot_drops())
    start = choose_window(J, scale, rig)
    W, yaw = place_clip(J, scale, start, FRAMES)
    deltas = local_deltas(world_rotations(W, rest, offsets), rest)
    pheno = _phenotype(model, subject)
    with torch.no_grad():
        out = model(pose_parameters=torch.as_tensor(deltas, dtype=model.dtype), phenotype_kwargs=pheno)
        verts = out["vertices"].double().numpy()
        heads = out["bone_poses"][..., :3, 3].double().numpy()
        weights = model.dense_vertex_bone_weights.double().numpy()
    labels = list(rest.labels)
    # the root: anny's hip centre onto the clip's (scaled, placed) hip centre horizontally;
    # vertically, anny's lowest vertex onto the clip's contact height (0 while a foot is down)
    hip = 0.5 * (heads[:, labels.index("upperleg01.L")] + heads[:, labels.index("upperleg01.R")])
    shift = (_hip_centre(W) - hip)[:, None, :]
    contact = contact_height(J, start, FRAMES) * scale
    shift[:, 0, 2] = contact - verts[..., 2].min(axis=1)
    lift = shift[:, 0, 2] - (_hip_centre(W)[:, 2] - hip[:, 2])
    verts, heads = verts + shift, heads + shift
    head_centre = verts[:, weights[:, labels.index("head")] > HEAD_WEIGHT].mean(axis=1)
    joints = gt_joints(heads, labels, head_centre)
    faces = model.get_triangular_faces().numpy().astype(np.int64)
    w, h = (int(x) for x in rig.sizes[0])
    todo = list(range(FRAMES)) if render_frames is None else list(render_frames)
    masks = np.empty((len(todo), len(rig), h, w), dtype=bool)
    for i, f in enumerate(todo):
        px, depth = project(rig, verts[f], return_depth=True)
        masks[i] = rasterize_silhouettes(px, faces, h, w, depth)
    edge = (masks[..., 0, :].any(-1) | masks[..., -1, :].any(-1) | masks[..., :, 0].any(-1)
            | masks[..., :, -1].any(-1))
    if edge.any():
        f, c = np.argwhere(edge)[0]
        raise ValueError(f"{spec.key}: the silhouette touches the image border in "
                         f"{int(edge.sum())} views (first: frame {todo[f]}, view {c})")
    return Rendered(vertices=verts, faces=faces, joints=joints, masks=masks,
                    stature_m=float(rest_verts[:, 2].max() - rest_verts[:, 2].min()),
                    start=start, yaw=yaw, scale=float(scale), ankle_offset=offsets,
                    floor_gap=verts[..., 2].min(axis=1), lift=lift)


def detection_labels() -> tuple[str, ...]:
    """The detections' label names: our catalogue's names of the HumanEva-15 joints (so the
    marker tracker's ``landmarks: auto`` resolves them)."""
    from mocap.body.skeletons import SKELETONS

    return tuple(SKELETONS["humaneva15"][n] for n in GT_JOINTS)


def detect(joints: np.ndarray, rig, seed: int):
    """Canton-style corrupted 2D detections (:data:`DETECTION`) of ``joints`` (F, 15, 3) in
    every view, from ``np.random.default_rng(seed)``; pixels rounded to 0.01 px, confidences
    to 0.001 (small files)."""
    from mocap.cameras import project
    from mocap.data.corruption import DetectionModel
    from mocap.data.sequence import Detections

    model = DetectionModel(**DETECTION)
    rng = np.random.default_rng(seed)
    w, h = (int(x) for x in rig.sizes[0])
    rows = []
    for f in range(len(joints)):
        px, depth = project(rig, joints[f], return_depth=True)
        for c in range(len(rig)):
            lab, xy, conf = model.sample(px[c], depth[c] > 0.05, w, h, rng)
            rows += [(f, c, int(lb), x, y, cf) for lb, (x, y), cf in zip(lab, xy, conf, strict=True)]
    a = np.array(rows, dtype=np.float64).reshape(-1, 6)
    return Detections(labels=detection_labels(), frame=a[:, 0].astype(np.int64),
                      view=a[:, 1].astype(np.int64), label=a[:, 2].astype(np.int64),
                      xy=np.round(a[:, 3:5], 2), confidence=np.round(a[:, 5], 3))


def sequence_seed(spec: RealMotionSpec) -> int:
    return zlib.crc32(spec.key.encode())


def to_sequence(spec: RealMotionSpec, clips: Path, model=None, rig=None):
    """The :class:`~mocap.data.sequence.Sequence` of one benchmark entry and its Rendered."""
    from mocap.data.sequence import GroundTruth, Sequence
    from mocap_build.mismatch.surface import surface_meta, surface_subset

    model = load_anny() if model is None else model
    rig = benchmark_rig() if rig is None else rig
    r = render(spec, clips, model, rig)
    subset = surface_subset(model)
    gt = GroundTruth(alpha=None, chi=None, joints=r.joints, markers=None, dof_names=(),
                     joint_names=tuple(GT_JOINTS), marker_names=(), body="",
                     joint_valid=np.ones(r.joints.shape[:2], bool), skeleton="humaneva15",
                     surface=subset.points(r.faces, r.vertices), surface_faces=subset.faces)
    subject = SUBJECTS[spec.subject]
    meta = {
        "source": "rendered by anny (full-resolution mesh, its own 104-bone linear blend "
                  "skinning), not by the tracker's PCA model; posed from a real motion-capture clip",
        "generator": GENERATOR_VERSION, "anny_version": _anny_version(),
        "split": spec.split, "motion": spec.motion, "clip": spec.clip,
        "clip_frames": [r.start, r.start + FRAMES], "yaw_deg": round(np.degrees(r.yaw), 3),
        "scale": round(r.scale, 5),
        "subject": spec.subject, "subject_description": subject.description,
        "phenotype": dict(subject.phenotype), "stature_m": round(r.stature_m, 4),
        "vertices": int(r.vertices.shape[1]), "faces": int(len(r.faces)),
        "ground_truth": {k: "+".join(v) for k, v in GT_JOINTS.items()},
        "detections": {**DETECTION, "seed": sequence_seed(spec), "labels": "HumanEva-15 joints by "
                       "our catalogue's names (landmarks: auto)"},
        "licence": "derived from Anny (NAVER, Apache-2.0) and MakeHuman/MPFB2 assets (CC0) and "
                   "from the Bandai-Namco-Research-Motiondataset (CC BY-NC 4.0, non-commercial); "
                   "see NOTICE.txt",
        "surface": surface_meta(subset),
    }
    seq = Sequence(name=f"real_{spec.name}", rig=rig, fps=FPS, masks=r.masks, gt=gt,
                   detections=detect(r.joints, rig, sequence_seed(spec)), meta=meta)
    return seq, r
