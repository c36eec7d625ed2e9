"""Real recordings as keypoint detections: a calibration file plus one folder of OpenPose-style
JSON files per camera (the layout of Pose2Sim projects), read into a :class:`Sequence` whose
detections are labelled with the body's landmark names.

    seq = load_openpose_sequence("../shared/data/pose2sim-demo")      # Calib.toml + pose/
    seq = load_openpose_sequence(path, calibration="calib/Calib.toml", keypoints="pose-2d")

Folders are matched to cameras by name, ignoring case, separators and a ``_json`` suffix
(``cam01_json`` <-> ``cam_01``); frame numbers come from the last integer in each file name
(``cam01.0042.json`` -> 42). Keypoints with confidence 0 (OpenPose's "not found") or below
``min_confidence`` are dropped.

Every frame may hold several people (the subject, bystanders). ``person="subject"`` keeps one:
in the first frame, the assignment of one person per view that triangulates consistently in
the most views and lies nearest the centre of the capture volume; afterwards, per view, the
person whose keypoints lie nearest the reprojection of the subject's previous 3D keypoints
(:func:`select_subject`).
``person="all"`` keeps everyone as candidate detections (other people then act as
false positives for the tracker).
"""

from __future__ import annotations

import itertools
import json
import re
import warnings
from collections.abc import Sequence as Seq
from pathlib import Path

import numpy as np

from mocap.body.skeletons import LAYOUT_BONES, LAYOUTS
from mocap.cameras import Rig, load_calibration, project, triangulate
from mocap.data.sequence import Detections, Sequence
from mocap.data.source_settings import OpenPoseSource, recording_settings


class OpenPoseFormatError(ValueError):
    """A keypoint file or folder layout that cannot be read; names the file and the problem."""

    def __init__(self, path: str | Path, reason: str):
        super().__init__(f"{path}: {reason}")
        self.path, self.reason = str(path), reason


def _key(name: str) -> str:
    name = re.sub(r"[_\-\s.]?json$", "", name.lower())
    return re.sub(r"[^a-z0-9]", "", name)


def write_openpose_folders(root: str | Path, names: Seq[str], keypoints: np.ndarray) -> None:
    """keypoints (C, F, K, 3) x, y, confidence per camera, frame and keypoint -> ``root/<name>_json/
    <name>.<frame:04d>.json``, one person per frame (none where every confidence is 0): the layout
    :func:`load_openpose_sequence` reads."""
    root = Path(root)
    for name, per_frame in zip(names, np.asarray(keypoints, float), strict=True):
        folder = root / f"{name}_json"
        folder.mkdir(parents=True, exist_ok=True)
        for f, kp in enumerate(per_frame):
            people = [{"pose_keypoints_2d": kp.reshape(-1).tolist()}] if kp[:, 2].any() else []
            (folder / f"{name}.{f:04d}.json").write_text(json.dumps({"people": people}))


def frame_number(path: Path) -> int:
    nums = re.findall(r"\d+", path.stem)
    if not nums:
        raise OpenPoseFormatError(path, "no frame number in the file name")
    return int(nums[-1])


def read_people(path: str | Path, num_keypoints: int) -> np.ndarray:
    """One OpenPose JSON file -> (N, K, 3) people x keypoints x (x, y, confidence)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise OpenPoseFormatError(path, f"not valid JSON ({exc})") from None
    people = data.get("people") if isinstance(data, dict) else None
    if not isinstance(people, list):
        raise OpenPoseFormatError(path, "expected an object with a 'people' list")
    out = np.zeros((len(people), num_keypoints, 3))
    for i, person in enumerate(people):
        kp = person.get("pose_keypoints_2d") if isinstance(person, dict) else None
        try:
            arr = np.asarray(kp, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise OpenPoseFormatError(path, f"person {i}: 'pose_keypoints_2d' is not a list of "
                                            "numbers") from None
        if arr.size != 3 * num_keypoints:
            raise OpenPoseFormatError(path, f"person {i}: {arr.size} values in 'pose_keypoints_2d', "
                                            f"expected {3 * num_keypoints} ({num_keypoints} x (x, y, c))")
        if not np.all(np.isfinite(arr)):
            bad = int(np.flatnonzero(~np.isfinite(arr))[0]) // 3
            raise OpenPoseFormatError(path, f"frame {frame_number(path)}, person {i}: non-finite keypoint "
                                            f"value (NaN or Inf) at keypoint {bad}")
        out[i] = arr.reshape(num_keypoints, 3)
    return out


def match_folders(camera_names: Seq[str], folders: Seq[Path], source: Path) -> list[Path]:
    """The keypoint folder of each camera, in camera order; raises when names don't match."""
    by_key: dict[str, Path] = {}
    for f in folders:
        by_key.setdefault(_key(f.name), f)
    missing = [n for n in camera_names if _key(n) not in by_key]
    if missing:
        raise OpenPoseFormatError(source, f"camera names {list(camera_names)} of the calibration do not "
                                          f"match the keypoint folders {sorted(f.name for f in folders)} "
                                          f"(no folder for {missing})")
    return [by_key[_key(n)] for n in camera_names]


