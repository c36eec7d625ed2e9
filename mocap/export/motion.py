"""``motion.npz``: the motion a run produced, kept in its run directory.

Every run of ``mocap track`` writes it (atomically: a temporary file renamed into
place once complete, so a killed run leaves none that looks complete). Keys (F frames,
J joints, L landmarks, D DOFs, K shape coefficients; world metres, Z up, float64 unless said):

    format              "mocap-motion-v1"
    fps, frame_index (F,) int, timestamps (F,) seconds (frame_index / fps)
    chi (F, D), dof_names (D,)              pose per frame (frame 0: the initial pose)
    alpha (F, K)                            shape per frame
    joints (F, J, 3) float32, joint_names (J,), joint_parents (J,) int (-1: root)
    joint_rotations (F, J, 3, 3) float32    world rotation of each joint's rest-to-posed
                                            transform (identity at rest: the rest pose has
                                            no joint orientations)
    rest_joints (J, 3)                      rest joints of the final shape (with its corrections)
    joint_offsets (F, J, 3)                 rest-joint corrections per frame, added to the
                                            shape's rest joints (a tracker that fits its own
                                            skeleton inside the shape: ``hybrid_kp``'s
                                            ``keypoints.two_cue.skeleton``); zeros: none (a file
                                            written before the field reads as zeros)
    root_transform (F, 4, 4)                rest-to-world transform of the root joint
    landmarks (F, L, 3) float32, landmark_names (L,)   the body's default landmark set
    energy (F,)                             total energy (NaN where not reported)
    energy_term_names (T,), energy_terms (F, T)
    energy_evaluations (F,), seconds (F,)   effort and step time
    apf_called (F,) int8                    1/0; -1 where the tracker does not report it
    limb_names (M,), limb_errors (F, M), misaligned (F, M) bool   hybrid/local decisions
    chain_names (K,), unexplained (F, K), unexplained_limit (F, K)   the two-sided check: each
                                            limb chain's share of the observed area left
                                            unexplained, and the share that flags it (NaN
                                            where not checked)
    initial (F,) bool                       the frame is the initialisation
    lost (F,) bool                          the tracker reported the frame lost / low-confidence
    reprojection_px (F,)                    median landmark reprojection error (marker runs)
    weak_landmark_names (W,), weak_landmarks (F, W) bool   landmarks seen in < 2 views
    body, model_hash, tracker, data, run_id, seed     provenance (model_hash: SHA-1 of the
                                            body model's arrays, 12 hex digits)
    vertices (F, V, 3) float32, faces (T, 3)          optional (``vertices=True``)
    tracker_landmarks (F, L', 3) float32, tracker_landmark_names (L',)   the landmarks a
                                            marker tracker fitted (named after the detection
                                            labels; NaN on frames it did not report, e.g. 0)

:func:`load_motion` returns a frozen :class:`Motion`; :func:`decisions` is the one place that
reads a tracker's diagnostics.
"""

from __future__ import annotations

import hashlib
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocap.body.skeleton import frames_by_body, joint_offsets_of
from mocap.safe_files import write_npz_atomic

FORMAT = "mocap-motion-v1"
REQUIRED = ("format", "fps", "frame_index", "timestamps", "chi", "dof_names", "alpha", "joints",
            "joint_names", "joint_parents", "joint_rotations", "rest_joints", "root_transform",
            "landmarks", "landmark_names")


class MotionFileError(ValueError):
    """A motion.npz is missing, incomplete or not of the expected format."""


@dataclass(frozen=True)
class Motion:
    """The contents of a ``motion.npz`` (shapes in the module docstring)."""

    fps: float
    frame_index: np.ndarray
    timestamps: np.ndarray
    chi: np.ndarray
    dof_names: tuple[str, ...]
    alpha: np.ndarray
    joints: np.ndarray
    joint_names: tuple[str, ...]
    joint_parents: np.ndarray
    joint_rotations: np.ndarray
    rest_joints: np.ndarray
    root_transform: np.ndarray
    landmarks: np.ndarray
    landmark_names: tuple[str, ...]
    per_frame: dict = field(default_factory=dict)   # energies and decisions (module docstring)
    info: dict = field(default_factory=dict)        # body, model_hash, tracker, data, run_id, seed
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    joint_offsets: np.ndarray | None = None         # (F, J, 3); load_motion: zeros for older files

    @property
    def num_frames(self) -> int:
        return len(self.chi)


