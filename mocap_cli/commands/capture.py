"""``mocap capture``: one command from calibrated videos to motion files. Chains detect ->
(calibrate, where asked) -> track -> export into one folder:

    mocap capture ../shared/data/pose2sim-demo --out outputs/capture_demo --stop 60
    mocap capture REC --out OUT --tracker hybrid --formats bvh,gltf
    mocap capture REC --out OUT --calibrate people --intrinsics-from intrinsics.toml --height 1.75
    mocap capture REC --out OUT --calibrate board --intrinsics BOARD_CLIPS --board-views SYNC_CLIPS
    mocap capture REC --out OUT --people auto        # several people: tracker=marker_people

REC holds the videos (in REC/videos/, or REC itself), one per camera named like the calibration's
cameras, and the calibration (--calibration FILE, default the single *.toml in REC or
REC/calibration/), unless --calibrate makes one (board or points: before detection, from boards
or known points; people: after detection, from the detected keypoints, intrinsics from
--intrinsics-from, default REC's calibration). OUT gets detect/ (mocap detect's folder),
calibrate/ (mocap calibrate's), track/ (a mocap track run folder), export/ (motion.bvh, .trc,
.glb, .c3d; one file per person and format with several people) and capture.json.

Every input is checked before any work (one line naming what is wrong and what to do). Each
stage prints its start and end with its wall time. Resumable: a stage done with the same
settings (recorded in capture.json) is skipped; a stage that runs again makes every later one
run again. docs/capture.md has the details and measured figures.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from mocap_cli import interrupt
from mocap_cli.errors import ArgumentParser

DEFAULT_FORMATS = ("bvh", "trc", "gltf", "c3d")
CALIBRATE = ("board", "points", "people")


@dataclass(frozen=True)
class Inputs:
    """What the checks found: paths resolved, the cameras, the frames."""

    source: Path
    videos: Path                    # the video folder
    calibration: Path | None        # the calibration detection uses (None: made by the board/points stage)
    cameras: tuple[str, ...]
    frames: int                     # frames per video
    fps: float


def _parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="mocap capture", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recording", help="folder with the videos (in videos/ or in it) and the calibration")
    p.add_argument("--out", required=True, help="output folder (new, or one written by mocap capture)")
    p.add_argument("--people", default="1", help="1 (default: the single-person tracker), N or auto "
                                                 "(several people: tracker=marker_people)")
    p.add_argument("--tracker", default=None, help="tracker preset (mocap/trackers/presets.py; default "
                                                   "marker_apf, marker_people for several people)")
    p.add_argument("--calibration", default=None, help="calibration file (default: the single *.toml in "
                                                        "the recording folder or its calibration/)")
    p.add_argument("--calibrate", default=None, choices=CALIBRATE,
                   help="calibrate the cameras first: board, points, or people (from the detections)")
    p.add_argument("--intrinsics", default=None, help="(--calibrate) board images or videos per camera")
    p.add_argument("--intrinsics-from", default=None,
                   help="(--calibrate) take the intrinsics from this calibration file")
    p.add_argument("--board", default="checkerboard:4x7:0.06",
                   help="(--calibrate) the board, as mocap calibrate takes it")
    p.add_argument("--board-views", default=None,
                   help="(--calibrate board) synchronised board views per camera")
    p.add_argument("--points", default=None, help="(--calibrate points) known points and their pixels")
    p.add_argument("--height", type=float, default=None, help="(--calibrate people) the person's height, m")
    p.add_argument("--length", nargs=3, default=None, metavar=("A", "B", "METRES"),
                   help="(--calibrate people) a known distance between two keypoints")
    p.add_argument("--start", type=int, default=0)
    p.add_argument("--stop", type=int, default=None, help="last source frame + 1 (default: all)")
    p.add_argument("--step", type=int, default=1)
    p.add_argument("--scale", type=float, default=1.0, help="detect at this fraction of the calibrated size")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--formats", default=",".join(DEFAULT_FORMATS),
                   help=f"export formats, comma separated (default {','.join(DEFAULT_FORMATS)})")
    p.add_argument("--track-set", action="append", default=[], metavar="KEY=VALUE",
                   help="one more mocap track override (repeatable), e.g. --track-set frames=20")
    p.add_argument("--no-progress", action="store_true")
    return p


def _people(value: str) -> int | str:
    if value == "auto":
        return "auto"
    try:
        n = int(value)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"--people must be a positive number or auto, got {value!r}")
    return n


def _trackers() -> list[str]:
    from mocap.trackers.presets import PRESETS  # the presets are Python (no numeric import)

    return sorted(PRESETS)


def _check_tracker(name: str, people) -> None:
    known = _trackers()
    if name not in known:
        import difflib

        close = difflib.get_close_matches(name, known, n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ValueError(f"--tracker: unknown tracker {name!r}{hint}; known: {', '.join(known)}")
    if people == 1 and name == "marker_people":
        raise ValueError("--tracker marker_people tracks several people: pass --people N or --people auto")
    if people != 1 and name != "marker_people":
        raise ValueError(f"--people {people}: several people are tracked by marker_people only, not {name!r} "
                         "(leave --tracker out)")


def _video_folder(source: Path) -> Path:
    return source / "videos" if (source / "videos").is_dir() else source


def _check_videos(cameras, folder: Path) -> tuple[int, float]:
    """Every camera's video opens, and all have the same length and frame rate."""
    from mocap.video.frames import VideoError, match_videos, video_info

    infos = []
    for name, path in zip(cameras, match_videos(cameras, folder), strict=True):
        try:
            infos.append((name, video_info(path)))
        except VideoError as exc:
            raise VideoError(path, f"camera {name!r}: {exc.reason}: re-encode it (e.g. ffmpeg -i IN -c:v "
                                   "libx264 OUT.mp4) or replace the file") from None
    name0, first = infos[0]
    for name, info in infos[1:]:
        if info.frames != first.frames:
            raise ValueError(f"{info.path}: camera {name!r} has {info.frames} frames, camera {name0!r} "
                             f"{first.frames}: the videos must be synchronised clips of the same length "
                             "(cut them to the same frames)")
        if abs(info.fps - first.fps) > 1e-3 * first.fps:
            raise ValueError(f"{info.path}: camera {name!r} runs at {info.fps:g} fps, camera {name0!r} at "
                             f"{first.fps:g}: the videos must have the same frame rate")
    return int(first.frames), float(first.fps)