def read_keypoint_folders(rig: Rig, keypoints: Path, num_keypoints: int | None = None
                          ) -> list[dict[int, np.ndarray]]:
    """Per camera, {frame: (N, K, 3) people}. ``num_keypoints`` None: taken from the first
    person found (every file must then agree). Raises :class:`OpenPoseFormatError` when a
    camera has no folder or when frames present in one view are missing in another."""
    if not keypoints.is_dir():
        raise FileNotFoundError(f"keypoint folder not found: {keypoints}")
    folders = sorted(p for p in keypoints.iterdir() if p.is_dir())
    if not folders:
        raise OpenPoseFormatError(keypoints, "no per-camera keypoint folders inside")
    K = num_keypoints or _first_keypoint_count(folders)
    out = []
    matched = match_folders(rig.names, folders, keypoints)
    for folder in matched:
        files = sorted(folder.glob("*.json"))
        if not files:
            raise OpenPoseFormatError(folder, "no .json files")
        frames: dict[int, np.ndarray] = {}
        for f in files:
            n = frame_number(f)
            if n in frames:
                raise OpenPoseFormatError(f, f"frame {n} appears twice in {folder.name}")
            frames[n] = read_people(f, K)
        out.append(frames)
    every = set().union(*(p.keys() for p in out))
    for folder, frames in zip(matched, out, strict=True):
        missing = sorted(every - frames.keys())
        if missing:
            shown = ", ".join(map(str, missing[:10])) + (" ..." if len(missing) > 10 else "")
            raise OpenPoseFormatError(folder, f"{len(missing)} frame(s) present in other views are "
                                              f"missing here: {shown} (OpenPose writes a file for every "
                                              "frame, empty 'people' when nobody is found)")
    return out


def _first_keypoint_count(folders: Seq[Path]) -> int:
    for folder in folders:
        for f in sorted(folder.glob("*.json")):
            try:
                people = json.loads(f.read_text()).get("people") or []
            except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
                continue            # read_people names the file
            for person in people:
                kp = person.get("pose_keypoints_2d") if isinstance(person, dict) else None
                if isinstance(kp, list) and len(kp) % 3 == 0 and kp:
                    return len(kp) // 3
    raise OpenPoseFormatError(folders[0].parent, "no person with 'pose_keypoints_2d' in any file")


def layout_scores(people: Seq[dict[int, np.ndarray]], layouts: Seq[str],
                  max_people: int = 400) -> dict[str, float]:
    """How well each layout's labels fit the keypoints: the median, over people seen in the
    files (up to ``max_people``), of the mean 2D length of the layout's short bones
    (:data:`LAYOUT_BONES`) divided by the diagonal of the person's bounding box. Read with
    the right labels a bone joins neighbouring keypoints (about 0.1-0.2); with the wrong
    labels many join distant parts (e.g. BODY_25 read as BODY_25B puts the ankles at the
    eyes). Independent of the view and of the person's orientation. Lower is better."""
    samples = []
    for per_view in people:
        for arr in per_view.values():
            samples.extend(arr)
            if len(samples) >= max_people:
                break
    scores = {}
    for name in layouts:
        names = LAYOUTS[name]
        idx = {n: i for i, n in enumerate(names) if n is not None}
        bones = np.array([(idx[a], idx[b]) for a, b in LAYOUT_BONES if a in idx and b in idx])
        vals = []
        for kp in samples:
            if kp.shape[0] != len(names) or not len(bones):
                continue
            ok = kp[:, 2] > 0
            use = ok[bones[:, 0]] & ok[bones[:, 1]]
            if ok.sum() < 5 or use.sum() < 4:
                continue
            diag = np.linalg.norm(np.ptp(kp[ok, :2], axis=0))
            if diag <= 0:
                continue
            b = bones[use]
            vals.append(np.linalg.norm(kp[b[:, 0], :2] - kp[b[:, 1], :2], axis=1).mean() / diag)
        scores[name] = float(np.median(vals)) if vals else float("nan")
    return scores


