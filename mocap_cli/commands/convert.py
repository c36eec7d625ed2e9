"""``mocap convert``: a Pose2Sim folder (calibration, OpenPose JSON per view under pose/,
optional gt.npz) -> a sequence folder (sequence.json, calibration.json, detections.json, gt.npz).

    mocap convert ../shared/data/pose2sim-demo outputs/demo_seq           # 60 fps, from its videos
    mocap convert REC OUT --person subject --layout BODY_25B --frames 50

The detector's grouping of keypoints into people is kept per view (detections.json's person
column; --person all, the default) or one person is picked per frame (--person subject). The
keypoint layout is detected (--layout auto) and recorded in sequence.json with the person mode.
Track the result with ``mocap track data=folder data.path=OUT tracker=marker_apf
init.mode=tracker``; ``mocap gt-from-joints JOINTS OUT`` adds ground truth to it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mocap.body.skeletons import LAYOUTS
from mocap_cli.errors import ArgumentParser


def videos_fps(recording: Path) -> float:
    """The frame rate of the recording's videos (videos/*, the first in name order); an error
    asking for --fps where there are none (no rate is assumed: the Pose2Sim demo is 60 fps)."""
    videos = sorted(p for p in (recording / "videos").glob("*") if p.is_file()) if recording.is_dir() else []
    if not videos:
        raise ValueError(f"{recording}: no videos/ to read the frame rate from: pass --fps (the "
                         "recording's frames per second; the Pose2Sim demo is 60)")
    from mocap.video.frames import video_info

    fps = float(video_info(videos[0]).fps)
    if not fps > 0:
        raise ValueError(f"{videos[0]}: no frame rate in the video: pass --fps")
    return fps


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap convert", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recording", help="Pose2Sim folder: a calibration (*.toml) and pose/<camera>_json/")
    p.add_argument("out", help="the sequence folder to write (new; --overwrite replaces one)")
    p.add_argument("--layout", default="auto", choices=["auto", *LAYOUTS], help="keypoint layout (auto)")
    p.add_argument("--person", default="all", choices=["all", "subject"],
                   help="all: everyone, grouped per view as detected; subject: one person per frame")
    p.add_argument("--fps", type=float, default=None,
                   help="the recording's frames per second (default: its videos' own, from videos/; "
                        "required without videos)")
    p.add_argument("--frames", type=int, default=None, help="convert only the first N frames")
    p.add_argument("--min-confidence", type=float, default=0.0, help="drop keypoints below it [0, 1)")
    p.add_argument("--calibration", default=None, help="calibration file inside the folder (default: "
                                                        "the single *.toml)")
    p.add_argument("--keypoints", default="pose", help="keypoint folder inside the folder (default pose)")
    p.add_argument("--gt", default=None, help="a ground-truth file (gt.npz) to include (default: the "
                                              "folder's gt.npz, when there is one)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    args = p.parse_args(argv)
    from mocap.checks import check_fps
    from mocap.data.openpose import convert_pose2sim

    if args.fps is not None:
        check_fps(args.fps, "--fps")                # before anything is read or written
    elif any(p.is_file() for p in (Path(args.recording) / "videos").glob("*")):
        # the fps from the videos: the calibration's camera names are checked before one is opened
        from mocap.cameras.calibration_io import load_calibration
        from mocap.data.openpose import _find_calibration

        root = Path(args.recording)
        load_calibration(root / args.calibration if args.calibration else _find_calibration(root))
    fps = args.fps if args.fps is not None else videos_fps(Path(args.recording))
    out = convert_pose2sim(args.recording, args.out, person=args.person, overwrite=args.overwrite,
                           layout=args.layout, fps=fps, frames=args.frames,
                           min_confidence=args.min_confidence, calibration=args.calibration,
                           keypoints=args.keypoints, gt=args.gt)
    from mocap.data.sequence_io import load_sequence

    seq = load_sequence(out, images=False)
    det = seq.detections
    people = int(det.person.max()) + 1 if det is not None and det.person is not None and len(det) else 0
    print(f"wrote {out}: {seq.num_frames} frames, {seq.num_views} views, {len(det) if det else 0} keypoints "
          f"({seq.meta.get('layout')}, person={seq.meta.get('person')}, up to {people} people per view)"
          + (", ground truth" if seq.gt is not None else ""))
    return 0