def check_inputs(a) -> tuple[Inputs, dict]:
    """Every check before any work; returns the inputs and the existing capture record."""
    from mocap.cameras import load_calibration
    from mocap.data.openpose import _find_calibration
    from mocap.export import FORMATS
    from mocap.run_folder.capture import check_capture_folder

    source = Path(a.recording)
    if not source.is_dir():
        raise FileNotFoundError(f"recording folder not found: {source} (a folder with the videos, one per "
                                "camera, and the calibration)")
    formats = [f.strip() for f in a.formats.split(",") if f.strip()]
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ValueError(f"--formats: unknown format {bad[0] if bad else a.formats!r} (known: "
                         f"{', '.join(FORMATS)})")
    if a.step < 1 or a.start < 0 or (a.stop is not None and a.stop <= a.start):
        raise ValueError(f"--start {a.start} --stop {a.stop} --step {a.step}: need 0 <= start < stop "
                         "and step >= 1")
    if not 0 < a.scale <= 1:
        raise ValueError(f"--scale must be in (0, 1] (detection resolution / calibrated), got {a.scale}")
    for kv in a.track_set:
        if "=" not in kv:
            raise ValueError(f"--track-set {kv!r}: write KEY=VALUE (a mocap track override)")
    if a.calibration is not None and a.calibrate is not None:
        raise ValueError("give --calibration FILE or --calibrate METHOD, not both")
    calib = None
    if a.calibrate is None:
        calib = Path(a.calibration) if a.calibration is not None else _find_calibration(source)
        if not calib.is_file():
            raise FileNotFoundError(f"--calibration: file not found: {calib}")
    else:
        _check_calibrate(a, source)
        if a.calibrate == "people":
            calib = Path(a.intrinsics_from)
    folder = _video_folder(source)
    if calib is not None:
        cameras = tuple(load_calibration(calib).names)
    elif a.intrinsics_from is not None:
        cameras = tuple(load_calibration(a.intrinsics_from).names)
    else:
        from mocap.calibration.sources import find_sources

        cameras = tuple(s.name for s in find_sources(a.intrinsics))
    frames, fps = _check_videos(cameras, folder)
    if a.start >= frames:
        raise ValueError(f"--start {a.start}: the videos have {frames} frames")
    record = check_capture_folder(a.out)
    inputs = Inputs(source, folder, calib, cameras, frames, fps)
    if calib is not None:       # mocap detect's own checks (video sizes against the calibration)
        detection_plan(a, inputs, Path(a.out), _people(a.people), calib)
    return inputs, record


