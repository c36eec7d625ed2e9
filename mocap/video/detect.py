"""``mocap detect``'s work: calibrated videos (one per camera) -> per-view 2D keypoints
(OpenPose JSON, ``MEDIAPIPE_33`` layout, with confidences) and person masks, written into a
Pose2Sim-style folder that :func:`mocap.data.openpose.load_openpose_sequence` and
:func:`mocap.video.sequence.load_video_sequence` read.

    plan = plan_detection("../shared/data/pose2sim-demo", "outputs/detect/demo")   # all checks
    summary = run_detection(plan)                                                   # the work

The output folder::

    <out>/Calib.toml                      the calibration, copied (its own file name)
    <out>/videos/<video>                  links to the source videos
    <out>/pose/<cam>_json/<cam>.<n:06d>.json   OpenPose JSON per source frame n; "people": []
                                          where nobody was found (as OpenPose writes it)
    <out>/masks/<cam>/<cam>.<n:06d>.png   the person probability x 255 (uint8), at the
                                          detection's resolution (threshold: 128)
    <out>/detect/<cam>.json               a view's record, written last: settings, frames,
                                          frames without a person, seconds per frame
    <out>/detect.json                     the folder's format and the settings of the run

With ``people`` other than 1 (``--people N|auto``: every person, :mod:`mocap.video.people`),
each keypoint file holds everyone found in that view (``"person_id": [id]``, the view's
person id, stable over its frames; views are associated by the several-people tracker),
``masks/<cam>/<cam>.<n:06d>.png`` is the union of everyone's masks and
``masks/<cam>/<id>/<cam>.<n:06d>.png`` each person's; ``detect.json`` and the view records
carry ``people`` (absent for 1: the one-person files of before), and per view
``people_per_frame`` and ``person_ids``. The left/right check then runs per person
(:func:`fix_left_right_people`).

Resumable: a view whose record exists with the same settings is skipped (``force`` redoes
it); a view without a record (an interrupted run) is redone from scratch. A view recorded
with other settings is refused unless ``force``; a non-empty folder without ``detect.json``
(not written by ``mocap detect``, e.g. a Pose2Sim project with its own ``pose/``) is refused
always: results are never mixed.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Sequence as Seq
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from mocap.cameras import load_calibration, project, triangulate
from mocap.data.openpose import _find_calibration
from mocap.safe_files import check_names, inside, write_text_atomic
from mocap.video.detector import NUM_KEYPOINTS, DetectorSettings, PoseDetector
from mocap.video.frames import VideoError, VideoFrames, frame_range, match_videos, video_info
from mocap.video.people import AUTO, PeopleDetector, PeopleSettings, parse_people
from mocap.video.people_views import group_views

FORMAT = "mocap-detect-v1"
KEYPOINTS_DIR, MASKS_DIR, RECORDS_DIR = "pose", "masks", "detect"


@dataclass(frozen=True)
class DetectPlan:
    """Everything checked before work: the views to run and the output folder."""

    source: Path
    out: Path
    calibration: Path
    names: tuple[str, ...]              # camera names, calibration order
    videos: tuple[Path, ...]            # one per camera
    sizes: tuple[tuple[int, int], ...]  # calibrated (width, height) per camera
    frames: tuple[int, ...]             # source frame indices
    scale: float                        # detection resolution / calibrated resolution
    size_tolerance: float
    detector: DetectorSettings = field(default_factory=DetectorSettings)
    todo: tuple[str, ...] = ()          # cameras to run (the others are done with these settings)
    force: bool = False
    people: int | None = 1              # people per view (None: everyone found, --people auto)

    @property
    def people_setting(self) -> int | str:
        """``people`` as written in the records: the number, or "auto"."""
        return AUTO if self.people is None else self.people

    def settings(self, c: int) -> dict:
        """What a view's record must match to be skipped."""
        out = {"video": str(self.videos[c].resolve()), "size": list(self.sizes[c]),
               "frames": list(self.frames), "scale": self.scale, "detector": asdict(self.detector)}
        if self.people != 1:            # one person: the records of before --people, still valid
            out["people"] = self.people_setting
        return out


def _atomic_json(path: Path, data: dict) -> None:
    write_text_atomic(path, json.dumps(data, indent=1))