def _get(diag, key: str, default=None):
    if diag is None:
        return default
    if isinstance(diag, Mapping):
        return diag.get(key, default)
    return getattr(diag, key, default)


def decisions(diagnostics) -> dict:
    """The per-frame facts motion.npz keeps, from one estimate's diagnostics (a dict today;
    an object with the same attribute names also works). Keys: energy, energy_terms (dict),
    energy_evaluations, apf_called (None if not reported), limb_errors (dict), misaligned
    (list of limb names), unexplained / unexplained_limit (dicts by chain), initial, lost,
    reprojection_px, landmarks / landmark_names (tracker's own, may be None), weak_landmarks
    (list), shape_update (a shape refinement's report as a dict, or None), patrol (the APF
    searched though no limb was flagged), apf_free_dofs (the DOFs it searched)."""
    d = diagnostics.as_dict() if hasattr(diagnostics, "as_dict") else diagnostics  # typed StepDiagnostics
    energy = _get(d, "energy")
    apf = _get(d, "apf_called")
    rep = _get(d, "reprojection_px")
    return {
        "energy": float("nan") if energy is None else float(energy),
        "energy_terms": dict(_get(d, "energy_terms", None) or {}),
        "energy_evaluations": int(_get(d, "energy_evaluations", 0) or 0),
        "apf_called": None if apf is None else int(apf),
        "limb_errors": dict(_get(d, "limb_errors", None) or {}),
        "misaligned": list(_get(d, "misaligned_limbs", None) or []),
        "unexplained": dict(_get(d, "unexplained", None) or {}),
        "unexplained_limit": dict(_get(d, "unexplained_limit", None) or {}),
        "initial": bool(_get(d, "initial", False)),
        "lost": bool(_get(d, "lost", False)),
        "reprojection_px": float("nan") if rep is None else float(rep),
        "weak_landmarks": list(_get(d, "weak_landmarks", None) or []),
        "landmarks": _get(d, "landmarks"),
        "landmark_names": list(_get(d, "landmark_names", None) or []),
        "shape_update": _get(d, "shape_update"),
        "patrol": bool(_get(d, "patrol", False)),
        "apf_free_dofs": list(_get(d, "apf_free_dofs", None) or []),
    }


def model_hash(body) -> str:
    """SHA-1 (12 hex digits) of a body model's arrays: which model file a motion belongs to."""
    h = hashlib.sha1()
    data = body.data
    for a in (data.mean, data.components, data.stddev, data.faces, data.joint_parents,
              data.joints_mean, data.joints_basis, data.weights):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update("|".join(data.joint_names).encode())
    return h.hexdigest()[:12]


def _union(lists: Sequence[Sequence[str]]) -> list[str]:
    return list(dict.fromkeys(n for names in lists for n in names))


