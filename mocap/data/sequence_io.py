"""Sequence folders: the on-disk format of multi-view recordings (synthetic or real).

    <sequence>/
      sequence.json        {"format": "mocap-sequence-v1", "name", "fps", "frames",
                            "views": [camera names], "image_size": [w, h],
                            "content": {"masks", "images", "detections", "gt": bool}, "meta"}
      calibration.json     the rig, mocap's JSON calibration format (mocap.cameras)
      masks/<view>/NNNNNN.png    silhouettes, 8-bit, 0 background / 255 foreground
      images/<view>/NNNNNN.png   RGB images (PNG, lossless)
      detections.json      {"labels": [marker names], "columns": ["frame", "view", "label",
                            "x", "y", "confidence"(, "person")], "rows": [[...], ...]}; view
                            indexes "views", label indexes "labels" (-1: unlabelled); the
                            optional "person": the detector's skeleton in its (frame, view)
                            (-1: unknown; ``mocap convert`` keeps OpenPose's)
      gt.npz               alpha (K,), chi (F, D), joints (F, J, 3), markers (F, L, 3),
                           dof_names, joint_names, marker_names, body; or, for a real
                           dataset, joints by name only: joint_names (J,), joints (F, J, 3),
                           optional joint_valid (F, J) bool and skeleton (a key of
                           mocap.body.skeletons.SKELETONS; "" = mocap's own joint names);
                           several people: joints (F, P, J, 3), joint_valid (F, P, J),
                           optional person_names (P,) (scored per person, best assignment);
                           optional, one person: surface (F, N, 3) float, world metres, points
                           on the true body surface per frame, and surface_faces (M, 3) int
                           when they are a mesh's vertices (mocap.eval.surface scores them)

Masks are foreground where the pixel is non-zero in a 0/1 image (maximum 1) and above 127
otherwise, so 0/1, 0/255 and 1-bit PNGs load the same; a view whose masks are all empty is
reported with a warning.

``write_sequence`` writes into a temporary folder beside the target and renames it into place
when complete, so an interrupted run leaves no half-written sequence. ``load_sequence``
validates everything and names the file and field of any problem. Non-finite values (NaN,
Inf) in the ground truth or the detections are refused, naming the file, field, frame / row;
``nonfinite="drop"`` leaves them out instead (ground-truth joints become invalid, detection
rows are removed) and counts what it dropped in ``meta["dropped_nonfinite"]`` (a run reports
it in metrics.json). Non-finite ground-truth poses (``chi``) and markers are always refused.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from mocap.cameras import load_calibration, save_calibration
from mocap.checks import MAX_FRAMES, MAX_IMAGE_SIDE, BadValueError, check_fps, check_int, check_type
from mocap.data.sequence import Detections, GroundTruth, Sequence
from mocap.safe_files import UnsafeNameError, check_name, check_names, write_npz_atomic

FORMAT = "mocap-sequence-v1"
_COLUMNS = ["frame", "view", "label", "x", "y", "confidence"]
#: the most frames a folder of keypoints alone (no image files to count) may claim
MAX_KEYPOINT_FRAMES = 1_000_000


class SequenceFormatError(ValueError):
    """A sequence folder is incomplete or inconsistent; the message names file and field."""


#: ``gt`` = "none" (or ""): the data is read without ground truth, its gt.npz ignored (one in
#: another format, or one not wanted for this run)
NO_GT = ("none", "")
#: what every error about a folder's ground truth adds: the way out
NO_GT_HINT = "data.gt=none tracks the data without it"


def gt_opted_out(gt) -> bool:
    """Whether the ``gt`` setting turns the data's ground truth off (:data:`NO_GT`)."""
    return isinstance(gt, str) and gt.strip().lower() in NO_GT


def load_ground_truth_of_data(path: Path, frames: int | None, nonfinite: str, dropped: dict | None,
                              listed: bool = False) -> GroundTruth:
    """:func:`load_ground_truth` for a data source's ground truth: an error says how to track
    without it (:data:`NO_GT_HINT`). listed: sequence.json lists it (a missing file is an error)."""
    try:
        if listed and not path.is_file():
            raise SequenceFormatError(f"{path}: not found (sequence.json lists ground truth)")
        return load_ground_truth(path, frames, nonfinite, dropped)
    except SequenceFormatError as exc:
        raise SequenceFormatError(f"{exc}; {NO_GT_HINT}") from None