def plan_detection(source: str | Path, out: str | Path, *, videos: str = "videos",
                   calibration: str | None = None, start: int = 0, stop: int | None = None,
                   step: int = 1, scale: float = 1.0, size_tolerance: float = 0.02,
                   detector: DetectorSettings | None = None, force: bool = False,
                   people: int | str | None = 1) -> DetectPlan:
    """Check the inputs and the output folder (raises ValueError / FileNotFoundError /
    FileExistsError with one line naming the file and what to do) and return the plan.
    people: people per view, a whole number >= 1 or "auto" (everyone found; None means the
    same); 1 is the one-person detector of before (tracking mode), more follow each person
    in its own crop (:mod:`mocap.video.people`)."""
    people = None if people is None else parse_people(people, "people")
    root = Path(source)
    if not root.is_dir():
        raise FileNotFoundError(f"recording folder not found: {root} (a folder with a calibration "
                                "*.toml and a videos/ folder)")
    if not 0 < scale <= 1:
        raise ValueError(f"scale must be in (0, 1] (detection resolution / calibrated), got {scale}")
    calib = root / calibration if calibration is not None else _find_calibration(root)
    rig = load_calibration(calib)       # (camera names are plain names: they become folder names)
    check_names(rig.names, "camera name", calib)
    paths = match_videos(rig.names, root / videos)
    infos = []
    for p in paths:
        try:
            infos.append(video_info(p))
        except VideoError as exc:
            raise VideoError(p, f"{exc.reason}: re-encode it (e.g. ffmpeg -i IN -c:v libx264 OUT.mp4) "
                                "or replace the file") from None
    sizes = tuple((int(w), int(h)) for w, h in rig.sizes)
    for info, (w, h), name in zip(infos, sizes, rig.names, strict=True):
        if abs(info.width - w) > size_tolerance * w or abs(info.height - h) > size_tolerance * h:
            raise ValueError(f"{info.path}: video is {info.width}x{info.height} but the calibration "
                             f"{calib} says {w}x{h} for camera {name!r}: use the calibration made for "
                             f"this video (or the unresized video); size_tolerance={size_tolerance}")
    total = min(i.frames for i in infos)
    frames = tuple(frame_range(total, start, stop, step))
    plan = DetectPlan(root, Path(out), calib, tuple(rig.names), tuple(paths), sizes, frames,
                      float(scale), float(size_tolerance), detector or DetectorSettings(), (), bool(force),
                      people)
    return _check_out(plan)


def _check_out(plan: DetectPlan) -> DetectPlan:
    out = plan.out
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"output {out} is a file: choose another --out")
    if out.resolve() == plan.source.resolve():
        raise FileExistsError(f"output {out} is the recording folder itself: write into a new folder "
                              "(--out), results are never mixed with the recording's own files")
    head = out / "detect.json"
    if out.is_dir() and any(out.iterdir()) and not head.is_file():
        raise FileExistsError(f"output {out} is not empty and was not written by mocap detect (no "
                              "detect.json): choose another --out")
    if head.is_file():
        try:
            fmt = json.loads(head.read_text()).get("format")
        except (OSError, json.JSONDecodeError, AttributeError):
            fmt = None
        if fmt != FORMAT:
            raise FileExistsError(f"{head}: not a {FORMAT} record: choose another --out")
    todo = []
    for c, name in enumerate(plan.names):
        rec = out / RECORDS_DIR / f"{name}.json"
        if plan.force or not rec.is_file():
            todo.append(name)
            continue
        try:
            done = json.loads(rec.read_text())
        except (OSError, json.JSONDecodeError):
            todo.append(name)
            continue
        if done.get("settings") != plan.settings(c):
            old = done.get("settings") or {}
            changed = ", ".join(sorted(k for k, v in plan.settings(c).items() if old.get(k) != v))
            raise FileExistsError(f"{rec}: view {name!r} was detected with other settings ({changed} "
                                  "differ): --force to redo it, or another --out")
    return DetectPlan(**{**plan.__dict__, "todo": tuple(todo)})


def _people_json(kp: np.ndarray | None) -> dict:
    people = [] if kp is None else [{"person_id": [-1],
                                     "pose_keypoints_2d": [round(float(v), 3) for v in kp.reshape(-1)]}]
    return {"version": 1.3, "people": people}