def _check_calibrate(a, source: Path) -> None:
    """--calibrate's own inputs, as mocap calibrate checks them (before any work)."""
    from mocap.data.openpose import _find_calibration

    if a.calibrate == "people":
        if a.intrinsics is not None:
            raise ValueError("--calibrate people takes the intrinsics from a calibration file "
                             "(--intrinsics-from FILE), not from boards: calibrate them first with "
                             "mocap calibrate")
        if a.intrinsics_from is None:
            a.intrinsics_from = str(_find_calibration(source))
    if (a.intrinsics is None) == (a.intrinsics_from is None):
        raise ValueError(f"--calibrate {a.calibrate} needs exactly one of --intrinsics FOLDER (board images "
                         "or videos per camera) and --intrinsics-from CALIBRATION")
    if a.calibrate == "board" and a.board_views is None:
        raise ValueError("--calibrate board needs --board-views FOLDER (synchronised board views per camera)")
    if a.calibrate == "points" and a.points is None:
        raise ValueError("--calibrate points needs --points FILE (known points and their pixels)")
    if a.calibrate == "people" and a.height is None and a.length is None:
        print("WARNING: --calibrate people without --height or --length: the calibration's scale is "
              "arbitrary", file=sys.stderr)
    from mocap.calibration.pipeline import check_options

    check_options(_calibrate_options(a, Path(a.out) / "calibrate", keypoints=str(source)))


def _calibrate_options(a, out: Path, keypoints: str | None = None):
    from mocap.calibration.boards import parse_board
    from mocap.calibration.pipeline import CalibrateOptions

    length = None
    if a.length is not None:
        try:
            length = (a.length[0], a.length[1], float(a.length[2]))
        except ValueError:
            raise ValueError(f"--length: METRES must be a number, got {a.length[2]!r}") from None
    return CalibrateOptions(out=str(out), intrinsics=a.intrinsics, intrinsics_from=a.intrinsics_from,
                            board=parse_board(a.board), extrinsics=a.calibrate, board_views=a.board_views,
                            points=a.points, keypoints=keypoints, layout="MEDIAPIPE_33", height=a.height,
                            length=length, overwrite=True)


def _fingerprint(path: Path | str | None) -> list | None:
    """A file's identity for the records: resolved path, size, modification time."""
    if path is None:
        return None
    p = Path(path).resolve()
    st = p.stat()
    return [str(p), st.st_size, st.st_mtime_ns]


# --- the stages -------------------------------------------------------------------------------