def _frame_name(f: int) -> str:
    return f"{f:06d}.png"


def _parallel(fn, items, threads: int = 4):
    with ThreadPoolExecutor(threads) as pool:
        return list(pool.map(fn, items))


def write_sequence(seq: Sequence, folder: str | Path, overwrite: bool = False) -> Path:
    """Write a sequence folder atomically; returns its path."""
    folder = Path(folder)
    # the views' names become folder names (masks/<view>): plain names only, checked before any write
    check_names(seq.rig.names, "camera name", f"the cameras of sequence {seq.name!r}")
    check_fps(seq.fps, f"sequence {seq.name!r}: fps")
    if folder.exists() and not overwrite:
        raise FileExistsError(f"{folder} exists (pass overwrite=True to replace it)")
    if folder.is_symlink():
        raise FileExistsError(f"{folder} is a symbolic link: write the sequence to a plain folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=folder.parent))
    try:
        names = list(seq.rig.names)
        save_calibration(seq.rig, tmp / "calibration.json")
        jobs = []
        for kind, arr in (("masks", seq.masks), ("images", seq.images)):
            if arr is None:
                continue
            for c, view in enumerate(names):
                (tmp / kind / view).mkdir(parents=True)
                for f in range(len(arr)):
                    img = arr[f, c]
                    img = img.astype(np.uint8) * 255 if kind == "masks" else img[..., ::-1]
                    jobs.append((tmp / kind / view / _frame_name(f), img))

        def _write(job):
            path, img = job
            if not cv2.imwrite(str(path), img, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
                raise OSError(f"could not write {path}")

        _parallel(_write, jobs)
        if seq.detections is not None:
            d = seq.detections
            rows = [[int(f), int(v), int(lb), float(x), float(y), float(c)]
                    for f, v, lb, (x, y), c in zip(d.frame, d.view, d.label, d.xy, d.confidence,
                                                   strict=True)]
            columns = _COLUMNS
            if d.person is not None:            # the detector's grouping into skeletons, kept
                columns = [*_COLUMNS, "person"]
                rows = [[*r, int(p)] for r, p in zip(rows, d.person, strict=True)]
            (tmp / "detections.json").write_text(json.dumps(
                {"labels": list(d.labels), "columns": columns, "rows": rows}))
        if seq.gt is not None:
            write_ground_truth(seq.gt, tmp / "gt.npz")
        w, h = seq.image_size
        (tmp / "sequence.json").write_text(json.dumps({
            "format": FORMAT, "name": seq.name, "fps": seq.fps, "frames": seq.num_frames,
            "views": names, "image_size": [w, h],
            "content": {"masks": seq.masks is not None, "images": seq.images is not None,
                        "detections": seq.detections is not None, "gt": seq.gt is not None},
            "meta": seq.meta}, indent=2))
        if folder.exists():
            shutil.rmtree(folder)
        tmp.rename(folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _read_json(path: Path, hint: str) -> dict:
    """A JSON file of the folder; a missing or invalid one names the file (and ``hint``)."""
    if not path.is_file():
        raise SequenceFormatError(f"{path}: not found ({hint})")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise SequenceFormatError(f"{path}: invalid JSON ({exc})") from exc


def _require(obj: dict, key: str, where: Path):
    if not isinstance(obj, dict):
        raise SequenceFormatError(f"{where}: must hold a JSON object, got {type(obj).__name__}")
    if key not in obj:
        raise SequenceFormatError(f"{where}: missing field '{key}'")
    return obj[key]


def _field(check, where: Path, field: str, *args):
    """``check(value, "<file>: field '<field>'", *args)``, its error as SequenceFormatError."""
    try:
        return check(f"{where}: field '{field}'", *args)
    except (BadValueError, UnsafeNameError) as exc:
        raise SequenceFormatError(str(exc)) from None


def _count_files(folder: Path, kind: str, views: list[str], frames: int, meta_path: Path) -> None:
    """Before any array is allocated: each view's folder of ``kind`` holds ``frames`` frame files
    (a count that disagrees is named; a huge claimed count is not read)."""
    for view in views:
        d = folder / kind / view
        if d.is_symlink() or not d.is_dir():
            raise SequenceFormatError(f"{d}: missing folder ({kind} of view {view!r}; "
                                      f"{meta_path} lists {kind} in field 'content')")
        n = sum(1 for p in d.iterdir() if p.suffix == ".png")
        if n < frames:
            f = next(f for f in range(n + 1) if not (d / _frame_name(f)).is_file())
            raise SequenceFormatError(f"{d / _frame_name(f)}: missing frame file ({kind}, view {view!r}, "
                                      f"frame {f}; {meta_path.name} field 'frames' says {frames}, the "
                                      f"folder holds {n})")


def _read_images(folder: Path, kind: str, views: list[str], frames: int, w: int, h: int,
                 threads: int) -> np.ndarray:
    color = kind == "images"
    out = np.zeros((frames, len(views), h, w, 3) if color else (frames, len(views), h, w),
                   dtype=np.uint8 if color else bool)

    def _read(job):
        f, c = job
        path = folder / kind / views[c] / _frame_name(f)
        if not path.is_file():
            raise SequenceFormatError(f"{path}: missing frame file ({kind}, view {views[c]!r}, "
                                      f"frame {f})")
        img = cv2.imread(str(path), cv2.IMREAD_COLOR if color else cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise SequenceFormatError(f"{path}: unreadable image")
        if img.shape[:2] != (h, w):
            raise SequenceFormatError(f"{path}: image is {img.shape[1]}x{img.shape[0]}, "
                                      f"field 'image_size' of sequence.json says {w}x{h}")
        out[f, c] = img[..., ::-1] if color else img > (0 if img.max() <= 1 else 127)

    _parallel(_read, [(f, c) for f in range(frames) for c in range(len(views))], threads)
    return out


NONFINITE = ("refuse", "drop")


def load_sequence(folder: str | Path, *, images: bool = True, threads: int = 4,
                  nonfinite: str = "refuse", gt: str | Path | None = None) -> Sequence:
    """Read and validate a sequence folder (``images=False`` skips the RGB images);
    ``nonfinite``: refuse (default) or drop NaN / Inf ground-truth joints and detections.
    ``gt``: a ground-truth file (:func:`load_ground_truth`) used instead of the folder's; without
    it the folder's gt.npz is used whenever it is there (even if sequence.json does not list
    it: a ground truth is never ignored unless ``gt`` is "none"; its path is ``meta["gt"]``)."""
    if nonfinite not in NONFINITE:
        raise ValueError(f"setting nonfinite = {nonfinite!r} is not allowed (one of: {', '.join(NONFINITE)})")
    folder = Path(folder)
    meta_path = folder / "sequence.json"
    info = _read_json(meta_path, f"is {folder} a sequence folder?")
    fmt = _require(info, "format", meta_path)
    if fmt != FORMAT:
        raise SequenceFormatError(f"{meta_path}: field 'format' is {fmt!r}, expected {FORMAT!r}")
    frames = _field(lambda w: check_int(_require(info, "frames", meta_path), w, 0, MAX_FRAMES),
                    meta_path, "frames")
    views = _field(lambda w: check_type(_require(info, "views", meta_path), w, list, "a list of view names"),
                   meta_path, "views")
    _field(lambda w: check_names(views, "view name", w), meta_path, "views")
    size = _field(lambda w: check_type(_require(info, "image_size", meta_path), w, list, "[width, height]"),
                  meta_path, "image_size")
    if len(size) != 2:
        raise SequenceFormatError(f"{meta_path}: field 'image_size' must be [width, height], got {size!r}")
    w, h = (_field(lambda f, v=v: check_int(v, f, 1, MAX_IMAGE_SIDE), meta_path, "image_size") for v in size)
    content = _field(lambda f: check_type(_require(info, "content", meta_path), f, dict,
                                          "a mapping of what the folder holds"), meta_path, "content")
    for key, value in content.items():
        _field(lambda f, v=value: check_type(v, f, bool, "true or false"), meta_path, f"content.{key}")
    fps = _field(lambda f: check_fps(info.get("fps", 25.0), f), meta_path, "fps")
    name = info.get("name", folder.name)
    _field(lambda f: check_type(name, f, str, "a string"), meta_path, "name")
    _field(lambda f: check_type(info.get("meta", {}), f, dict, "a mapping"), meta_path, "meta")
    rig = load_calibration(folder / "calibration.json")
    if list(rig.names) != views:
        raise SequenceFormatError(f"{folder / 'calibration.json'}: cameras {list(rig.names)} do not "
                                  f"match field 'views' of sequence.json {views}")
    for kind in ("masks", "images"):
        if content.get(kind) and (kind == "masks" or images):
            _count_files(folder, kind, views, frames, meta_path)
    if not content.get("masks") and not (content.get("images") and images) and frames > MAX_KEYPOINT_FRAMES:
        raise SequenceFormatError(f"{meta_path}: field 'frames' = {frames} is more than a keypoint folder "
                                  f"holds (at most {MAX_KEYPOINT_FRAMES})")
    for cam in rig:
        if (cam.width, cam.height) != (w, h):
            raise SequenceFormatError(f"{folder / 'calibration.json'}: camera {cam.name!r} is "
                                      f"{cam.width}x{cam.height}, sequence.json field "
                                      f"'image_size' says {w}x{h}")
    dropped: dict[str, int] = {}
    # the ground truth first: a bad one is refused before any image is read
    gt_path = Path(gt) if gt is not None else folder / "gt.npz"
    if gt_opted_out(gt):
        truth = None
    elif gt is not None or (gt_path.is_file() and not content.get("gt")):
        truth = load_ground_truth_of_data(gt_path, frames, nonfinite, dropped)
    else:
        truth = (load_ground_truth_of_data(gt_path, frames, nonfinite, dropped, listed=True)
                 if content.get("gt") else None)
    masks = _read_images(folder, "masks", views, frames, w, h, threads) if content.get("masks") else None
    if masks is not None and frames:
        empty = [v for c, v in enumerate(views) if not masks[:, c].any()]
        if empty:
            warnings.warn(f"{folder / 'masks'}: the masks of view(s) {', '.join(empty)} are empty in "
                          "every frame (wrong threshold or segmentation failed?)", stacklevel=2)
    imgs = (_read_images(folder, "images", views, frames, w, h, threads)
            if content.get("images") and images else None)
    det = (_load_detections(folder / "detections.json", views, frames, nonfinite, dropped)
           if content.get("detections") else None)
    meta = dict(info.get("meta", {}))
    if truth is not None:
        meta["gt"] = str(gt_path)
    if dropped:
        meta["dropped_nonfinite"] = dropped
        warnings.warn(f"{folder}: non-finite values dropped (nonfinite=drop): "
                      + ", ".join(f"{n} {what}" for what, n in dropped.items()), stacklevel=2)
    return Sequence(name=name, rig=rig, fps=fps,
                    masks=masks, images=imgs, detections=det, gt=truth, meta=meta,
                    # the count only where no array carries it (keypoints alone)
                    frames=frames if masks is None and imgs is None else None)


def _load_detections(path: Path, views: list[str], frames: int | None = None, nonfinite: str = "refuse",
                     dropped: dict | None = None) -> Detections:
    d = _read_json(path, "sequence.json lists detections")
    labels = _field(lambda f: check_type(_require(d, "labels", path), f, list, "a list of label names"),
                    path, "labels")
    for i, label in enumerate(labels):
        _field(lambda f, v=label: check_name(v, "label", f), path, f"labels[{i}]")
    labels = tuple(labels)
    columns = _require(d, "columns", path)
    if columns not in (_COLUMNS, [*_COLUMNS, "person"]):
        raise SequenceFormatError(f"{path}: field 'columns' must be {_COLUMNS} (optionally with 'person' "
                                  f"last), got {columns}")
    n = len(columns)
    try:
        rows = np.asarray(_require(d, "rows", path), dtype=np.float64)
        if rows.size and (rows.ndim != 2 or rows.shape[1] != n):
            raise ValueError(f"shape {rows.shape}")
        rows = rows.reshape(-1, n)
    except (TypeError, ValueError) as exc:
        raise SequenceFormatError(f"{path}: field 'rows' must be rows of {n} numbers ({exc})") from None
    bad = ~np.isfinite(rows).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        col = columns[int(np.flatnonzero(~np.isfinite(rows[i]))[0])]
        if nonfinite != "drop" or not np.isfinite(rows[bad][:, [0, 1, 2, *range(6, n)]]).all():
            raise SequenceFormatError(
                f"{path}: field 'rows': row {i} has {col} = {rows[i, columns.index(col)]} "
                f"({int(bad.sum())} row(s) with NaN/Inf; data.nonfinite=drop leaves out rows with a "
                "non-finite x, y or confidence)")
        rows = rows[~bad]
        if dropped is not None:
            dropped["detection rows"] = int(bad.sum())
    checks = (("view", 1, 0, len(views)), ("label", 2, -1, len(labels)),
              ("frame", 0, 0, frames if frames is not None else np.inf),
              *((("person", 6, -1, np.inf),) if n == 7 else ()))
    for name, c, lo, hi in checks:
        out = (rows[:, c] < lo) | (rows[:, c] >= hi) | (rows[:, c] != np.round(rows[:, c]))
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise SequenceFormatError(f"{path}: field 'rows': row {i} has {name} = {rows[i, c]:g}, out of "
                                      f"range (an integer in [{lo}, {hi - 1:g}])")
    try:
        return Detections(labels=labels, frame=rows[:, 0].astype(np.int64),
                          view=rows[:, 1].astype(np.int64), label=rows[:, 2].astype(np.int64),
                          xy=rows[:, 3:5].copy(), confidence=rows[:, 5].copy(),
                          person=rows[:, 6].astype(np.int64) if n == 7 else None)
    except ValueError as exc:
        raise SequenceFormatError(f"{path}: {exc}") from exc


def write_ground_truth(g: GroundTruth, path: Path) -> None:
    """gt.npz of a ground truth (fields that are None are left out), written atomically
    (:func:`mocap.safe_files.write_npz_atomic`)."""
    arrays = {"joints": g.joints, "joint_names": np.array(g.joint_names), "body": np.array(g.body),
              "skeleton": np.array(g.skeleton)}
    for key in ("alpha", "chi", "markers", "joint_valid", "surface", "surface_faces"):
        if getattr(g, key) is not None:
            arrays[key] = getattr(g, key)
    for key in ("dof_names", "marker_names"):
        arrays[key] = np.array(getattr(g, key), dtype=str)
    if g.person_names:
        arrays["person_names"] = np.array(g.person_names, dtype=str)
    write_npz_atomic(path, arrays)


def load_ground_truth(path: str | Path, frames: int | None = None, nonfinite: str = "refuse",
                      dropped: dict | None = None) -> GroundTruth:
    """A gt.npz (the fields of the module docstring; a person axis: ``joints`` (F, P, J, 3),
    optional ``person_names`` (P,) and ``joint_valid`` (F, P, J)), validated before any work:
    every error names the file and the field. ``frames``: the frames the data has (None: not
    checked)."""
    path = Path(path)
    if not path.is_file():
        raise SequenceFormatError(f"{path}: ground-truth file not found")
    try:
        z = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise SequenceFormatError(f"{path}: not a readable .npz file ({exc})") from None
    if not hasattr(z, "files"):
        raise SequenceFormatError(f"{path}: not a .npz archive of named arrays (one array saved with "
                                  "np.save?)")
    try:
        with z:
            for key in ("joints", "joint_names"):
                if key not in z:
                    raise SequenceFormatError(f"{path}: missing field '{key}' (has "
                                              f"{', '.join(z.files) or 'none'})")
            get = lambda k: z[k] if k in z else None  # noqa: E731
            names = lambda k: tuple(str(n) for n in np.atleast_1d(z[k])) if k in z else ()  # noqa: E731
            joints = z["joints"]
            if not np.issubdtype(joints.dtype, np.number):
                raise SequenceFormatError(f"{path}: field 'joints' must be numbers, got dtype {joints.dtype}")
            surface, surface_faces = _surface(path, get("surface"), get("surface_faces"), joints.shape,
                                              frames)
            gt = GroundTruth(alpha=get("alpha"), chi=get("chi"), joints=joints.astype(np.float64),
                             markers=get("markers"), dof_names=names("dof_names"),
                             joint_names=names("joint_names"), marker_names=names("marker_names"),
                             body=str(z["body"]) if "body" in z else "",
                             joint_valid=None if "joint_valid" not in z else z["joint_valid"].astype(bool),
                             skeleton=str(z["skeleton"]) if "skeleton" in z else "",
                             person_names=names("person_names"), surface=surface,
                             surface_faces=surface_faces)
    except (ValueError, OSError, EOFError) as exc:
        if isinstance(exc, SequenceFormatError):
            raise
        raise SequenceFormatError(f"{path}: cannot read the arrays ({exc})") from None
    J = len(gt.joint_names)
    people = gt.joints.ndim == 4
    if people:
        P = gt.joints.shape[1]
        if not gt.person_names:
            from dataclasses import replace

            gt = replace(gt, person_names=tuple(f"person{p}" for p in range(P)))
        if len(gt.person_names) != P:
            raise SequenceFormatError(f"{path}: field 'person_names' has {len(gt.person_names)} names, "
                                      f"'joints' {gt.joints.shape} has {P} people (axis 1)")
        if len(set(gt.person_names)) != P:
            raise SequenceFormatError(f"{path}: field 'person_names' repeats a name")
        for i, n in enumerate(gt.person_names):
            _field(lambda f, v=n: check_name(v, "person name", f), path, f"person_names[{i}]")
        for key in ("chi", "alpha", "markers"):
            if getattr(gt, key) is not None:
                raise SequenceFormatError(f"{path}: field '{key}' is not allowed with several people "
                                          "(joints (F, P, J, 3)): joints by name only")
    elif gt.person_names:
        raise SequenceFormatError(f"{path}: field 'person_names' needs 'joints' with a person axis "
                                  f"(F, P, J, 3), got {gt.joints.shape}")
    shape = gt.joints.shape
    if gt.joints.ndim not in (3, 4) or shape[-2:] != (J, 3):
        raise SequenceFormatError(f"{path}: field 'joints' must be (F, {J}, 3), or (F, P, {J}, 3) for P "
                                  f"people, for {J} joint_names; got {shape}")
    if len(set(gt.joint_names)) != J:
        raise SequenceFormatError(f"{path}: field 'joint_names' repeats a name")
    if gt.joint_valid is not None and gt.joint_valid.shape != shape[:-1]:
        raise SequenceFormatError(f"{path}: field 'joint_valid' must be {shape[:-1]} (as 'joints' without "
                                  f"its last axis), got {gt.joint_valid.shape}")
    if gt.skeleton:
        from mocap.body.skeletons import SKELETONS, JointNameError, resolve_mapping

        if gt.skeleton not in SKELETONS:
            raise SequenceFormatError(f"{path}: field 'skeleton' is {gt.skeleton!r}, not a known skeleton "
                                      f"(one of: {', '.join(SKELETONS)}; empty for mocap's own joint names)")
        try:
            resolve_mapping(gt.joint_names, [v for v in SKELETONS[gt.skeleton].values() if v], gt.skeleton)
        except JointNameError as exc:
            raise SequenceFormatError(f"{path}: field 'joint_names': {exc}") from None
    for key in ("chi", "markers"):
        arr = getattr(gt, key)
        if arr is not None and len(arr) != len(gt.joints):
            raise SequenceFormatError(f"{path}: field '{key}' has {len(arr)} frames, 'joints' "
                                      f"{len(gt.joints)}")
    if gt.chi is not None and gt.dof_names and gt.chi.shape[1:] != (len(gt.dof_names),):
        raise SequenceFormatError(f"{path}: field 'chi' is {gt.chi.shape}, 'dof_names' has "
                                  f"{len(gt.dof_names)} names")
    if frames is not None and len(gt.joints) != frames:
        raise SequenceFormatError(f"{path}: field 'joints' has {len(gt.joints)} frames, the data has "
                                  f"{frames} (one ground-truth frame per frame of the recording)")
    for key in ("chi", "markers", "alpha"):
        arr = getattr(gt, key)
        if arr is not None and not np.isfinite(arr).all():
            where = np.argwhere(~np.isfinite(np.asarray(arr)))[0]
            raise SequenceFormatError(f"{path}: field '{key}' has NaN/Inf (first at index "
                                      f"{tuple(int(i) for i in where)}; never dropped)")
    valid = np.ones(shape[:-1], bool) if gt.joint_valid is None else gt.joint_valid
    bad = valid & ~np.isfinite(gt.joints).all(axis=-1)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        at = f"frame {where[0]}, " + (f"person {gt.person_names[where[1]]!r}, " if people else "")
        if nonfinite != "drop":
            raise SequenceFormatError(
                f"{path}: field 'joints' has NaN/Inf at {at}joint {gt.joint_names[where[-1]]!r} "
                f"({int(bad.sum())} joint position(s); mark them invalid in 'joint_valid', or "
                "data.nonfinite=drop leaves them out)")
        from dataclasses import replace

        gt = replace(gt, joint_valid=valid & ~bad)
        if dropped is not None:
            dropped["ground-truth joints"] = int(bad.sum())
    return gt


def _surface(path: Path, surface: np.ndarray | None, faces: np.ndarray | None, joints_shape: tuple,
             frames: int | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The optional true surface of a gt.npz, validated: surface (F, N, 3) finite numbers with F
    the frames of 'joints' (and of the data), surface_faces (M, 3) integer indices of its points."""
    if surface is None:
        if faces is not None:
            raise SequenceFormatError(f"{path}: field 'surface_faces' {faces.shape} without field 'surface'")
        return None, None
    F = joints_shape[0] if frames is None else frames
    if (not np.issubdtype(surface.dtype, np.number) or surface.ndim != 3 or surface.shape[2] != 3
            or surface.shape[1] < 1):
        raise SequenceFormatError(f"{path}: field 'surface' must be (F, N, 3) numbers (points on the "
                                  f"true surface per frame, metres), got shape {surface.shape} dtype "
                                  f"{surface.dtype}")
    if len(joints_shape) == 4:
        raise SequenceFormatError(f"{path}: field 'surface' {surface.shape} is for one person, 'joints' "
                                  f"{joints_shape} has several")
    if len(surface) != F or len(surface) != joints_shape[0]:
        raise SequenceFormatError(f"{path}: field 'surface' has shape {surface.shape}: {len(surface)} "
                                  f"frames, the sequence has {F} (one surface per frame)")
    if not np.isfinite(surface).all():
        where = tuple(int(i) for i in np.argwhere(~np.isfinite(surface))[0])
        raise SequenceFormatError(f"{path}: field 'surface' {surface.shape} has NaN/Inf (first at frame "
                                  f"{where[0]}, point {where[1]})")
    if faces is None:
        return surface.astype(np.float64), None
    if not np.issubdtype(faces.dtype, np.integer) or faces.ndim != 2 or faces.shape[1] != 3:
        raise SequenceFormatError(f"{path}: field 'surface_faces' must be (M, 3) integers, got shape "
                                  f"{faces.shape} dtype {faces.dtype}")
    N = surface.shape[1]
    if faces.size and (faces.min() < 0 or faces.max() >= N):
        raise SequenceFormatError(f"{path}: field 'surface_faces' {faces.shape} indexes points "
                                  f"{faces.min()}..{faces.max()}, out of range for 'surface' {surface.shape} "
                                  f"(0..{N - 1})")
    return surface.astype(np.float64), faces.astype(np.int64)
