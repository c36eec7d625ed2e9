"""``mocap detect``: calibrated videos (one per camera) -> per-view 2D keypoints (OpenPose JSON,
MEDIAPIPE_33 layout, with confidences) and person masks, in a Pose2Sim-style folder.

    mocap detect ../shared/data/pose2sim-demo --out outputs/detect/demo
    mocap detect REC --out OUT --stop 100 --step 2 --scale 0.25     # detect at the tracked size

With --people N (or auto) every person in every view is followed: each in a crop around its
previous keypoints, new people found by searching the image again with the people already
found blacked out (mocap/video/people.py); the keypoint files hold several people
("person_id": the view's person id, stable over its frames) and the left/right check runs per
person. Track them with the several-people tracker:

    mocap track tracker=marker_people data=pose2sim_demo data.path=OUT data.person=all \\
        init.mode=tracker

REC holds a calibration (*.toml, or --calibration FILE) and videos/ with one video per camera
(named like the calibration's cameras). OUT gets the calibration, links to the videos,
pose/<cam>_json/*.json, masks/<cam>/*.png and detect.json (mocap/video/detect.py); the
detector's native logs go to OUT/native.log (to the terminal with mocap --debug). After
detection a multi-view check mirrors a view's left/right labels where the other views say
they are swapped (--keep-left-right skips it). Resumable: views already done with the same
settings are skipped (--force redoes them). Track it:

    mocap track data=pose2sim_demo_video data.path=OUT data.keypoints=pose data.layout=auto \\
        data.masks=OUT/masks tracker=marker_apf init.mode=tracker

The detector (MediaPipe BlazePose, shipped in the mediapipe wheel) is an optional dependency
that scripts/setup_env.sh installs (requirements-detect.txt).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings

from mocap_cli.errors import ArgumentParser
from mocap_cli.quiet import debug, native_logs_to


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap detect", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recording", help="folder with the calibration and videos/")
    p.add_argument("--out", required=True, help="output folder (new, or one written by mocap detect)")
    p.add_argument("--videos", default="videos", help="video folder inside the recording (default videos)")
    p.add_argument("--calibration", default=None, help="calibration file inside the recording "
                                                        "(default: the single *.toml)")
    p.add_argument("--start", type=int, default=0)
    p.add_argument("--stop", type=int, default=None, help="last source frame + 1 (default: all)")
    p.add_argument("--step", type=int, default=1)
    p.add_argument("--scale", type=float, default=1.0,
                   help="detect at this fraction of the calibrated size (keypoints are written in "
                        "calibrated pixels; masks at the detection size)")
    p.add_argument("--size-tolerance", type=float, default=0.02,
                   help="video vs calibration size: pad / crop within this fraction of a side")
    p.add_argument("--model-complexity", type=int, default=1, choices=[0, 1])
    p.add_argument("--min-confidence", type=float, default=0.5, help="detection and tracking confidence")
    p.add_argument("--max-missing", type=int, default=None,
                   help="fail (exit 2) when a view has no person in more than this many frames")
    p.add_argument("--keep-left-right", action="store_true",
                   help="skip the multi-view check that mirrors a view's left/right labels when the other "
                        "views say they are swapped")
    p.add_argument("--people", default="1",
                   help="people per view: a whole number >= 1, or auto (everyone the search finds; "
                        "leftover parts of the people already found are refused, and a small person "
                        "far in the background may be missed: give N when known); 1 (default) "
                        "follows one person per view; more: each person in its "
                        "own crop, several people per keypoint file, a mask per person "
                        "(masks/<cam>/<id>/)")
    p.add_argument("--force", action="store_true", help="redo views already done")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    from mocap.video.people import parse_people

    people = parse_people(args.people, "--people")          # before anything else: one line, exit 2
    from mocap.video.detect import plan_detection, run_detection
    from mocap.video.detector import DetectorSettings, detector_available

    if not detector_available():
        raise FileNotFoundError("the detector needs mediapipe==0.10.14, which is not installed: run "
                                "bash scripts/setup_env.sh (or see requirements-detect.txt)")
    settings = DetectorSettings(model_complexity=args.model_complexity,
                                min_detection_confidence=args.min_confidence,
                                min_tracking_confidence=args.min_confidence)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plan = plan_detection(args.recording, args.out, videos=args.videos, calibration=args.calibration,
                              start=args.start, stop=args.stop, step=args.step, scale=args.scale,
                              size_tolerance=args.size_tolerance, detector=settings, force=args.force,
                              people=people)
    for w in {str(w.message) for w in caught}:
        print(f"WARNING: {w}", file=sys.stderr)
    skipped = [n for n in plan.names if n not in plan.todo]
    if skipped:
        print(f"views already done with these settings, skipped: {', '.join(skipped)} (--force redoes them)")
    plan.out.mkdir(parents=True, exist_ok=True)
    # TensorFlow Lite's and absl's lines (about ten per run) go to OUT/native.log unless --debug
    native = contextlib.nullcontext() if debug() else native_logs_to(plan.out / "native.log")
    with warnings.catch_warnings(), native:
        warnings.simplefilter("ignore")             # the padding warning, said above once
        summary = run_detection(plan, progress=not args.no_progress, left_right=not args.keep_left_right)
    too_many = []
    for name, v in summary["views"].items():
        miss = v["missing_frames"]
        w, h = v["resolution"]
        line = (f"{name}: {v['frames'] - len(miss)}/{v['frames']} frames with a person, "
                f"{1000 * v['seconds_per_frame']:.0f} ms per frame at {w}x{h}")
        if "people_per_frame" in v:
            counts = v["people_per_frame"]
            mean = sum(counts) / len(counts)
            line += (f"; people per frame {min(counts)}-{max(counts)} (mean {mean:.2f}), "
                     f"{len(v['person_ids'])} person ids")
        if miss:
            shown = ", ".join(map(str, miss[:20])) + (" ..." if len(miss) > 20 else "")
            line += f"; no person in source frames {shown}"
        mirrored = v.get("left_right_mirrored", [])
        if mirrored:
            line += f"; left/right mirrored (other views disagreed) in {len(mirrored)} frames"
        print(line)
        if args.max_missing is not None and len(miss) > args.max_missing:
            too_many.append(f"{name} ({len(miss)})")
    print(f"-> {plan.out}")
    if too_many:
        raise ValueError(f"{plan.out}: no person found in more than --max-missing={args.max_missing} frames "
                         f"in views {', '.join(too_many)} (see detect.json): check the videos, or lower "
                         "--min-confidence")
    return 0