def _stages(a, inputs: Inputs, out: Path, people, tracker: str, formats: list[str]):
    from mocap.run_folder.capture import Stage

    calib_made = out / "calibrate" / "Calib.toml"
    detect_calib = inputs.calibration if a.calibrate in (None, "people") else calib_made
    track_calib = inputs.calibration if a.calibrate is None else calib_made
    from mocap.video.frames import match_videos

    made_first = a.calibrate in ("board", "points")
    detect_settings = {"videos": [_fingerprint(p) for p in match_videos(inputs.cameras, inputs.videos)],
                       "calibration": None if made_first else _fingerprint(detect_calib),
                       "start": a.start, "stop": a.stop, "step": a.step, "scale": a.scale, "people": people,
                       "left_right": a.calibrate != "people"}
    stages = {"detect": Stage("detect", detect_settings, ("detect/detect.json",))}
    if a.calibrate is not None:
        calib = {"method": a.calibrate, "intrinsics": a.intrinsics,
                 "intrinsics_from": _fingerprint(a.intrinsics_from),
                 "board": a.board, "board_views": a.board_views, "points": _fingerprint(a.points),
                 "height": a.height, "length": a.length}
        stages["calibrate"] = Stage("calibrate", calib, ("calibrate/Calib.toml",))
    order = ["calibrate", "detect"] if made_first else ["detect", "calibrate"]
    ordered = [stages[n] for n in order if n in stages]
    overrides = track_overrides(a, inputs, out, people, tracker, track_calib)
    ordered.append(Stage("track", {"overrides": overrides}, ("track/manifest.json",)))
    ordered.append(Stage("export", {"formats": formats}))
    return ordered, detect_calib, track_calib


def _quote(value) -> str:
    text = str(value)
    if "'" in text or "\\" in text:
        raise ValueError(f"path {text!r}: quotes and backslashes cannot be passed to the tracker's config; "
                         "rename the folder")
    return f"'{text}'"


def track_overrides(a, inputs: Inputs, out: Path, people, tracker: str, calibration: Path) -> list[str]:
    """The ``mocap track`` overrides of the track stage."""
    detect = (out / "detect").resolve()
    stop = "null" if a.stop is None else a.stop
    common = [f"tracker={tracker}", f"seed={a.seed}", "init.mode=tracker",
              f"data.path={_quote(detect)}", f"data.calibration={_quote(Path(calibration).resolve())}",
              "data.keypoints=pose", "data.layout=auto"]
    if tracker.startswith("marker_"):
        # keypoints only (the detection's frames are the files written)
        data = ["data=pose2sim_demo", f"data.fps={inputs.fps / a.step:g}", "data.name=capture",
                f"data.person={'subject' if people == 1 else 'all'}"]
    else:
        # silhouette trackers: the videos, the detected masks and keypoints, the detection's frames
        data = ["data=pose2sim_demo_video", f"data.masks={_quote(detect / 'masks')}", f"data.start={a.start}",
                f"data.stop={stop}", f"data.step={a.step}", "data.name=capture"]
    return [data[0], *common, *data[1:], f"hydra.run.dir={_quote((out / 'track').resolve())}", *a.track_set]


def _say(line: str) -> None:
    print(line, flush=True)


def detection_plan(a, inputs: Inputs, out: Path, people, calibration: Path, force: bool = False):
    """The detect stage's plan (every check of mocap detect; nothing written); None when views
    were detected with other settings and not ``force``."""
    import warnings

    from mocap.video.detect import plan_detection

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return plan_detection(inputs.source, out / "detect", people=people,
                                   videos=str(inputs.videos.relative_to(inputs.source)),
                                   calibration=str(Path(calibration).resolve()), start=a.start, stop=a.stop,
                                   step=a.step, scale=a.scale, force=force)
        except FileExistsError as exc:
            if force or "other settings" not in str(exc):
                raise
            return None