def resolve_layout(people: Seq[dict[int, np.ndarray]], layout: str, source: Path,
                   margin: float = 1.5) -> str:
    """The layout to read ``people`` with. ``layout="auto"``: among the layouts with the
    files' keypoint count, the one with the best :func:`layout_scores`. A named layout is
    checked: its keypoint count must match, and if another layout of that count fits
    ``margin`` times better the files were most likely written in that one, and an
    :class:`OpenPoseFormatError` says so."""
    K = next((a.shape[1] for p in people for a in p.values() if len(a)), None)
    if K is None:
        if layout == "auto":
            raise OpenPoseFormatError(source, "no person in any keypoint file: cannot detect the layout")
        return layout
    same = [n for n, names in LAYOUTS.items() if len(names) == K]
    if layout == "auto":
        if not same:
            raise OpenPoseFormatError(source, f"{K} keypoints per person match no known layout "
                                              f"({', '.join(f'{n}: {len(v)}' for n, v in LAYOUTS.items())})")
        if len(same) == 1:
            return same[0]
        scores = layout_scores(people, same)
        return min(same, key=lambda n: scores[n] if np.isfinite(scores[n]) else np.inf)
    if len(LAYOUTS[layout]) != K:
        raise OpenPoseFormatError(source, f"layout {layout} has {len(LAYOUTS[layout])} keypoints, the files "
                                          f"have {K} (layouts with {K}: {same or 'none'}; try layout=auto)")
    if len(same) > 1:
        scores = layout_scores(people, same)
        best = min(same, key=lambda n: scores[n] if np.isfinite(scores[n]) else np.inf)
        if best != layout and scores[best] * margin < scores[layout]:
            raise OpenPoseFormatError(source, f"the keypoints do not look like {layout}: read as {best} "
                                              f"their bones are {scores[layout] / scores[best]:.1f}x shorter "
                                              f"(bone/size {scores[best]:.2f} vs {scores[layout]:.2f}); "
                                              f"set layout={best} (or layout=auto)")
    return layout


def _triangulation_error(rig: Rig, xy: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, float]:
    """Triangulate keypoints (C, K, 2) valid (C, K); (points (K, 3), median reprojection px)."""
    X = triangulate(rig, xy, valid=ok)
    have = np.all(np.isfinite(X), axis=1)
    if have.sum() < 3:
        return X, np.inf
    px = project(rig, np.where(have[:, None], X, 0.0))
    err = np.linalg.norm(px - xy, axis=-1)
    use = ok & have[None]
    return X, float(np.median(err[use])) if use.any() else np.inf


def capture_centre(rig: Rig) -> np.ndarray:
    """(3,) the point nearest (least squares) to every camera's optical axis."""
    d = rig.R[:, 2, :]                                                   # optical axes, world
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    return np.linalg.solve(proj.sum(axis=0), (proj @ rig.centers[..., None]).sum(axis=0))[:, 0]


