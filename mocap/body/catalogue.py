"""The landmarks a marker tracker fits: a catalogue of named points on the body, chosen by
name (or given as definitions) in the tracker's configuration, and the pairs of landmarks
whose distance no pose can change (the "bones" used to fit the subject's size).

The catalogue holds the project's default marker set (the 15 HumanEva joints plus head
top, chest, hands and toes, :data:`mocap.body.landmarks.DEFAULT_LANDMARKS`) and the extra
points of 2D keypoint detectors (OpenPose BODY_25 / BODY_25B: nose, eyes, ears, neck,
neck base (between the clavicles: HumanEva's ``thorax``), mid-hip, heels, small toes) and the
points that evaluation skeletons name where no joint of ours sits (the centre of the head:
the centroid of the head part).
Face and foot points are approximate: the vertex of the head or foot part furthest along a
direction on the mean body.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mocap.body.landmarks import DEFAULT_LANDMARKS, LandmarkSet
from mocap.body.model import BodyModel

KEYPOINT_LANDMARKS: tuple[Mapping, ...] = (
    {"name": "nose", "joint": "head", "extreme": [0, -1, 0]},
    {"name": "l_eye", "joint": "head", "extreme": [0.35, -1, 0.25]},
    {"name": "r_eye", "joint": "head", "extreme": [-0.35, -1, 0.25]},
    {"name": "l_ear", "joint": "head", "extreme": [1, 0, 0]},
    {"name": "r_ear", "joint": "head", "extreme": [-1, 0, 0]},
    {"name": "neck", "joint": "neck", "at": "neck"},
    {"name": "neck_base", "joint": "thorax", "between": ["l_clavicle", "r_clavicle"]},
    # the midpoint of the hip joints (OpenPose's MidHip, the pelvis of HumanEva-style
    # skeletons); our ``pelvis`` joint sits ~16 mm above it
    {"name": "mid_hip", "joint": "pelvis", "between": ["l_hip", "r_hip"]},
    {"name": "l_heel", "joint": "l_ankle", "extreme": [0, 1, -1]},
    {"name": "r_heel", "joint": "r_ankle", "extreme": [0, 1, -1]},
    {"name": "l_small_toe", "joint": "l_ankle", "extreme": [1, -1, -0.3]},
    {"name": "r_small_toe", "joint": "r_ankle", "extreme": [-1, -1, -0.3]},
)

#: points that ground-truth skeletons name and the two sets above do not hold
EVALUATION_LANDMARKS: tuple[Mapping, ...] = (
    {"name": "head_centre", "joint": "head", "centroid": True},
)

CATALOGUE: dict[str, Mapping] = {e["name"]: e for e in (*DEFAULT_LANDMARKS, *KEYPOINT_LANDMARKS,
                                                          *EVALUATION_LANDMARKS)}


def landmarks_with(body: BodyModel, names: Sequence[str | None]) -> LandmarkSet:
    """The default landmark set plus the catalogue's landmarks among ``names`` that are neither
    a joint of ``body`` nor in the default set (names it does not know are ignored): the points
    a ground-truth skeleton is scored on."""
    default = {e["name"] for e in DEFAULT_LANDMARKS}
    extra = [CATALOGUE[n] for n in dict.fromkeys(n for n in names if n)
             if n in CATALOGUE and n not in default and n not in body.joint_names]
    return LandmarkSet(body, (*DEFAULT_LANDMARKS, *extra))


def landmark_entries(spec: str | Sequence[str | Mapping] | None,
                     available: Sequence[str] | None = None) -> tuple[Mapping, ...]:
    """Landmark definitions from a configuration value.

    spec: ``"default"`` (or None): the default marker set; ``"auto"``: the catalogue entries
    named in ``available`` (the detections' label names, in their order; unknown names are
    skipped); a list of catalogue names and/or full definitions (mappings with ``name``,
    ``joint`` and ``at`` / ``vertex`` / ``extreme``, see :mod:`mocap.body.landmarks`).
    """
    if spec is None or spec == "default":
        return tuple(DEFAULT_LANDMARKS)
    if spec == "auto":
        if available is None:
            raise ValueError("landmarks='auto' needs the detections' label names")
        entries = tuple(CATALOGUE[n] for n in available if n in CATALOGUE)
        if not entries:
            raise ValueError(f"none of the detection labels {list(available)} is a known landmark "
                             f"(known: {', '.join(CATALOGUE)})")
        return entries
    if isinstance(spec, str):
        raise ValueError(f"landmarks must be 'default', 'auto' or a list, got {spec!r}")
    out = []
    for item in spec:
        if isinstance(item, str):
            if item not in CATALOGUE:
                raise KeyError(f"unknown landmark {item!r} (known: {', '.join(CATALOGUE)})")
            out.append(CATALOGUE[item])
        else:
            out.append(dict(item))
    return tuple(out)


def make_landmark_set(body: BodyModel, spec: str | Sequence[str | Mapping] | None = "default",
                      available: Sequence[str] | None = None) -> LandmarkSet:
    return LandmarkSet(body, landmark_entries(spec, available))


def rest_point_basis(body: BodyModel, landmarks: LandmarkSet) -> tuple[np.ndarray, np.ndarray]:
    """Rest landmarks are linear in the shape: R(alpha) = R0 + sum_k alpha_k B_k.

    Returns R0: (L, 3) and B: (K, L, 3), metres per standardised coefficient.
    """
    K = body.num_shape
    verts, joints = body.rest(np.vstack([np.zeros(K), np.eye(K)]))     # (K+1, V, 3), (K+1, J, 3)
    pts = np.empty((K + 1, len(landmarks), 3))
    for i, lm in enumerate(landmarks.landmarks):
        pts[:, i] = lm.rest_point(body, joints, verts)
    return pts[0], pts[1:] - pts[0]


def probe_poses(body: BodyModel, count: int = 8) -> np.ndarray:
    """(count, D) deterministic poses spread over the joint limits (a golden-ratio lattice),
    the root at the origin; for checks that must not depend on a random stream."""
    lo, hi = body.limits[6:, 0], body.limits[6:, 1]
    i = np.arange(body.num_dofs - 6)
    frac = np.mod(np.outer(np.arange(1, count + 1), i + 1) * 0.6180339887498949, 1.0)
    chi = np.zeros((count, body.num_dofs))
    chi[:, 6:] = lo + frac * (hi - lo)
    return chi


def rigid_pairs(body: BodyModel, landmarks: LandmarkSet, min_length: float = 0.05,
                tolerance: float = 1e-4) -> np.ndarray:
    """(B, 2) index pairs (i < j) of landmarks whose distance is the same in every pose
    (tested on :func:`probe_poses` and the rest pose) and at least ``min_length`` metres:
    the bone lengths a subject's size can be fitted to."""
    shaped = body.shaped(np.zeros(body.num_shape))
    chi = np.vstack([np.zeros(body.num_dofs), probe_poses(body)])
    X = landmarks.positions(shaped, chi).astype(np.float64)              # (S, L, 3)
    d = np.linalg.norm(X[:, :, None] - X[:, None, :], axis=-1)           # (S, L, L)
    rigid = (np.ptp(d, axis=0) < tolerance) & (d[0] >= min_length)
    i, j = np.nonzero(np.triu(rigid, k=1))
    return np.stack([i, j], axis=1)


def dof_moves(body: BodyModel, landmarks: LandmarkSet, tolerance: float = 1e-5) -> np.ndarray:
    """(D, L) bool: DOF d moves landmark l (tested by a small step of each DOF from
    :func:`probe_poses`; the six root DOFs move everything)."""
    shaped = body.shaped(np.zeros(body.num_shape))
    base = probe_poses(body, 3)
    D = body.num_dofs
    X0 = landmarks.positions(shaped, base).astype(np.float64)                 # (S, L, 3)
    moves = np.zeros((D, len(landmarks)), bool)
    moves[:6] = True
    for d in range(6, D):
        x = base.copy()
        lo, hi = body.limits[d]
        x[:, d] = np.where(x[:, d] + 0.05 <= hi, x[:, d] + 0.05, x[:, d] - 0.05)
        x[:, d] = np.clip(x[:, d], lo, hi)
        X = landmarks.positions(shaped, x).astype(np.float64)
        moves[d] = np.linalg.norm(X - X0, axis=-1).max(axis=0) > tolerance
    return moves