def run_detect(a, inputs: Inputs, out: Path, people, calibration: Path) -> dict:
    import contextlib
    import warnings

    from mocap.video.detect import run_detection
    from mocap.video.detector import detector_available
    from mocap_cli.quiet import debug, native_logs_to

    if not detector_available():
        raise FileNotFoundError("the detector needs mediapipe==0.10.14, which is not installed: run "
                                "bash scripts/setup_env.sh (or see requirements-detect.txt)")
    interrupt.check()           # a Ctrl-C during the detector's import (recorded, not raised there)
    plan = detection_plan(a, inputs, out, people, calibration, force=False)
    if plan is None:            # views detected with other settings before: this stage redoes them
        plan = detection_plan(a, inputs, out, people, calibration, force=True)
    plan.out.mkdir(parents=True, exist_ok=True)
    native = contextlib.nullcontext() if debug() else native_logs_to(plan.out / "native.log")
    with warnings.catch_warnings(), native:
        warnings.simplefilter("ignore")
        summary = run_detection(plan, progress=not a.no_progress, left_right=a.calibrate != "people")
    for name, v in summary["views"].items():
        miss = v["missing_frames"]
        _say(f"  {name}: {v['frames'] - len(miss)}/{v['frames']} frames with a person")
    return summary


def run_calibrate(a, out: Path) -> dict:
    from mocap.calibration.pipeline import run_calibration, summary

    keypoints = str(out / "detect" / "pose") if a.calibrate == "people" else None
    report = run_calibration(_calibrate_options(a, out / "calibrate", keypoints))
    for line in summary(report).splitlines():
        _say(f"  {line}")
    return report


def run_track(overrides: list[str], tracker: str) -> None:
    from mocap_cli.commands import track

    what = "silhouettes" if not tracker.startswith("marker_") else "keypoints"
    cost = "seconds to a minute" if tracker.startswith("marker_") else "a minute or more on busy cores"
    _say(f"  start-up: {tracker} initialises itself from the first frames' {what} (no ground truth): "
         f"{cost} before the first frame ...")
    track.main(overrides)


def run_export(out: Path, formats: list[str]) -> list[str]:
    """Every format into ``out/export``: ``motion.<ext>``; several people
    (:func:`mocap.run_folder.export.export_files`): a BVH per person (``motion_p<id>.bvh``) and one
    TRC / C3D / GLB with everyone."""
    from mocap.export import FORMATS
    from mocap.run_folder.export import export_files

    run = out / "track"
    folder = out / "export"
    folder.mkdir(exist_ok=True)
    for old in folder.iterdir():        # an earlier run's files (another motion, other formats)
        if old.is_file():
            old.unlink()
    written: list[Path] = []
    for fmt in formats:
        written += export_files(run, fmt, folder / f"motion{FORMATS[fmt]}", overwrite=True)
    return [str(Path(p).relative_to(out)) for p in written]


def capture_summary(out: Path, record: dict) -> dict:
    """Frames, people, lost frames, reprojection per camera and the files, from the run's outputs."""
    metrics = json.loads((out / "track" / "metrics.json").read_text())
    quality = metrics.get("quality") or {}
    people = metrics.get("people")
    summary = {"frames": metrics.get("frames"),
               "people": len(people) if isinstance(people, list) else 1,
               "frames_without_detections": len(metrics.get("frames_without_detections") or []),
               "frames_seen_by_fewer_than_2_cameras": _under_two_views(out / "detect" / "detect.json"),
               "lost_frames": quality.get("lost_frames"),
               "reprojection_median_px": metrics.get("reprojection_median_px"),
               "reprojection_median_px_per_view": metrics.get("reprojection_median_px_per_view"),
               "reprojection_px_per_person": metrics.get("reprojection_px_per_person"),
               "quality_flags": quality.get("flags", []),
               "files": (record["stages"].get("export") or {}).get("outputs", [])}
    calib_report = out / "calibrate" / "report.json"
    if calib_report.is_file():
        rep = json.loads(calib_report.read_text())
        summary["calibration_rms_px"] = {n: r["rms_px"] for n, r in rep.get("extrinsics_px", {}).items()}
    return summary


def _under_two_views(detect_json: Path) -> int | None:
    """Detected frames in which fewer than two cameras found a person (nothing to triangulate)."""
    try:
        views = json.loads(detect_json.read_text())["views"]
    except (OSError, ValueError, KeyError):
        return None
    from collections import Counter

    missing = Counter(n for v in views.values() for n in v.get("missing_frames", []))
    return sum(1 for n, k in missing.items() if len(views) - k < 2)


