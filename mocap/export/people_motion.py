"""``motion.npz`` of a several-people run (``tracker=marker_people``): the motion of every
person in one file, with a person axis after the frame axis.

Keys (F frames of the run, P people = tracks, ids in ``person_ids``; world metres, Z up; every
per-frame array holds NaN (float), False (bool) where a person is not live; the arrays of
each person are those of :mod:`mocap.export.motion`, posed at that person's shape):

    format              "mocap-people-v1"
    fps, frame_index (F,) int, timestamps (F,) seconds
    person_ids (P,) int                 track ids (never reused; born in this order)
    live (F, P) bool                    the person has an estimate in the frame
    born (P,) int, last_frame (P,) int  first and last frame with an estimate
    ended (P,) bool                     the track ended (the person left) before the last frame
    chi (F, P, D), dof_names (D,)       pose per frame
    alpha (F, P, K)                     shape per frame
    joints (F, P, J, 3) float32, joint_names (J,), joint_parents (J,)
    joint_rotations (F, P, J, 3, 3) float32, root_transform (F, P, 4, 4)
    rest_joints (P, J, 3)               rest joints of each person's final shape
    landmarks (F, P, L, 3) float32, landmark_names (L,)
    tracker_landmarks (F, P, L', 3) float32, tracker_landmark_names (L',)   the fitted keypoints
    energy (F, P), reprojection_px (F, P), initial (F, P) bool, lost (F, P) bool
    seconds (F,)                        step time of the frame (all people)
    body, model_hash, tracker, data, run_id, seed     provenance

:func:`load_people_motion` reads it; :func:`mocap.export.motion.load_motion` refuses it with a
message naming this module.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mocap.export.motion import MotionFileError, motion_arrays, read_motion_npz

FORMAT = "mocap-people-v1"
PER_FRAME = ("chi", "alpha", "joints", "joint_rotations", "root_transform", "landmarks", "tracker_landmarks",
             "energy", "reprojection_px", "initial", "lost")
STATIC = ("dof_names", "joint_names", "joint_parents", "landmark_names", "tracker_landmark_names", "body",
          "model_hash")


def people_motion_arrays(body, people: Mapping[int, Mapping[int, object]], frames: int,
                         seconds: Sequence[float], fps: float, info: Mapping | None = None) -> dict:
    """The arrays of a several-people motion.npz: ``people`` {track id: {frame: estimate}},
    ``frames`` of the run, step ``seconds`` per frame."""
    ids = sorted(people)
    F, P = int(frames), len(ids)
    out: dict = {"format": np.array(FORMAT), "fps": np.float64(fps), "frame_index": np.arange(F),
                 "timestamps": np.arange(F) / float(fps), "person_ids": np.array(ids, np.int64),
                 "live": np.zeros((F, P), bool), "born": np.full(P, -1, np.int64),
                 "last_frame": np.full(P, -1, np.int64), "seconds": np.asarray(seconds, np.float64)[:F]}
    rest = []
    for p, pid in enumerate(ids):
        est = people[pid]
        fr = np.array(sorted(f for f in est if f < F), np.int64)
        if not len(fr):
            rest.append(np.full((body.num_joints, 3), np.nan))
            continue
        a = motion_arrays(body, [est[f] for f in fr], np.zeros(len(fr)), fps, info)
        out["live"][fr, p] = True
        out["born"][p], out["last_frame"][p] = fr[0], fr[-1]
        rest.append(a["rest_joints"])
        for k in STATIC:
            if k in a and k not in out:
                out[k] = a[k]
        for k in PER_FRAME:
            if k not in a:
                continue
            v = a[k]
            if k not in out:
                fill = False if v.dtype == bool else np.nan
                out[k] = np.full((F, P, *v.shape[1:]), fill, v.dtype)
            if k == "tracker_landmarks" and v.shape[1:] != out[k].shape[2:]:
                continue                        # another landmark set (cannot happen with one tracker)
            out[k][fr, p] = v
    out["rest_joints"] = np.stack(rest) if rest else np.zeros((0, body.num_joints, 3))
    out["ended"] = (out["last_frame"] >= 0) & (out["last_frame"] < F - 1)
    for key in ("tracker", "data", "run_id"):
        out[key] = np.array(str((info or {}).get(key, "")))
    out["seed"] = np.int64((info or {}).get("seed", -1))
    if not P:              # nobody tracked: the names still say what the axes are
        out.update(dof_names=np.array(body.dof_names), joint_names=np.array(body.joint_names),
                   joint_parents=np.asarray(body.parents, np.int64),
                   joints=np.zeros((F, 0, body.num_joints, 3), np.float32))
    return out


def write_people_motion(path: str | Path, arrays: Mapping[str, np.ndarray]) -> Path:
    """Write the arrays atomically (:func:`mocap.safe_files.write_npz_atomic`)."""
    from mocap.safe_files import write_npz_atomic

    return write_npz_atomic(path, arrays)


def load_people_motion(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a several-people motion.npz (a run directory works too), checked."""
    path, a = read_motion_npz(path)
    if str(a.get("format", "")) != FORMAT:
        raise MotionFileError(f"{path}: format is {str(a.get('format', ''))!r}, expected {FORMAT!r}")
    for k in ("live", "person_ids", "chi", "joints", "fps"):
        if k not in a:
            raise MotionFileError(f"{path}: missing field '{k}'")
    if a["live"].ndim != 2:
        raise MotionFileError(f"{path}: field 'live' is {a['live'].shape}, expected (F, P)")
    F, P = a["live"].shape
    for k in ("chi", "joints"):
        if a[k].shape[:2] != (F, P):
            raise MotionFileError(f"{path}: field '{k}' is {a[k].shape}, expected ({F}, {P}, ...)")
    check_person_ids(a["person_ids"], P, path)
    return a