def motion_arrays(body, estimates: Sequence, seconds: Sequence[float], fps: float,
                  info: Mapping | None = None, vertices: bool = False) -> dict:
    """The arrays of motion.npz from a run: ``estimates`` (one per frame, ``.chi``, ``.alpha``,
    ``.diagnostics``), step ``seconds`` per frame, frames per second."""
    from mocap.body.landmarks import LandmarkSet

    F = len(estimates)
    if F == 0:
        raise ValueError("a motion needs at least one frame")
    chi = np.stack([np.asarray(e.chi, np.float64) for e in estimates])
    alpha = np.stack([np.asarray(e.alpha, np.float64) for e in estimates])
    J = body.num_joints
    found = joint_offsets_of(estimates, J)
    offsets = np.zeros((F, J, 3)) if found is None else found
    joints = np.empty((F, J, 3), np.float32)
    rotations = np.empty((F, J, 3, 3), np.float32)
    root = np.empty((F, 4, 4), np.float64)
    marks = LandmarkSet(body)
    lms = np.empty((F, len(marks), 3), np.float32)
    verts = np.empty((F, body.num_vertices, 3), np.float32) if vertices else None
    # one shape per run in practice: pose all frames of the same shape (and skeleton) at once
    for sel, a, d in frames_by_body(alpha, found, F):
        shaped = body.shaped(a, d)
        out = shaped.pose(chi[sel])
        joints[sel], rotations[sel] = out.joints, out.transforms[:, :, :3, :3]
        root[sel] = out.transforms[:, 0]
        lms[sel] = marks.from_transforms(out.transforms, marks.rest_points(shaped))
        if verts is not None:
            verts[sel] = out.vertices
    last = offsets[-1] if offsets[-1].any() else None
    rest_joints = body.shaped(alpha[-1], last).rest_joints.astype(np.float64)
    dec = [decisions(e.diagnostics) for e in estimates]
    terms = _union([d["energy_terms"] for d in dec])
    limbs = _union([list(d["limb_errors"]) + d["misaligned"] for d in dec])
    weak = _union([d["weak_landmarks"] for d in dec])
    chains = _union([list(d["unexplained"]) for d in dec])
    out = {
        "format": np.array(FORMAT), "fps": np.float64(fps),
        "frame_index": np.arange(F), "timestamps": np.arange(F) / float(fps),
        "chi": chi, "dof_names": np.array(body.dof_names), "alpha": alpha,
        "joints": joints, "joint_names": np.array(body.joint_names),
        "joint_parents": np.asarray(body.parents, np.int64), "joint_rotations": rotations,
        "rest_joints": rest_joints, "joint_offsets": offsets, "root_transform": root,
        "landmarks": lms, "landmark_names": np.array(marks.names),
        "energy": np.array([d["energy"] for d in dec]),
        "energy_term_names": np.array(terms, dtype=str),
        "energy_terms": np.array([[d["energy_terms"].get(t, np.nan) for t in terms] for d in dec],
                                 np.float64).reshape(F, len(terms)),
        "energy_evaluations": np.array([d["energy_evaluations"] for d in dec], np.int64),
        "seconds": np.asarray(seconds, np.float64),
        "apf_called": np.array([-1 if d["apf_called"] is None else d["apf_called"] for d in dec], np.int8),
        "limb_names": np.array(limbs, dtype=str),
        "limb_errors": np.array([[d["limb_errors"].get(n, np.nan) for n in limbs] for d in dec],
                                np.float64).reshape(F, len(limbs)),
        "misaligned": np.array([[n in d["misaligned"] for n in limbs] for d in dec],
                               bool).reshape(F, len(limbs)),
        "chain_names": np.array(chains, dtype=str),
        **{k: np.array([[d[k].get(n, np.nan) for n in chains] for d in dec],
                       np.float64).reshape(F, len(chains)) for k in ("unexplained", "unexplained_limit")},
        "initial": np.array([d["initial"] for d in dec], bool),
        "lost": np.array([d["lost"] for d in dec], bool),
        "reprojection_px": np.array([d["reprojection_px"] for d in dec], np.float64),
        "weak_landmark_names": np.array(weak, dtype=str),
        "weak_landmarks": np.array([[n in d["weak_landmarks"] for n in weak] for d in dec],
                                   bool).reshape(F, len(weak)),
        "body": np.array(getattr(body, "name", "")), "model_hash": np.array(model_hash(body)),
    }
    for key in ("tracker", "data", "run_id"):
        out[key] = np.array(str((info or {}).get(key, "")))
    out["seed"] = np.int64((info or {}).get("seed", -1))
    tnames = _union([d["landmark_names"] for d in dec if d["landmarks"] is not None])
    if tnames:                 # the tracker's own landmarks (marker runs; NaN where not reported)
        tl = np.full((F, len(tnames), 3), np.nan, np.float32)
        for f, d in enumerate(dec):
            if d["landmarks"] is not None:
                tl[f, [tnames.index(n) for n in d["landmark_names"]]] = np.asarray(d["landmarks"])
        out["tracker_landmarks"], out["tracker_landmark_names"] = tl, np.array(tnames, dtype=str)
    if verts is not None:
        out["vertices"], out["faces"] = verts, np.asarray(body.faces)
    return out


def write_motion(path: str | Path, arrays: Mapping[str, np.ndarray]) -> Path:
    """Write motion arrays to ``path`` atomically (temporary file, then ``os.replace``)."""
    path = Path(path)
    missing = [k for k in REQUIRED if k not in arrays]
    if missing:
        raise ValueError(f"motion arrays miss {', '.join(missing)}")
    return write_npz_atomic(path, arrays)