def select_subject(rig: Rig, people: list[dict[int, np.ndarray]], frames: Seq[int],
                   min_confidence: float, max_error_px: float = 50.0) -> dict[int, list[int | None]]:
    """Per frame, the index of the subject in each view (None: not seen there).

    First frame: every assignment of one person (or none) per view is triangulated; among
    those with a median reprojection error below ``max_error_px`` the subject is the one
    seen in the most views, then the one nearest the centre of the capture volume
    (:func:`capture_centre`). Later frames: per view, the person nearest (median keypoint
    distance) to the reprojection of the subject's last 3D keypoints, if within
    3 x ``max_error_px``.
    """
    C = len(rig)
    centre = capture_centre(rig)
    choice: dict[int, list[int | None]] = {}
    last: np.ndarray | None = None
    for f in frames:
        per_view = [people[c].get(f, np.zeros((0, 1, 3))) for c in range(C)]
        if last is None or not np.isfinite(last).any():
            best, best_key, best_X = None, None, None
            options = [list(range(len(p))) + [None] for p in per_view]
            for combo in itertools.product(*options):
                views = sum(i is not None for i in combo)
                if views < 2:
                    continue
                xy, ok = _stack(per_view, combo, min_confidence)
                X, err = _triangulation_error(rig, xy, ok)
                if err >= max_error_px:
                    continue
                key = (views, -float(np.linalg.norm(np.nanmedian(X, axis=0) - centre)))
                if best_key is None or key > best_key:
                    best, best_key, best_X = list(combo), key, X
            choice[f] = best if best is not None else [None] * C
            last = best_X
            continue
        have = np.all(np.isfinite(last), axis=1)
        px = project(rig, np.where(have[:, None], last, 0.0))          # (C, K, 2)
        pick: list[int | None] = []
        for c in range(C):
            d = []
            for p in per_view[c]:
                use = (p[:, 2] > min_confidence) & have
                d.append(np.median(np.linalg.norm(p[use, :2] - px[c, use], axis=1)) if use.any() else np.inf)
            i = int(np.argmin(d)) if d else None
            pick.append(i if i is not None and d[i] < 3 * max_error_px else None)
        choice[f] = pick
        if sum(i is not None for i in pick) >= 2:
            X, _ = _triangulation_error(rig, *_stack(per_view, pick, min_confidence))
            last = np.where(np.isfinite(X), X, last)
    return choice