def summary_lines(out: Path, s: dict) -> list[str]:
    lost = "not measured by this tracker" if s["lost_frames"] is None else s["lost_frames"]
    lines = [f"frames: {s['frames']}, people: {s['people']}, lost frames: {lost}; frames without detections: "
             f"{s['frames_without_detections']}, seen by fewer than 2 cameras: "
             f"{s['frames_seen_by_fewer_than_2_cameras']}"]
    if s.get("reprojection_median_px_per_view"):
        per = ", ".join(f"{k} {v:.1f}" for k, v in s["reprojection_median_px_per_view"].items())
        lines.append(f"reprojection median px: {s['reprojection_median_px']:.1f} (per camera: {per})")
    if s.get("reprojection_px_per_person"):
        per = ", ".join(f"person {k} {v:.1f}" for k, v in s["reprojection_px_per_person"].items())
        lines.append(f"reprojection median px per person: {per}")
    if s.get("calibration_rms_px"):
        per = ", ".join(f"{k} {v:.2f}" for k, v in s["calibration_rms_px"].items())
        lines.append(f"calibration reprojection RMS px: {per}")
    if s.get("quality_flags"):
        lines.append(f"quality flags: {'; '.join(s['quality_flags'])}")
    lines.append(f"files: {', '.join(str(out / f) for f in s['files'])}")
    lines.append(f"run folder: {out / 'track'} (mocap replay {out / 'track'}); "
                 f"record: {out / 'capture.json'}")
    return lines


def main(argv: list[str] | None = None) -> int:
    a = _parser().parse_args(argv)
    people = _people(a.people)
    tracker = a.tracker or ("marker_apf" if people == 1 else "marker_people")
    _check_tracker(tracker, people)
    inputs, record = check_inputs(a)
    out = Path(a.out)
    formats = [f.strip() for f in a.formats.split(",") if f.strip()]
    from mocap.run_folder import capture as plan
    from mocap.run_folder.lock import run_lock

    stages, detect_calib, _ = _stages(a, inputs, out, people, tracker, formats)
    from mocap.run_folder.manifest import manifest_problem

    invalid = {"track": (out / "track").is_dir() and manifest_problem(out / "track") is not None}
    todo = plan.stages_to_run(out, record, stages, invalid)
    t_all = time.perf_counter()
    with run_lock(out):
        record = {**record, "format": plan.FORMAT, "stages": record.get("stages", {})}
        for i, (stage, run) in enumerate(zip(stages, todo, strict=True)):
            if not run:
                _say(f"[{stage.name}] done before with these settings: skipped")
                continue
            changed = plan.changed_settings(record, stage) if stage.name in record["stages"] else []
            why = f" (changed: {', '.join(changed)})" if changed else ""
            interrupt.check()
            _say(f"[{stage.name}] start{why}")
            record = plan.start_stage(out, record, stages, i)
            t, cpu = time.perf_counter(), time.process_time()
            outputs = None
            if stage.name == "detect":
                run_detect(a, inputs, out, people, detect_calib)
            elif stage.name == "calibrate":
                run_calibrate(a, out)
            elif stage.name == "track":
                run_track(list(stage.settings["overrides"]), tracker)
            else:
                outputs = run_export(out, formats)
            seconds = time.perf_counter() - t
            cpu = time.process_time() - cpu
            record = plan.finish_stage(out, record, stage, seconds, outputs, cpu_seconds=round(cpu, 3))
            _say(f"[{stage.name}] done in {seconds:.1f} s ({cpu:.1f} s CPU)")
        summary = capture_summary(out, record)
        record = {**record, "summary": summary}
        plan.write_record(out, record)
    _say(f"capture done in {time.perf_counter() - t_all:.1f} s")
    for line in summary_lines(out, summary):
        _say(line)
    return 0