def _several_json(ids: Seq[int], kps: Seq[np.ndarray]) -> dict:
    """OpenPose JSON of several people: ``person_id`` [the per-view id] (stable over the view's frames)."""
    return {"version": 1.3, "people": [{"person_id": [int(i)],
                                        "pose_keypoints_2d": [round(float(v), 3) for v in kp.reshape(-1)]}
                                       for i, kp in zip(ids, kps, strict=True)]}


#: BlazePose index -> its left/right mirror (eyes, ears, mouth corners, limbs, hands, feet)
MIRROR = np.arange(NUM_KEYPOINTS)
for _a, _b in [(1, 4), (2, 5), (3, 6), (7, 8), (9, 10)] + [(k, k + 1) for k in range(11, 32, 2)]:
    MIRROR[_a], MIRROR[_b] = _b, _a
#: keypoints compared when checking a view's left/right labels (shoulders to feet)
BODY = np.arange(11, NUM_KEYPOINTS)


#: BlazePose indices of the handedness cues: left/right shoulders and hips; the nose; heels and toes
_SHOULDERS, _HIPS, _NOSE, _HEELS, _TOES = (11, 12), (23, 24), 0, (29, 30), (31, 32)


def handedness(X: np.ndarray) -> np.ndarray:
    """(..., 33, 3) triangulated BlazePose keypoints (NaN where unknown) -> (..., 2): for a
    forward direction from the nose (ahead of the shoulders' midpoint) and one from the feet
    (toes ahead of heels, both feet), the cosine between the body's left-to-right direction
    (right minus left, shoulders and hips averaged) and the right that forward and up (hips'
    to shoulders' midpoint) make (forward x up). +1: labels as on a real body; -1: left and
    right swapped in 3D, as when most views are mirrored alike; NaN where a cue is missing.
    Every forward and up here is unchanged by swapping the labels; only left-to-right flips."""
    L, R = [np.asarray(i) for i in zip(_SHOULDERS, _HIPS, strict=True)]
    across = (X[..., R, :] - X[..., L, :]).mean(-2)                                  # (..., 3)
    shoulders = X[..., _SHOULDERS, :].mean(-2)
    up = shoulders - X[..., _HIPS, :].mean(-2)
    forward = np.stack([X[..., _NOSE, :] - shoulders,
                        (X[..., _TOES, :] - X[..., _HEELS, :]).mean(-2)], -2)     # (..., 2, 3)
    right = np.cross(forward, up[..., None, :])
    with np.errstate(invalid="ignore", divide="ignore"):
        return (np.einsum("...k,...ik->...i", across, right)
                / (np.linalg.norm(right, axis=-1) * np.linalg.norm(across, axis=-1)[..., None]))


def left_right_fixes(rig, keypoints: np.ndarray, min_confidence: float = 0.5,
                     ratio: float = 0.5, min_handedness: float = 0.3) -> list[int]:
    """Views of one frame whose left/right labels are swapped (fixed in place).

    keypoints: (C, 33, 3) per view (x, y, confidence; all 0 where no person). BlazePose tells
    left from right by the person's appearance and now and then mirrors one view. For each
    view with a person, the body keypoints are triangulated from the other views and
    reprojected into it; when its mirrored labels fit that reprojection better than ``ratio``
    x its own (median pixel error), the view is mirrored. One view at a time, the clearest
    first, until none qualifies. The views then agree, but agreement cannot tell which side was
    right where as many views were swapped as not (2 of 4: the step above mirrors either half).
    So where it mirrored half the views with a person or more (3+ views), the person
    triangulated from them all is checked against a real body's handedness
    (:func:`handedness`), and where every cue found is below ``-min_handedness`` every view is
    mirrored (the other half was the swapped one). Where it mirrored fewer, the views that
    agreed are kept as given: a consensus is not overruled by the 3D cue (one bad view, e.g.
    two people's limbs mixed, can turn the triangulated body over). Returns the views whose
    labels changed (ascending)."""
    C = len(keypoints)
    fixed: list[int] = []
    for _ in range(C):
        ok = keypoints[:, BODY, 2] >= min_confidence                       # (C, B)
        best, best_ratio = None, ratio
        for c in range(C):
            others = ok.copy()
            others[c] = False
            if not ok[c].any() or (others.sum(0) >= 2).sum() < 6:
                continue
            X = triangulate(rig, keypoints[:, BODY, :2], valid=others)
            px = project(rig[[c]], np.nan_to_num(X))[0]                    # (B, 2)
            have = np.all(np.isfinite(X), axis=1) & (others.sum(0) >= 2)
            mirrored = keypoints[c][MIRROR][BODY]
            use = have & ok[c] & (mirrored[:, 2] >= min_confidence)
            if use.sum() < 6:
                continue
            own = np.median(np.linalg.norm(keypoints[c, BODY, :2][use] - px[use], axis=1))
            mir = np.median(np.linalg.norm(mirrored[use, :2] - px[use], axis=1))
            if own > 0 and mir / own < best_ratio:
                best, best_ratio = c, mir / own
        if best is None:
            break
        keypoints[best] = keypoints[best][MIRROR]
        fixed.append(best)
    fixed = [c for c in set(fixed) if fixed.count(c) % 2]          # (a view mirrored twice: as given)
    people = [c for c in range(C) if keypoints[c, :, 2].any()]
    if len(people) >= 3 and 2 * len(fixed) >= len(people) and _swapped_in_3d(
            rig, keypoints, people, min_confidence, min_handedness):
        keypoints[people] = keypoints[people][:, MIRROR]
        fixed = sorted(set(fixed) ^ set(people))
    return sorted(fixed)