PER_FRAME = ("tracker_landmarks", "tracker_landmark_names",
             "energy", "energy_term_names", "energy_terms", "energy_evaluations", "seconds",
             "apf_called", "limb_names", "limb_errors", "misaligned", "chain_names", "unexplained",
             "unexplained_limit", "initial", "lost",
             "reprojection_px", "weak_landmark_names", "weak_landmarks")
INFO = ("body", "model_hash", "tracker", "data", "run_id", "seed")


def read_motion_npz(path: str | Path) -> tuple[Path, dict[str, np.ndarray]]:
    """(the file's path, every array of it) for a motion.npz of either format (a run directory
    works too); a missing or unreadable file raises :class:`MotionFileError` naming it."""
    path = Path(path)
    if path.is_dir():
        path = path / "motion.npz"
    if not path.is_file():
        raise MotionFileError(f"{path}: not found (runs write motion.npz when they finish)")
    try:
        with np.load(path, allow_pickle=False) as z:
            return path, {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise MotionFileError(f"{path}: not a readable .npz ({exc})") from exc


def load_motion(path: str | Path) -> Motion:
    """Read and check a ``motion.npz`` (a run directory works too)."""
    path, a = read_motion_npz(path)
    if "format" in a and str(a["format"]) == "mocap-people-v1":
        raise MotionFileError(f"{path}: holds several people (format 'mocap-people-v1'): read it with "
                              "mocap.export.people_motion.load_people_motion")
    missing = [k for k in REQUIRED if k not in a]
    if missing:
        raise MotionFileError(f"{path}: missing field(s) {', '.join(missing)}")
    if str(a["format"]) != FORMAT:
        raise MotionFileError(f"{path}: format is {str(a['format'])!r}, expected {FORMAT!r}")
    F = len(a["chi"])
    for k in ("frame_index", "timestamps", "alpha", "joints", "joint_rotations", "root_transform",
              "landmarks"):
        if len(a[k]) != F:
            raise MotionFileError(f"{path}: field '{k}' has {len(a[k])} frames, 'chi' has {F}")
    names = lambda k: tuple(str(n) for n in a[k])  # noqa: E731
    J = len(a["joint_names"])
    offsets = np.asarray(a["joint_offsets"], np.float64) if "joint_offsets" in a else np.zeros((F, J, 3))
    if offsets.shape != (F, J, 3):
        raise MotionFileError(f"{path}: field 'joint_offsets' has shape {offsets.shape}, "
                              f"expected ({F}, {J}, 3)")
    per_frame = {k: a[k] for k in PER_FRAME if k in a}
    info = {k: (int(a[k]) if k == "seed" else str(a[k])) for k in INFO if k in a}
    return Motion(fps=float(a["fps"]), frame_index=a["frame_index"], timestamps=a["timestamps"],
                  chi=a["chi"], dof_names=names("dof_names"), alpha=a["alpha"], joints=a["joints"],
                  joint_names=names("joint_names"), joint_parents=a["joint_parents"],
                  joint_rotations=a["joint_rotations"], rest_joints=a["rest_joints"],
                  root_transform=a["root_transform"], landmarks=a["landmarks"],
                  landmark_names=names("landmark_names"), per_frame=per_frame, info=info,
                  vertices=a.get("vertices"), faces=a.get("faces"), joint_offsets=offsets)


def summary_text(m: Motion) -> str:
    pf = m.per_frame
    lines = [f"motion: {m.num_frames} frames at {m.fps:g} fps, {len(m.joint_names)} joints, "
             f"{len(m.landmark_names)} landmarks, body {m.info.get('body', '?')} "
             f"(model {m.info.get('model_hash', '?')}), tracker {m.info.get('tracker', '?')}"]
    if "apf_called" in pf and (pf["apf_called"] >= 0).any():
        lines.append(f"  APF called on {int((pf['apf_called'] == 1).sum())} frames")
    if "misaligned" in pf and pf["misaligned"].size:
        lines.append(f"  frames with misaligned limbs: {int(pf['misaligned'].any(axis=1).sum())}")
    if "lost" in pf and pf["lost"].any():
        lines.append(f"  frames lost: {int(pf['lost'].sum())}")
    return "\n".join(lines)
