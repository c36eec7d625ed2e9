"""The model-mismatch benchmark: sequences rendered NOT by the tracker's PCA body model.

The generator (``mocap_build/make_mismatch.py``, build extra: torch + anny) poses the
full-resolution anny mesh (13,718 vertices, anny's own 104-bone linear blend skinning) of
subjects whose phenotypes were not among the bodies the shipped PCA was built from, with
procedural motions written directly as anny bone rotations (independent of
:mod:`mocap.data.motion` and of mocap's twist chain), renders exact silhouettes with
mocap's rasterizer on an 8-view ring, and stores ground-truth joints defined anatomically
on anny's posed skeleton, named as the HumanEva-15 skeleton.

This module holds the pure-numpy parts (no torch): subjects, the motion curves, the
ground-truth joint definitions and the pose assembly. Conventions (anny's, equal to mocap's
body frame): metres, z up, the subject's front is -y, its left +x. Bone rotations are given
in anny's ``local-ref`` parameterisation: each bone's delta rotation is expressed in the
world-aligned axes of anny's reference pose (an A-pose) and composed down the chain, so a
rotation about +x swings a bone hanging down backwards (towards +y).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

GENERATOR_VERSION = "mismatch-v1"
FPS = 25.0
FRAMES = 60

# ground-truth joint (HumanEva-15 names) -> anny bones whose posed heads are averaged;
# "head" is the centroid of the vertices skinned to the head bone (weight > 0.9).
GT_JOINTS: dict[str, tuple[str, ...]] = {
    "pelvis": ("upperleg01.L", "upperleg01.R"),         # mid-point of the hip centres
    "thorax": ("clavicle.L", "clavicle.R"),             # sternal ends of the clavicles
    "head": ("@head-vertices",),
    "lsho": ("upperarm01.L",), "lelb": ("lowerarm01.L",), "lwri": ("wrist.L",),
    "rsho": ("upperarm01.R",), "relb": ("lowerarm01.R",), "rwri": ("wrist.R",),
    "lhip": ("upperleg01.L",), "lkne": ("lowerleg01.L",), "lank": ("foot.L",),
    "rhip": ("upperleg01.R",), "rkne": ("lowerleg01.R",), "rank": ("foot.R",),
}
HEAD_WEIGHT = 0.9
# parents of GT_JOINTS (for drawing): pelvis, thorax, head, arms, legs
GT_PARENTS = np.array([-1, 0, 1, 1, 3, 4, 1, 6, 7, 0, 9, 10, 0, 12, 13])


@dataclass(frozen=True)
class MismatchSpec:
    name: str
    motion: str
    subject: str
    phenotype: Mapping[str, float]     # anny phenotype parameters in [0, 1]
    description: str


SEQUENCES: dict[str, MismatchSpec] = {
    "walk": MismatchSpec(
        "walk", "walk", "tall_slim_man",
        {"gender": 0.95, "age": 0.55, "muscle": 0.45, "weight": 0.3, "height": 0.8,
         "proportions": 0.6},
        "walking on an arc (radius 0.7 m, ~150 deg) with arm swing, pelvis/spine "
        "counter-rotation, neck and ankle motion"),
    "box": MismatchSpec(
        "box", "box", "heavy_muscular_man",
        {"gender": 1.0, "age": 0.6, "muscle": 0.95, "weight": 0.8, "height": 0.55,
         "proportions": 0.45},
        "shadow boxing: guard, jabs and crosses, torso twist, wrists, head movement"),
    "gesture_turn": MismatchSpec(
        "gesture_turn", "gesture_turn", "middle_aged_woman",
        {"gender": 0.2, "age": 0.7, "muscle": 0.35, "weight": 0.6, "height": 0.3,
         "proportions": 0.5},
        "arm gestures (wave, point, open arms) while the whole body turns 90 deg about "
        "the vertical"),
}


# --- rotations ---------------------------------------------------------------------------


def rotvec_to_matrix(rv: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 3, 3) matrices (Rodrigues)."""
    rv = np.asarray(rv, dtype=np.float64)
    th = np.linalg.norm(rv, axis=-1)[..., None, None]
    k = rv / np.where(th[..., 0] > 1e-12, th[..., 0], 1.0)
    K = np.zeros(rv.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -k[..., 2], k[..., 1]
    K[..., 1, 0], K[..., 1, 2] = k[..., 2], -k[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -k[..., 1], k[..., 0]
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def axis_angle(axis, angle: np.ndarray) -> np.ndarray:
    """(F, 3, 3) rotations by ``angle`` (F,) radians about a fixed unit ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return rotvec_to_matrix(np.asarray(angle, dtype=np.float64)[..., None] * a)


def rotation_between(a, b) -> np.ndarray:
    """The rotation vector of the smallest rotation taking direction ``a`` to ``b``."""
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    c = np.cross(a, b)
    s = np.linalg.norm(c)
    return c / max(s, 1e-12) * np.arctan2(s, float(a @ b))


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _pulse(t: np.ndarray, start: float, rise: float, hold: float, fall: float) -> np.ndarray:
    """0 -> 1 -> 0: smooth rise from ``start`` over ``rise`` s, hold, smooth fall (s)."""
    up = _smoothstep((t - start) / rise)
    down = _smoothstep((t - start - rise - hold) / fall)
    return up * (1 - down)


# --- motions -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Motion:
    """Per-bone delta rotations (F, 3, 3) in anny's local-ref axes (bones not listed stay
    at the reference pose); the root's yaw (F,) about +z (0: facing -y) and its horizontal
    world position (F, 2). The generator puts the lowest vertex of every frame on z = 0."""

    rotations: dict[str, np.ndarray]
    yaw: np.ndarray
    position: np.ndarray


class _Pose:
    """Accumulates rotations per bone: ``add(bone, R)`` applies R after what is there."""

    def __init__(self, frames: int):
        self.F = frames
        self.rot: dict[str, np.ndarray] = {}

    def add(self, bone: str, R: np.ndarray) -> None:
        R = np.broadcast_to(R, (self.F, 3, 3))
        self.rot[bone] = R @ self.rot[bone] if bone in self.rot else np.array(R)

    def about(self, bone: str, axis, angle) -> None:
        self.add(bone, axis_angle(axis, np.broadcast_to(np.asarray(angle, float), (self.F,))))


def _arm_axes(ref: Mapping[str, np.ndarray], side: str):
    """(upper-arm direction, elbow flexion axis, elbow flexion angle) of one arm in the
    reference pose (whose elbows are already bent); a positive rotation about the axis
    bends the elbow further."""
    u = _unit(ref[f"lowerarm01.{side}"] - ref[f"upperarm01.{side}"])
    f = _unit(ref[f"wrist.{side}"] - ref[f"lowerarm01.{side}"])
    return u, _unit(np.cross(u, f)), float(np.arccos(np.clip(u @ f, -1.0, 1.0)))


def _arm_to(pose: _Pose, ref, side: str, direction: np.ndarray, elbow: np.ndarray,
            twist: np.ndarray | float = 0.0) -> None:
    """Point the upper arm along ``direction`` (F, 3) (torso axes) with the elbow flexed by
    ``elbow`` (F,) radians (0: straight), rotating the arm about its own axis by ``twist``
    first (positive: the forearm turns towards the body's midline for either arm)."""
    u, flex, bent = _arm_axes(ref, side)
    F = pose.F
    pose.about(f"lowerarm01.{side}", flex, np.asarray(elbow, float) - bent)
    sgn = 1.0 if side == "L" else -1.0
    tw = axis_angle(u, sgn * np.broadcast_to(np.asarray(twist, float), (F,)))
    swing = np.stack([rotvec_to_matrix(rotation_between(u, d)) for d in direction])
    pose.add(f"upperarm01.{side}", swing @ tw)


def _slerp_dirs(a, b, w: np.ndarray) -> np.ndarray:
    """(F, 3) unit directions interpolated from ``a`` (F, 3 or 3) to ``b`` by weight w (F,)."""
    a = np.broadcast_to(np.asarray(a, float), (len(w), 3))
    b = np.broadcast_to(np.asarray(b, float), (len(w), 3))
    d = (1 - w)[:, None] * a + w[:, None] * b
    return d / np.linalg.norm(d, axis=1, keepdims=True)


X, Y, Z = np.eye(3)


def motion_walk(t: np.ndarray, ref: Mapping[str, np.ndarray]) -> Motion:
    """Gait on a counter-clockwise arc: radius 0.7 m at 0.75 m/s, stride period 1.2 s."""
    F = len(t)
    p = _Pose(F)
    ph = 2 * np.pi * t / 1.2 + 0.3
    s, c = np.sin(ph), np.cos(ph)
    for side, sgn in (("L", 1.0), ("R", -1.0)):
        sp, cp = sgn * s, sgn * c
        # hip: flexion (forward = rotation about -x) and a little abduction
        p.about(f"upperleg01.{side}", -X, 0.05 + 0.42 * sp)
        p.about(f"upperleg01.{side}", Y, sgn * 0.03 * (1 + cp))
        # knee: flexes in swing (leading the hip by a quarter period), some in stance
        ph_side = ph + (0.0 if sgn > 0 else np.pi)
        swing = _smoothstep(0.5 + 0.5 * np.sin(ph_side + 0.9))
        p.about(f"lowerleg01.{side}", X, 0.12 + 0.75 * swing)
        p.about(f"foot.{side}", X, -0.05 + 0.22 * np.sin(ph_side - 0.8))
        # arms: down from the A-pose, swing opposite to the leg, elbow bent a little
        down = _unit([sgn * 0.18, 0.0, -1.0])
        fwd = np.stack([_unit(down + np.array([0, 0.45 * a, 0])) for a in sp])
        _arm_to(p, ref, side, fwd, 0.35 - 0.2 * sp, twist=0.3)
        p.about(f"wrist.{side}", X, 0.15 * cp)
    # pelvis counter-rotation against the shoulders, lateral tilt, spine compensation
    p.about("spine05", Z, -0.10 * s)
    for b in ("spine03", "spine02", "spine01"):
        p.about(b, Z, 0.07 * s)
    p.about("spine04", Y, 0.04 * np.sin(2 * ph))
    p.about("spine02", -X, 0.06)                                  # slight forward lean
    p.about("neck01", -X, 0.08 * np.sin(2 * ph) + 0.05)
    p.about("neck02", Z, 0.12 * np.sin(2 * np.pi * t / 2.4))     # looks around slowly
    for b in ("pelvis.L", "pelvis.R"):
        p.about(b, Z, 0.10 * s)
    # the path: arc of radius 0.7 m around the origin, heading along the tangent
    theta = -1.3 + 0.75 * t / 0.7
    pos = 0.7 * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    return Motion(p.rot, theta + np.pi, pos)


def motion_box(t: np.ndarray, ref: Mapping[str, np.ndarray]) -> Motion:
    """Boxing stance facing 20 deg left of -y; jabs, crosses and a hook with torso twist."""
    F = len(t)
    p = _Pose(F)
    bounce = np.sin(2 * np.pi * t / 0.6)
    # stance: left foot forward, knees bent
    p.about("upperleg01.L", -X, 0.30)
    p.about("upperleg01.L", -Y, 0.08)
    p.about("upperleg01.R", X, 0.15)
    p.about("upperleg01.R", Y, 0.10)
    p.about("lowerleg01.L", X, 0.35 + 0.05 * bounce)
    p.about("lowerleg01.R", X, 0.30 + 0.05 * bounce)
    p.about("foot.L", -X, 0.05 + 0.04 * bounce)
    p.about("foot.R", X, 0.10 - 0.04 * bounce)
    # punches (start, rise, hold, fall in s): left jab x2, right cross, left hook, right cross
    jab_l = _pulse(t, 0.20, 0.12, 0.06, 0.18) + _pulse(t, 0.75, 0.10, 0.05, 0.15)
    hook_l = _pulse(t, 1.70, 0.15, 0.08, 0.20)
    cross_r = _pulse(t, 1.10, 0.13, 0.06, 0.20) + _pulse(t, 2.05, 0.12, 0.05, 0.16)
    # torso twist: towards the right for a left punch (shoulder forward), left for a right
    twist = 0.30 * cross_r - 0.25 * jab_l - 0.45 * hook_l + 0.08 * bounce
    for b, share in (("spine04", 0.2), ("spine03", 0.3), ("spine02", 0.25), ("spine01", 0.25)):
        p.about(b, -Z, share * twist)
    p.about("spine02", -X, 0.12 + 0.05 * (jab_l + cross_r))
    # head: chin down, slips against the punches
    p.about("neck01", -X, 0.15 + 0.05 * bounce)
    p.about("neck02", Z, 0.8 * 0.5 * twist)
    p.about("neck03", Y, 0.15 * np.sin(2 * np.pi * t / 1.3))
    guard = {"L": _unit([0.25, -0.55, -0.8]), "R": _unit([-0.25, -0.45, -0.85])}
    punch = {"L": _unit([-0.10, -1.0, 0.05]), "R": _unit([0.05, -1.0, 0.05])}
    hook = _unit([0.75, -0.65, 0.0])
    for side, sgn, pw in (("L", 1.0, jab_l), ("R", -1.0, cross_r)):
        d = _slerp_dirs(guard[side], punch[side], pw)
        elbow = 2.0 * (1 - pw) + 0.15 * pw
        if side == "L":
            d = _slerp_dirs(d, hook, hook_l)
            elbow = elbow * (1 - hook_l) + 1.6 * hook_l
        _arm_to(p, ref, side, d, elbow, twist=0.4 * (1 - pw))
        p.about(f"wrist.{side}", -X, 0.25 * (1 - pw) - 0.1 * pw)
        p.about(f"wrist.{side}", Z, sgn * 0.2 * np.sin(2 * np.pi * t / 0.9))
    yaw = np.deg2rad(-20.0) + 0.1 * np.sin(2 * np.pi * t / 2.4)
    pos = np.stack([0.15 * np.sin(2 * np.pi * t / 2.4), 0.10 * np.sin(2 * np.pi * t / 1.2)], axis=1)
    return Motion(p.rot, yaw, pos)


def motion_gesture_turn(t: np.ndarray, ref: Mapping[str, np.ndarray]) -> Motion:
    """Turns 90 deg to the left between 0.3 and 2.0 s while gesturing: the right hand waves
    overhead, then the left arm points forward, then both arms open; head leads the turn."""
    F = len(t)
    p = _Pose(F)
    x = np.clip((t - 0.3) / 1.7, 0.0, 1.0)
    turn = _smoothstep(x)
    yaw = np.deg2rad(90.0) * turn
    dturn = 6 * x * (1 - x) / 1.7                    # d(turn)/dt, per second
    # legs: weight shift, a small step rhythm while pivoting
    shift = np.sin(2 * np.pi * t / 1.0)
    for side, sgn in (("L", 1.0), ("R", -1.0)):
        lift = np.clip(sgn * shift, 0, None) * np.clip(dturn, 0, 1)
        p.about(f"upperleg01.{side}", -X, 0.05 + 0.5 * lift)
        p.about(f"upperleg01.{side}", Y, sgn * 0.04)
        p.about(f"lowerleg01.{side}", X, 0.08 + 0.9 * lift)
        p.about(f"foot.{side}", X, -0.05 + 0.3 * lift)
    p.about("spine05", Y, 0.04 * shift)
    # trunk leads the turn, neck and head lead more
    lead = 0.25 * np.clip(dturn, 0, 1.5)
    for b in ("spine03", "spine02", "spine01"):
        p.about(b, Z, 0.5 * lead)
    p.about("spine02", Y, -0.08 * _pulse(t, 0.1, 0.4, 0.4, 0.4))     # lean with the wave
    p.about("neck02", Z, lead + 0.15 * np.sin(2 * np.pi * t / 1.6))
    p.about("neck01", X, -0.1 * np.sin(2 * np.pi * t / 2.0))
    rest_side = {"L": _unit([0.2, 0.0, -1.0]), "R": _unit([-0.2, 0.0, -1.0])}
    # right hand: raised to the side and up, waving with the elbow and wrist
    wave = _pulse(t, 0.05, 0.35, 0.75, 0.35)
    up_r = _unit([-0.55, -0.2, 0.8])
    osc = np.sin(2 * np.pi * t / 0.45)
    d_r = _slerp_dirs(rest_side["R"], up_r, wave)
    # both arms open wide at the end
    opened = _pulse(t, 1.75, 0.3, 0.5, 0.25)
    d_r = _slerp_dirs(d_r, _unit([-1.0, -0.5, 0.15]), opened)
    _arm_to(p, ref, "R", d_r, 0.2 + wave * (1.1 + 0.35 * osc) + 0.3 * opened)
    p.about("wrist.R", Z, wave * 0.35 * osc)
    # left arm: points forward (and follows the turn), then opens
    point = _pulse(t, 0.9, 0.35, 0.55, 0.3)
    d_l = _slerp_dirs(rest_side["L"], _unit([0.25, -1.0, 0.25]), point)
    d_l = _slerp_dirs(d_l, _unit([1.0, -0.5, 0.15]), opened)
    _arm_to(p, ref, "L", d_l, 0.25 * (1 - point) + 0.05 + 0.3 * opened)
    p.about("wrist.L", X, -0.4 * point + 0.2 * opened)
    p.about("wrist.R", X, -0.3 * opened)
    pos = np.stack([0.05 * np.sin(np.pi * t / 2.4), 0.03 * shift], axis=1)
    return Motion(p.rot, yaw, pos)


MOTIONS = {"walk": motion_walk, "box": motion_box, "gesture_turn": motion_gesture_turn}


def frame_times(frames: int = FRAMES, fps: float = FPS) -> np.ndarray:
    return np.arange(frames) / fps


def pose_matrices(motion: Motion, bone_labels: list[str]) -> np.ndarray:
    """(F, B, 4, 4) delta transforms for anny's forward (local-ref); the root's carries
    the yaw (its translation stays 0: the generator places the body afterwards)."""
    F = len(motion.yaw)
    out = np.tile(np.eye(4), (F, len(bone_labels), 1, 1))
    unknown = set(motion.rotations) - set(bone_labels)
    if unknown:
        raise KeyError(f"motion rotates unknown bones: {sorted(unknown)}")
    for b, R in motion.rotations.items():
        out[:, bone_labels.index(b), :3, :3] = R
    out[:, bone_labels.index("root"), :3, :3] = axis_angle(Z, motion.yaw) @ \
        out[:, bone_labels.index("root"), :3, :3]
    return out


def place_on_floor(vertices: np.ndarray, heads: np.ndarray,
                   position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shift each frame horizontally to ``position`` (F, 2) (the root bone's head) and
    vertically so that its lowest vertex is on z = 0. vertices (F, V, 3), heads (F, B, 3)
    with the root's head at index 0."""
    shift = np.zeros((len(vertices), 1, 3))
    shift[:, 0, :2] = position - heads[:, 0, :2]
    shift[:, 0, 2] = -vertices[..., 2].min(axis=1)
    return vertices + shift, heads + shift


def gt_joints(heads: np.ndarray, bone_labels: list[str], head_centre: np.ndarray) -> np.ndarray:
    """(F, 15, 3) ground-truth joints in the order of :data:`GT_JOINTS` from the posed
    bone heads (F, B, 3) and the head-vertex centroid (F, 3)."""
    out = []
    for bones in GT_JOINTS.values():
        if bones == ("@head-vertices",):
            out.append(head_centre)
        else:
            out.append(heads[:, [bone_labels.index(b) for b in bones]].mean(axis=1))
    return np.stack(out, axis=1)


# --- rendering (build extra: torch + anny, imported lazily) ------------------------------


def benchmark_rig(size: int = 500):
    """The mpi08 ring (8 views, 4 m radius, 1.8 m high, 40 deg field of view) at
    ``size`` x ``size`` pixels."""
    from mocap.cameras.rigs import ring_rig

    return ring_rig(num_cameras=8, radius=4.0, height=1.8, width=size, image_height=size,
                    fov_deg=40.0, look_at=(0.0, 0.0, 0.9))


def load_anny():
    """anny's full-body model with its own 104-bone linear blend skinning (build extra)."""
    from anny import Anny

    return Anny(skinning_method="lbs")


@dataclass(frozen=True)
class Rendered:
    vertices: np.ndarray        # (F, V, 3) posed anny mesh, world metres
    faces: np.ndarray           # (T, 3)
    joints: np.ndarray          # (F, 15, 3) ground truth, GT_JOINTS order
    masks: np.ndarray           # (F, C, H, W) bool
    stature_m: float            # rest-pose height of the subject


def render(spec: MismatchSpec, model=None, rig=None, frames: int = FRAMES,
           fps: float = FPS, masks: bool = True) -> Rendered:
    """Pose anny's mesh of ``spec`` with its motion and render exact silhouettes (none, an
    empty masks array, with ``masks=False``)."""
    import torch

    from mocap.cameras import project
    from mocap.render.silhouette import rasterize_silhouettes

    model = load_anny() if model is None else model
    rig = benchmark_rig() if rig is None else rig
    labels = list(model.bone_labels)
    dtype = model.dtype if hasattr(model, "dtype") else torch.float64
    pheno = {k: torch.tensor([float(spec.phenotype.get(k, 0.5))], dtype=dtype)
             for k in model.phenotype_labels}
    with torch.no_grad():
        ref = model(phenotype_kwargs=pheno)
        ref_heads = ref["bone_poses"][0, :, :3, 3].double().numpy()
        rest = ref["rest_vertices"][0].double().numpy()
        t = frame_times(frames, fps)
        motion = MOTIONS[spec.motion](t, dict(zip(labels, ref_heads, strict=True)))
        deltas = torch.as_tensor(pose_matrices(motion, labels), dtype=dtype)
        out = model(pose_parameters=deltas, phenotype_kwargs=pheno)
        verts = out["vertices"].double().numpy()
        heads = out["bone_poses"][..., :3, 3].double().numpy()
        weights = model.dense_vertex_bone_weights.double().numpy()
    verts, heads = place_on_floor(verts, heads, motion.position)
    head_centre = verts[:, weights[:, labels.index("head")] > HEAD_WEIGHT].mean(axis=1)
    joints = gt_joints(heads, labels, head_centre)
    faces = model.get_triangular_faces().numpy().astype(np.int64)
    w, h = (int(x) for x in rig.sizes[0])
    keep = masks
    masks = np.empty((frames if keep else 0, len(rig), h, w), dtype=bool)
    for f in range(len(masks)):
        px, depth = project(rig, verts[f], return_depth=True)
        masks[f] = rasterize_silhouettes(px, faces, h, w, depth)
    edge = (masks[..., 0, :].any(-1) | masks[..., -1, :].any(-1) | masks[..., :, 0].any(-1)
            | masks[..., :, -1].any(-1))
    if edge.any():
        f, c = np.argwhere(edge)[0]
        raise ValueError(f"{spec.name}: the silhouette touches the image border in "
                         f"{int(edge.sum())} views (first: frame {f}, view {c})")
    return Rendered(vertices=verts, faces=faces, joints=joints, masks=masks,
                    stature_m=float(rest[:, 2].max() - rest[:, 2].min()))


def to_sequence(spec: MismatchSpec, model=None, rig=None, frames: int = FRAMES):
    """The :class:`~mocap.data.sequence.Sequence` of one benchmark entry (masks + ground
    truth by HumanEva-15 name, no chi/alpha: the tracker's model did not make it)."""
    from mocap.data.sequence import GroundTruth, Sequence
    from mocap_build.mismatch.surface import surface_meta, surface_subset

    model = load_anny() if model is None else model
    r = render(spec, model, rig, frames)
    rig = benchmark_rig() if rig is None else rig
    subset = surface_subset(model)
    gt = GroundTruth(alpha=None, chi=None, joints=r.joints, markers=None, dof_names=(),
                     joint_names=tuple(GT_JOINTS), marker_names=(), body="",
                     joint_valid=np.ones(r.joints.shape[:2], bool), skeleton="humaneva15",
                     surface=subset.points(r.faces, r.vertices), surface_faces=subset.faces)
    meta = {
        "source": "rendered by anny (full-resolution mesh, its own 104-bone linear blend "
                  "skinning), not by the tracker's PCA model",
        "generator": GENERATOR_VERSION, "anny_version": _anny_version(),
        "motion": spec.motion, "motion_description": spec.description,
        "subject": spec.subject, "phenotype": dict(spec.phenotype),
        "stature_m": round(r.stature_m, 4), "vertices": int(r.vertices.shape[1]),
        "faces": int(len(r.faces)),
        "ground_truth": {k: "+".join(v) for k, v in GT_JOINTS.items()},
        "licence": "derived from Anny (NAVER, Apache-2.0) and MakeHuman/MPFB2 assets (CC0); "
                   "see NOTICE.txt",
        "surface": surface_meta(subset),
    }
    return Sequence(name=f"mismatch_{spec.name}", rig=rig, fps=FPS, masks=r.masks, gt=gt,
                    meta=meta)


def _anny_version() -> str:
    try:
        import importlib.metadata

        return importlib.metadata.version("anny")
    except Exception:  # noqa: BLE001
        return "unknown"


def write_mismatch(seq, folder) -> object:
    """write_sequence, then the masks re-encoded as 1-bit PNGs at full compression
    (~10x smaller; they load the same)."""
    import cv2

    from mocap.data.sequence_io import write_sequence

    path = write_sequence(seq, folder, overwrite=True)
    for png in sorted(path.glob("masks/*/*.png")):
        m = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(png), m, [cv2.IMWRITE_PNG_COMPRESSION, 9, cv2.IMWRITE_PNG_BILEVEL, 1])
    return path


def contact_sheets(seqs, path, frame: int | None = None, tile_width: int = 220):
    """One contact sheet per sequence (8 views, ground-truth skeleton), stacked."""
    from mocap.viz.contact_sheet import contact_sheet, save_png

    sheets = [contact_sheet(s, s.num_frames // 2 if frame is None else frame, GT_PARENTS,
                            tile_width=tile_width) for s in seqs]
    return save_png(np.concatenate(sheets, axis=0), path)