def _swapped_in_3d(rig, keypoints: np.ndarray, views: list[int], min_confidence: float,
                   min_handedness: float) -> bool:
    """Whether the person triangulated from ``views`` of ``keypoints`` (C, 33, 3) has every
    :func:`handedness` cue found (at least one) below ``-min_handedness``."""
    seen = np.zeros(keypoints.shape[:2], bool)
    seen[views] = keypoints[views, :, 2] >= min_confidence
    X = triangulate(rig, keypoints[:, :, :2], valid=seen)
    X[seen.sum(0) < 2] = np.nan
    cues = handedness(X)
    cues = cues[np.isfinite(cues)]
    return bool(len(cues)) and bool(np.all(cues < -min_handedness))


def fix_left_right(plan: DetectPlan, progress: bool = True) -> dict[str, list[int]]:
    """Apply :func:`left_right_fixes` to every frame of the folder's keypoint files
    (rewritten in place; idempotent). Returns {camera: source frames mirrored}."""
    from tqdm import tqdm

    rig = load_calibration(plan.calibration)
    out = plan.out / KEYPOINTS_DIR
    fixes: dict[str, list[int]] = {name: [] for name in plan.names}
    for n in tqdm(plan.frames, desc="left/right check", unit="frame", disable=not progress):
        paths = [out / f"{name}_json" / frame_file(name, n, ".json") for name in plan.names]
        kp = np.zeros((len(paths), NUM_KEYPOINTS, 3))
        for c, p in enumerate(paths):
            people = json.loads(p.read_text())["people"]
            if people:
                kp[c] = np.reshape(people[0]["pose_keypoints_2d"], (NUM_KEYPOINTS, 3))
        for c in left_right_fixes(rig, kp):
            write_text_atomic(paths[c], json.dumps(_people_json(kp[c])))
            fixes[plan.names[c]].append(n)
    return fixes


def fix_left_right_people(plan: DetectPlan, progress: bool = True) -> dict[str, list[int]]:
    """:func:`fix_left_right` for several people per view: in each frame the views' people are
    grouped (:func:`mocap.video.people_views.group_views`: one person per view per group, by
    the two-view triangulation of mirror-invariant centres) and each group of 3+ views is
    checked as one person. Returns {camera: source frames where someone was mirrored}."""
    from tqdm import tqdm

    rig = load_calibration(plan.calibration)
    out = plan.out / KEYPOINTS_DIR
    fixes: dict[str, list[int]] = {name: [] for name in plan.names}
    for n in tqdm(plan.frames, desc="left/right check", unit="frame", disable=not progress):
        paths = [out / f"{name}_json" / frame_file(name, n, ".json") for name in plan.names]
        files = [json.loads(p.read_text()) for p in paths]
        ids = [[int(q["person_id"][0]) for q in f["people"]] for f in files]
        people = [np.reshape([q["pose_keypoints_2d"] for q in f["people"]], (-1, NUM_KEYPOINTS, 3))
                  for f in files]
        changed = set()
        for group in group_views(rig, people):
            if len(group) < 3:
                continue
            kp = np.zeros((len(paths), NUM_KEYPOINTS, 3))
            for c, i in group.items():
                kp[c] = people[c][i]
            for c in left_right_fixes(rig, kp):
                people[c][group[c]] = kp[c]
                changed.add(c)
        for c in sorted(changed):
            write_text_atomic(paths[c], json.dumps(_several_json(ids[c], people[c])))
            fixes[plan.names[c]].append(n)
    return fixes


