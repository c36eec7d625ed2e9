"""``mocap calibrate``: cameras' intrinsics from board images or videos, their extrinsics from a
board seen by several cameras, from points of known coordinates, or from the people in the
scene; writes OUT/calibration.json (ours), OUT/Calib.toml (Pose2Sim), OUT/report.json and
OUT/contact_sheet.png (observed points green, reprojections red).

    mocap calibrate OUT --intrinsics ../shared/data/pose2sim-demo/calibration/intrinsics \\
        --board checkerboard:4x7:0.06 --compare ../shared/data/pose2sim-demo/Calib.toml
    mocap calibrate OUT --intrinsics-from ../shared/data/pose2sim-demo/Calib.toml \\
        --extrinsics people --keypoints ../shared/data/pose2sim-demo/pose --height 1.7
    mocap calibrate OUT --intrinsics BOARD_CLIPS --extrinsics board --board-views SYNC_CLIPS
    mocap calibrate OUT --intrinsics-from calib.json --extrinsics points --points clicked.json

Inputs per camera (--intrinsics, --board-views): one sub-folder per camera, or files named
after the cameras (cam01.mp4, cam01_03.jpg); board views with the same frame number are the
same moment. --board COLSxROWS counts inner corners. Known points: JSON {"points": {name:
[x, y, z]}, "cameras": {camera: {name: [u, v]}}} or CSV camera,point,x,y,z,u,v (metres,
pixels). People: OpenPose JSON folders per camera (the largest person in each view is used);
scale from --height (top keypoint above the floor) or --length A B METRES; the floor from
the feet (z up). docs/calibration.md has the details and measured accuracy.
"""

from __future__ import annotations

import argparse

from mocap.calibration.methods import EXTRINSICS
from mocap_cli.errors import ArgumentParser


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap calibrate", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", help="the folder to write (new; --overwrite replaces one)")
    p.add_argument("--intrinsics", default=None, help="board images or videos per camera (a folder)")
    p.add_argument("--intrinsics-from", default=None, help="take the intrinsics (and camera names) from "
                                                           "this calibration file instead")
    p.add_argument("--board", default="checkerboard:4x7:0.06",
                   help="checkerboard:COLSxROWS:SQUARE_M or charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT] "
                        "(inner corners; default checkerboard:4x7:0.06)")
    p.add_argument("--extrinsics", default="none", choices=EXTRINSICS, help="how to place the cameras "
                                                                            "(default none: intrinsics only)")
    p.add_argument("--board-views", default=None,
                   help="(board) synchronised board images or videos per camera")
    p.add_argument("--points", default=None, help="(points) known 3D points and their pixels: .json or .csv")
    p.add_argument("--keypoints", default=None, help="(people) OpenPose JSON folders per camera")
    p.add_argument("--layout", default="BODY_25B", help="(people) keypoint layout (default BODY_25B)")
    p.add_argument("--height", type=float, default=None,
                   help="(people) the person's height, metres: the scale")
    p.add_argument("--length", nargs=3, default=None, metavar=("A", "B", "METRES"),
                   help="(people) the distance between keypoints A and B, metres: the scale")
    p.add_argument("--frames", type=int, default=None, help="(people) use the first N frames")
    p.add_argument("--max-video-frames", type=int, default=60, help="board frames taken from a video, "
                                                                    "evenly spread (default 60)")
    p.add_argument("--reference-camera", type=int, default=0,
                   help="(board) index of the camera that is the world frame (default 0)")
    p.add_argument("--compare", default=None, help="a reference calibration to compare with (printed, "
                                                   "and in report.json)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    a = p.parse_args(argv)
    length = None
    if a.length is not None:
        try:
            length = (a.length[0], a.length[1], float(a.length[2]))
        except ValueError:
            p.error(f"--length: METRES must be a number, got {a.length[2]!r}")
    from mocap.calibration.boards import parse_board  # (the numeric stack: after the arguments)
    from mocap.calibration.pipeline import CalibrateOptions, run_calibration, summary

    options = CalibrateOptions(out=a.out, intrinsics=a.intrinsics, intrinsics_from=a.intrinsics_from,
                               board=parse_board(a.board), extrinsics=a.extrinsics, board_views=a.board_views,
                               points=a.points, keypoints=a.keypoints, layout=a.layout, height=a.height,
                               length=length, frames=a.frames, max_video_frames=a.max_video_frames,
                               compare=a.compare, overwrite=a.overwrite, reference=a.reference_camera)
    report = run_calibration(options)
    print(summary(report))
    print(f"wrote {a.out}: calibration.json, Calib.toml, report.json"
          + (", contact_sheet.png" if report else ""))
    return 0