def check_person_ids(ids: np.ndarray, people: int, path) -> list[int]:
    """The track ids of a people motion file as ints: ``people`` distinct non-negative integers
    (they name files: ``p<id>``); anything else raises :class:`MotionFileError` (one line)."""
    ids = np.asarray(ids)
    if ids.shape != (people,) or not np.issubdtype(ids.dtype, np.integer):
        shown = repr(ids.tolist())[:80]
        raise MotionFileError(f"{path}: field 'person_ids' must be {people} integers (track ids), got "
                              f"{shown}; refused (ids name the exported files)")
    if (ids < 0).any() or len(set(ids.tolist())) != people:
        raise MotionFileError(f"{path}: field 'person_ids' {ids.tolist()[:20]} must be distinct "
                              "non-negative integers; refused (ids name the exported files)")
    return [int(i) for i in ids]


def person_label(pid: int) -> str:
    """The name of track ``pid`` in exported files: ``p<id>`` (file names, marker and node prefixes)."""
    return f"p{int(pid)}"


def live_people(a: Mapping[str, np.ndarray]) -> list[int]:
    """The ids of the people of a people motion file that are live in at least one frame."""
    return [int(pid) for p, pid in enumerate(a["person_ids"]) if a["live"][:, p].any()]


def people_points(a: Mapping[str, np.ndarray], which: str = "landmarks") -> tuple[list[str], np.ndarray]:
    """Every person's points in one array for TRC / C3D: names ``p<id>_<name>`` and points
    (F, P * L, 3) world metres (person-major; NaN where the person is not live). ``which``:
    landmarks, joints or tracker (a marker tracker's own landmarks)."""
    keys = {"landmarks": ("landmarks", "landmark_names"), "joints": ("joints", "joint_names"),
            "tracker": ("tracker_landmarks", "tracker_landmark_names")}
    if which not in keys:
        raise ValueError(f"which must be 'landmarks', 'joints' or 'tracker', got {which!r}")
    key, name_key = keys[which]
    if key not in a:
        raise ValueError("this run's tracker reported no landmarks of its own (marker runs do)")
    pts = np.asarray(a[key], np.float64)                         # (F, P, L, 3)
    F, P, L = pts.shape[:3]
    pts = np.where(np.asarray(a["live"], bool)[:, :, None, None], pts, np.nan)
    names = [f"{person_label(pid)}_{n}" for pid in a["person_ids"] for n in a[name_key]]
    return names, pts.reshape(F, P * L, 3)