def _detect_people(plan: DetectPlan, c: int, frames: VideoFrames, kdir: Path, mdir: Path, bar) -> dict:
    """Several people in view ``c``: keypoints of everyone per frame (person_id = the view's
    person id), the union of their masks at masks/<cam>/<cam>.<n>.png and each person's at
    masks/<cam>/<id>/<cam>.<n>.png. Returns the view record's figures."""
    name = plan.names[c]
    W, H = plan.sizes[c]
    sx, sy = W / frames.width, H / frames.height
    settings = PeopleSettings(people=plan.people, detector=plan.detector)
    missing, counts, seconds = [], [], 0.0
    with PeopleDetector(settings) as det:
        for f, n in enumerate(plan.frames):
            rgb = frames.view(f, 0)
            t0 = time.perf_counter()
            found = det(rgb)
            seconds += time.perf_counter() - t0
            kps = []
            for person in found:
                kp = person.keypoints.copy()
                kp[:, 0] = sx * (kp[:, 0] + 0.5) - 0.5           # back to calibrated pixels
                kp[:, 1] = sy * (kp[:, 1] + 0.5) - 0.5
                kps.append(kp)
            if not found:
                missing.append(n)
            counts.append(len(found))
            text = json.dumps(_several_json([p.id for p in found], kps))
            (kdir / frame_file(name, n, ".json")).write_text(text)
            union = np.zeros((frames.height, frames.width), np.float32)
            for person in found:
                union = np.maximum(union, person.mask)
                pdir = mdir / str(person.id)
                pdir.mkdir(exist_ok=True)
                cv2.imwrite(str(pdir / frame_file(name, n, ".png")),
                            np.clip(np.round(255 * person.mask), 0, 255).astype(np.uint8))
            cv2.imwrite(str(mdir / frame_file(name, n, ".png")),
                        np.clip(np.round(255 * union), 0, 255).astype(np.uint8))
            bar.update()
    ids = sorted({int(p.name) for p in mdir.iterdir() if p.is_dir()})
    return {"missing_frames": missing, "people_per_frame": counts, "person_ids": ids,
            "seconds": seconds}


def frame_file(name: str, n: int, suffix: str) -> str:
    return f"{name}.{n:06d}{suffix}"