def _stack(per_view: list[np.ndarray], combo: Seq[int | None],
           min_confidence: float) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints (C, K, 2) and validity (C, K) of one person per view (None: no one)."""
    C, K = len(per_view), max(p.shape[1] for p in per_view)
    xy = np.zeros((C, K, 2))
    ok = np.zeros((C, K), bool)
    for c, i in enumerate(combo):
        if i is not None:
            p = per_view[c][i]
            ok[c], xy[c] = p[:, 2] > min_confidence, p[:, :2]
    return xy, ok


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def check_options(layout: str, fps, person: str, min_confidence, frames) -> None:
    """The reading settings, checked before any file is read; each error names the setting,
    its value and what is allowed."""
    if layout != "auto" and layout not in LAYOUTS:
        raise ValueError(f"setting layout = {layout!r} is not a keypoint layout (one of: auto, "
                         f"{', '.join(LAYOUTS)})")
    if person not in ("subject", "all"):
        raise ValueError(f"setting person = {person!r} is not allowed (subject: one person per frame; "
                         "all: everyone as candidates)")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"setting fps = {fps!r} is out of range (frames per second, a number > 0)")
    if (isinstance(min_confidence, bool) or not isinstance(min_confidence, (int, float))
            or not 0.0 <= min_confidence < 1.0):
        raise ValueError(f"setting min_confidence = {min_confidence!r} is out of range ([0, 1): "
                         "keypoints below it are dropped; 0 keeps every keypoint found)")
    if frames is not None and (not _is_int(frames) or frames < 1):
        raise ValueError(f"setting frames = {frames!r} is out of range (an integer >= 1: read the first "
                         "N frames, or null for all)")


def find_ground_truth(root: Path, gt: str | Path | None) -> Path | None:
    """The ground-truth file of a recording: ``gt`` (as given, else relative to ``root``) or,
    without it, ``root/gt.npz`` when there is one (ignored only with ``gt`` = "none")."""
    from mocap.data.sequence_io import NO_GT_HINT, gt_opted_out

    if gt_opted_out(gt):
        return None
    if gt is None:
        found = root / "gt.npz"
        return found if found.is_file() else None
    p = Path(gt)
    if not p.is_file() and not p.is_absolute() and (root / p).is_file():
        p = root / p
    if not p.is_file():
        raise FileNotFoundError(f"setting gt = {str(gt)!r}: ground-truth file not found (a gt.npz: "
                                f"joints by name, docs/data_formats.md; {NO_GT_HINT})")
    return p


_S = OpenPoseSource         # the defaults (mocap/data/source_settings.py)


def load_openpose_sequence(path: str | Path, *, calibration: str | Path | None = _S.calibration,
                           keypoints: str | Path | None = _S.keypoints, layout: str = _S.layout,
                           fps: float = _S.fps, person: str = _S.person,
                           min_confidence: float = _S.min_confidence, frames: int | None = _S.frames,
                           name: str | None = _S.name, gt: str | Path | None = _S.gt,
                           nonfinite: str = _S.nonfinite) -> Sequence:
    """A :class:`Sequence` with a rig and labelled keypoint detections, and ground truth
    when the folder has a ``gt.npz`` or ``gt`` names one.

    path: the project folder; calibration: file relative to it (default: the single
    ``*.toml`` in it or in ``calibration/``); keypoints: folder of per-camera folders
    (default ``pose``); layout: a key of :data:`LAYOUTS`; person: "subject" or "all";
    frames: keep the first N frames; gt: a ground-truth file (the gt.npz of a sequence
    folder, :func:`mocap.data.sequence_io.load_ground_truth`: joints by name in any skeleton
    of :mod:`mocap.eval.by_name`, optionally several people) with one frame per frame of the
    recording (frame 0: the first keypoint frame), checked before the keypoints are read;
    nonfinite: NaN / Inf ground-truth joints refused or dropped. Raises
    :class:`OpenPoseFormatError` (a ValueError) for malformed files or camera names that
    don't match the folders.
    """
    from mocap.data.sequence_io import NONFINITE, load_ground_truth_of_data

    root = Path(path)
    check_options(layout, fps, person, min_confidence, frames)
    if nonfinite not in NONFINITE:
        raise ValueError(f"setting nonfinite = {nonfinite!r} is not allowed (one of: {', '.join(NONFINITE)})")
    if not root.is_dir():
        raise FileNotFoundError(f"recording folder not found: {root}")
    gt_path = find_ground_truth(root, gt)
    dropped: dict[str, int] = {}
    truth = load_ground_truth_of_data(gt_path, None, nonfinite, dropped) if gt_path is not None else None
    layout_setting = layout
    calib = root / calibration if calibration is not None else _find_calibration(root)
    rig = load_calibration(calib)
    kp_root = root / (keypoints or "pose")
    people = read_keypoint_folders(rig, kp_root)      # K from the files; a named layout is checked below
    layout = resolve_layout(people, layout, kp_root)
    all_frames = sorted(set().union(*(p.keys() for p in people)))
    first = all_frames[0]
    if truth is not None:
        span = all_frames[-1] - first + 1
        if truth.num_frames != span:
            raise OpenPoseFormatError(gt_path, f"field 'joints' has {truth.num_frames} frames, the recording "
                                               f"{span} (keypoint frames {first}-{all_frames[-1]}; one "
                                               "ground-truth frame per frame, frame 0 the first)")
    all_frames = all_frames[:frames] if frames is not None else all_frames
    names = LAYOUTS[layout]
    labels = tuple(n for n in names if n is not None)
    label_of = np.array([labels.index(n) if n is not None else -1 for n in names])
    subject = select_subject(rig, people, all_frames, min_confidence) if person == "subject" else None
    rows = []
    for f in all_frames:
        for c in range(len(rig)):
            ppl = people[c].get(f)
            if ppl is None or not len(ppl):
                continue
            idx = range(len(ppl)) if subject is None else [i for i in [subject[f][c]] if i is not None]
            for i in idx:
                kp = ppl[i]
                keep = (kp[:, 2] > 0) & (kp[:, 2] >= min_confidence) & (label_of >= 0)
                for k in np.flatnonzero(keep):
                    rows.append((f - first, c, label_of[k], kp[k, 0], kp[k, 1], kp[k, 2], i))
    arr = np.array(rows, np.float64).reshape(-1, 7)
    if not len(arr):
        kept = f"no keypoint with confidence >= min_confidence = {min_confidence} "
        raise OpenPoseFormatError(kp_root, (kept if min_confidence > 0 else "no keypoint ")
                                  + ("of a subject seen consistently in 2+ views " if subject is not None
                                     else "") + f"in frames {_ranges([f - first for f in all_frames])}"
                                  + (" (try person=all)" if subject is not None else ""))
    seen = {(int(f), int(c)) for f, c in arr[:, :2]}
    without = {rig.names[c]: [f - first for f in all_frames if (f - first, c) not in seen]
               for c in range(len(rig))}
    without = {name: frames for name, frames in without.items() if frames}
    if without:
        warnings.warn(f"{kp_root}: no keypoints of the subject in " + "; ".join(
            f"{name} frames {_ranges(frames)}" for name, frames in without.items())
            + " (the tracker has no detections there)", stacklevel=2)
    det = Detections(labels=labels, frame=arr[:, 0].astype(np.int64), view=arr[:, 1].astype(np.int64),
                     label=arr[:, 2].astype(np.int64), xy=arr[:, 3:5], confidence=arr[:, 5],
                     person=arr[:, 6].astype(np.int64))
    meta = {"source": str(root), "calibration": str(calib), "layout": layout,
            "layout_setting": layout_setting, "person": person, "first_frame": int(first),
            "frames": len(all_frames), "frames_without_keypoints": without,
            "people_in_view": _most_in_view(people, all_frames)}
    if truth is not None:
        from dataclasses import replace

        last = all_frames[-1] - first + 1          # frames are numbered from the first keypoint frame
        truth = replace(truth, **{k: (None if getattr(truth, k) is None else getattr(truth, k)[:last])
                                  for k in ("joints", "joint_valid", "chi", "markers")})
        meta["gt"] = str(gt_path)
        if dropped:
            meta["dropped_nonfinite"] = dropped
    # the frame count from the files, not from the last detection: trailing frames with nobody
    # detected are frames of the recording too
    return Sequence(name=name or root.name, rig=rig, fps=fps, detections=det, gt=truth, meta=meta,
                    frames=all_frames[-1] - first + 1)


def _most_in_view(people: list[dict[int, np.ndarray]], frames: Seq[int]) -> int:
    """The most people one view's keypoint file held in one of ``frames`` (before any choice of
    a subject): several people in the recording, whatever ``person`` keeps."""
    kept = set(frames)
    return max((len(ppl) for view in people for f, ppl in view.items() if f in kept), default=0)


def _ranges(frames: Seq[int]) -> str:
    """"0-3, 7, 9-10" for [0, 1, 2, 3, 7, 9, 10]."""
    out, start = [], None
    for i, f in enumerate(frames):
        if start is None:
            start = f
        if i + 1 == len(frames) or frames[i + 1] != f + 1:
            out.append(f"{start}" if start == f else f"{start}-{f}")
            start = None
    return ", ".join(out)


def _find_calibration(root: Path) -> Path:
    for folder in (root, root / "calibration"):
        found = sorted(folder.glob("*.toml")) if folder.is_dir() else []
        if len(found) == 1:
            return found[0]
        if len(found) > 1:
            raise OpenPoseFormatError(folder, f"several calibration files {[f.name for f in found]}: "
                                              "pass calibration=")
    raise FileNotFoundError(f"no calibration (*.toml) in {root} or {root / 'calibration'}")


def openpose_sequence(*, body=None, **keys) -> Sequence:
    """Hydra entry point (``conf/data/pose2sim_demo.yaml``); ``body`` is accepted and unused;
    ``keys``: the settings that differ from :class:`~mocap.data.source_settings.OpenPoseSource`'s
    defaults. An unknown setting is refused by name (before any file is read)."""
    path, options = recording_settings(OpenPoseSource, keys, "keypoint recording")
    return load_openpose_sequence(path, **options)


def convert_pose2sim(src: str | Path, out: str | Path, *, person: str = "all", overwrite: bool = False,
                     **options) -> Path:
    """A Pose2Sim folder (calibration + per-view OpenPose JSON, optional gt.npz) -> a sequence
    folder (:mod:`mocap.data.sequence_io`): calibration.json, detections.json with the
    detector's per-view person grouping in its ``person`` column, gt.npz when there is ground
    truth, sequence.json whose ``meta`` records the source, the resolved layout and the person
    mode. ``person``: "all" (default: every person kept, grouped as the detector grouped them)
    or "subject"; ``options``: the other settings of :func:`load_openpose_sequence`. Checked
    before anything is written; written atomically."""
    from mocap.data.sequence_io import write_sequence

    out = Path(out)
    if out.exists() and not overwrite:
        raise FileExistsError(f"output folder {out} exists (--overwrite replaces it)")
    if out.resolve() == Path(src).resolve():
        raise ValueError(f"output folder {out} is the Pose2Sim folder itself: choose another")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)     # frames without keypoints: in the meta
        seq = load_openpose_sequence(src, person=person, **options)
    return write_sequence(seq, out, overwrite=overwrite)