def person_motion(path: str | Path, person: int, arrays: Mapping | None = None):
    """Person ``person`` (a track id) of a several-people motion.npz (``arrays``: its arrays,
    already read by :func:`load_people_motion`) as a single-person
    :class:`mocap.export.motion.Motion` over the frames the person is live (what the exporters
    write); an unknown id raises :class:`MotionFileError` naming the ids there are."""
    from mocap.export.motion import INFO, Motion

    a = load_people_motion(path) if arrays is None else arrays
    ids = [int(i) for i in a["person_ids"]]
    if person not in ids:
        raise MotionFileError(f"{path}: no person {person} (the run's people: {ids})")
    p = ids.index(person)
    fr = np.flatnonzero(a["live"][:, p])
    if not len(fr):
        raise MotionFileError(f"{path}: person {person} has no frame with an estimate (nothing to export)")
    pick = lambda k: a[k][fr, p]          # noqa: E731
    names = lambda k: tuple(str(n) for n in a[k])  # noqa: E731
    per_frame = {k: pick(k) for k in ("energy", "reprojection_px", "initial", "lost", "tracker_landmarks")
                 if k in a}
    per_frame["seconds"] = a["seconds"][fr]
    if "tracker_landmark_names" in a:
        per_frame["tracker_landmark_names"] = a["tracker_landmark_names"]
    info = {k: (int(a[k]) if k == "seed" else str(a[k])) for k in INFO if k in a}
    return Motion(fps=float(a["fps"]), frame_index=a["frame_index"][fr], timestamps=a["timestamps"][fr],
                  chi=pick("chi"), dof_names=names("dof_names"), alpha=pick("alpha"), joints=pick("joints"),
                  joint_names=names("joint_names"), joint_parents=a["joint_parents"],
                  joint_rotations=pick("joint_rotations"), rest_joints=a["rest_joints"][p],
                  root_transform=pick("root_transform"), landmarks=pick("landmarks"),
                  landmark_names=names("landmark_names"), per_frame=per_frame, info=info)


def person_timeline(path: str | Path, person: int, arrays: Mapping | None = None):
    """(motion, live): person ``person`` over every frame of the run (a glTF animation shares
    one timeline): :func:`person_motion` with each frame where the person is not live holding
    the pose of the nearest live frame, and ``live`` (F,) bool saying which frames are real."""
    from dataclasses import replace

    a = load_people_motion(path) if arrays is None else arrays
    m = person_motion(path, person, a)
    live = np.asarray(a["live"][:, [int(i) for i in a["person_ids"]].index(person)], bool)
    fr = np.flatnonzero(live)
    F = len(live)
    near = np.abs(np.arange(F)[:, None] - fr[None]).argmin(axis=1)        # (F,) index into fr
    return replace(m, frame_index=a["frame_index"], timestamps=a["timestamps"],
                   **{k: getattr(m, k)[near] for k in ("chi", "alpha", "joints", "joint_rotations",
                                                       "root_transform", "landmarks")},
                   per_frame={}), live


def people_summary_text(a: Mapping[str, np.ndarray]) -> str:
    """A few lines on a people motion file's arrays: frames, people, each person's frames."""
    F, P = a["live"].shape
    lines = [f"people motion: {F} frames at {float(a['fps']):g} fps, {P} people "
             f"(ids {', '.join(str(int(i)) for i in a['person_ids'])}), {len(a['joint_names'])} joints, "
             f"body {str(a.get('body', '?'))} (model {str(a.get('model_hash', '?'))}), "
             f"tracker {str(a.get('tracker', '?'))}"]
    for p, pid in enumerate(a["person_ids"]):
        live = np.flatnonzero(a["live"][:, p])
        if not len(live):
            lines.append(f"  person {int(pid)}: no frame")
            continue
        lost = int(np.asarray(a["lost"])[:, p].sum()) if "lost" in a else 0
        ended = " (ended)" if "ended" in a and bool(a["ended"][p]) else ""
        lines.append(f"  person {int(pid)}: {len(live)} frame{'s' * (len(live) != 1)}, "
                     f"{int(live[0])}-{int(live[-1])}{ended}"
                     + (f", {lost} lost" if lost else ""))
    return "\n".join(lines)