def run_detection(plan: DetectPlan, progress: bool = True, left_right: bool = True) -> dict:
    """Detect every view of ``plan.todo`` (the others are kept) and return the summary
    (also written to ``<out>/detect.json``): per view, frames without a person and speed.
    left_right: then check every frame's left/right labels across views
    (:func:`fix_left_right`; the frames mirrored are in the summary)."""
    from tqdm import tqdm

    out = plan.out
    check_names(plan.names, "camera name", plan.calibration)
    out.mkdir(parents=True, exist_ok=True)
    head = {"format": FORMAT, "source": str(plan.source.resolve()), "calibration": plan.calibration.name,
            "layout": "MEDIAPIPE_33", "cameras": list(plan.names)}
    if plan.people != 1:
        head["people"] = plan.people_setting
    _atomic_json(out / "detect.json", head)
    if not (out / plan.calibration.name).is_file():
        shutil.copy2(plan.calibration, out / plan.calibration.name)
    (out / "videos").mkdir(exist_ok=True)
    for p in plan.videos:
        link = out / "videos" / p.name
        if not link.exists():
            link.symlink_to(p.resolve())
    (out / RECORDS_DIR).mkdir(exist_ok=True)
    for c, name in enumerate(plan.names):
        if name not in plan.todo:
            continue
        rec = inside(out / RECORDS_DIR / f"{name}.json", out, "delete")
        rec.unlink(missing_ok=True)
        kdir, mdir = out / KEYPOINTS_DIR / f"{name}_json", out / MASKS_DIR / name
        for d in (kdir, mdir):
            inside(d, out, "delete")
            if d.is_symlink():          # never through a link: only the link goes
                d.unlink()
            shutil.rmtree(d, ignore_errors=True)
            d.mkdir(parents=True)
        frames = VideoFrames([plan.videos[c]], [plan.sizes[c]], list(plan.frames), plan.scale,
                             names=[name], size_tolerance=plan.size_tolerance, cache=1)
        W, H = plan.sizes[c]
        sx, sy = W / frames.width, H / frames.height
        missing, seconds = [], 0.0
        bar = tqdm(total=len(plan.frames), desc=f"detect {name}", unit="frame", disable=not progress)
        if plan.people != 1:
            with bar:
                got = _detect_people(plan, c, frames, kdir, mdir, bar)
            frames.close()
            seconds = got.pop("seconds")
            _atomic_json(rec, {"settings": plan.settings(c), **got,
                               "resolution": [frames.width, frames.height],
                               "seconds_per_frame": seconds / len(plan.frames)})
            continue
        with PoseDetector(plan.detector) as det, bar:
            for f, n in enumerate(plan.frames):
                rgb = frames.view(f, 0)
                t0 = time.perf_counter()
                d = det(rgb)
                seconds += time.perf_counter() - t0
                kp = None
                if d.found:
                    kp = d.keypoints.copy()
                    kp[:, 0] = sx * (kp[:, 0] + 0.5) - 0.5           # back to calibrated pixels
                    kp[:, 1] = sy * (kp[:, 1] + 0.5) - 0.5
                else:
                    missing.append(n)
                (kdir / frame_file(name, n, ".json")).write_text(json.dumps(_people_json(kp)))
                mask = d.mask if d.mask is not None else np.zeros((frames.height, frames.width))
                cv2.imwrite(str(mdir / frame_file(name, n, ".png")),
                            np.clip(np.round(255 * mask), 0, 255).astype(np.uint8))
                bar.update()
        frames.close()
        _atomic_json(rec, {"settings": plan.settings(c), "missing_frames": missing,
                           "resolution": [frames.width, frames.height],
                           "seconds_per_frame": seconds / len(plan.frames)})
    fix = fix_left_right if plan.people == 1 else fix_left_right_people
    fixes = fix(plan, progress) if left_right and len(plan.names) >= 3 else None
    return summarise(out, plan.names, fixes, redone=plan.todo)


def summarise(out: Path, names: Seq[str], fixes: dict[str, list[int]] | None = None,
              redone: Seq[str] = ()) -> dict:
    """Per view, from the records: frames without a person, resolution and speed (and the
    frames whose left/right labels were mirrored, accumulated over runs); written into
    ``<out>/detect.json`` beside its header."""
    head = json.loads((out / "detect.json").read_text())
    views = {}
    for name in names:
        rec = json.loads((out / RECORDS_DIR / f"{name}.json").read_text())
        views[name] = {k: rec[k] for k in ("missing_frames", "resolution", "seconds_per_frame",
                                           "people_per_frame", "person_ids") if k in rec}
        views[name]["frames"] = len(rec["settings"]["frames"])
        before = [] if name in redone else head.get("views", {}).get(name, {}).get("left_right_mirrored", [])
        views[name]["left_right_mirrored"] = sorted(set(before) | set((fixes or {}).get(name, [])))
    head["views"] = views
    _atomic_json(out / "detect.json", head)
    return head


def read_masks(folder: str | Path, names: Seq[str], frames: Seq[int], size: tuple[int, int],
               probability: bool = False) -> np.ndarray:
    """(F, C, H, W) masks of source ``frames`` from a ``masks/`` folder written by
    :func:`run_detection`, resized to ``size`` = (W, H): bool (probability >= 0.5) or, with
    ``probability``, float32 in [0, 1]. Raises FileNotFoundError naming a missing file."""
    folder = Path(folder)
    W, H = size
    out = np.zeros((len(frames), len(names), H, W), np.float32 if probability else bool)
    for c, name in enumerate(names):
        for f, n in enumerate(frames):
            p = folder / name / frame_file(name, n, ".png")
            img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
            if img is None:
                raise FileNotFoundError(f"mask not found or unreadable: {p} (run mocap detect for these "
                                        "frames)")
            if img.shape != (H, W):
                img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
            prob = img.astype(np.float32) / 255.0
            out[f, c] = prob if probability else prob >= 0.5
    return out


__all__ = ["DetectPlan", "plan_detection", "run_detection", "read_masks", "summarise", "NUM_KEYPOINTS",
           "fix_left_right_people", "handedness"]
