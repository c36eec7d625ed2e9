"""Does ``mocap calibrate`` give back a known rig, by every extrinsics method, with intrinsics it
estimates itself?

Method: a ring of four 1280x960 cameras with lens distortion (tests/calibration/scenes.py's
``walking_rig``). Per camera, 10 renders of a 7x5 checkerboard (80 mm squares) held 0.9 m in
front of it, tilted up to 45 degrees (intrinsics). Extrinsics (a) board: 4 board poses between
each pair of neighbouring cameras, rendered into every camera as synchronised frames; (b) known
points: 10 points in the volume with their projections (0.3 px noise) in a JSON file; (c) people:
the joints of a 60-frame walk (mocap.synthetic_sequence) projected with 1 px noise, written as
OpenPose JSON; the floor from the feet and the scale from a leg's length (--length). Every
image goes through the detector. ``mocap calibrate`` then runs per method with
--compare against the true rig (a similarity alignment for people, as their scale comes from a
body length; a printed table also gives the rigid error).

    OPENBLAS_NUM_THREADS=1 python -m experiments.calibration_synthetic --out outputs/calib_synth
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

import mocap as mc
from mocap.calibration.boards import Board
from mocap.calibration.compare import compare_rigs
from mocap.calibration.synthetic import (
    board_poses_facing,
    keypoints_through,
    openpose_keypoints,
    render_board,
    walking_rig,
)
from mocap.cameras import load_calibration, project, save_calibration
from mocap.data.openpose import LAYOUTS, write_openpose_folders
from mocap_cli.main import main as mocap

BOARD = Board("checkerboard", 7, 5, 0.08)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="outputs/calib_synth")
    a = p.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rig = walking_rig()
    rng = np.random.default_rng(0)
    save_calibration(rig, out / "truth.json")
    intr = out / "intrinsics"
    for cam in rig:
        fwd = cam.R[2]
        poses = board_poses_facing(rng, 10, BOARD, cam.center + 0.9 * fwd, -fwd, spread=0.12, tilt_deg=45)
        (intr / cam.name).mkdir(parents=True, exist_ok=True)
        for i, T in enumerate(poses):
            cv2.imwrite(str(intr / cam.name / f"{i:02d}.png"), render_board(cam, BOARD, T, supersample=2))
    views = out / "board_views"
    target = np.array([0, 0, 1.0])
    f = 0
    for c in range(len(rig)):
        mid = (rig.centers[c] + rig.centers[(c + 1) % len(rig)]) / 2
        facing = mid - target
        facing[2] = 0
        for T in board_poses_facing(rng, 4, BOARD, target, facing / np.linalg.norm(facing), spread=0.3,
                                    tilt_deg=20):
            for cam in rig:
                (views / cam.name).mkdir(parents=True, exist_ok=True)
                image = render_board(cam, BOARD, T, supersample=2)
                cv2.imwrite(str(views / cam.name / f"{f:03d}.png"), image)
            f += 1
    X = rng.uniform([-1.5, -1.5, 0], [1.5, 1.5, 1.8], (10, 3))
    px = project(rig, X) + rng.normal(0, 0.3, (len(rig), 10, 2))
    (out / "points.json").write_text(json.dumps({
        "points": {f"p{i}": x.tolist() for i, x in enumerate(X)},
        "cameras": {n: {f"p{i}": px[c, i].tolist() for i in range(10)} for c, n in enumerate(rig.names)}}))
    seq = mc.synthetic_sequence(mc.load_body("paper22"), cameras="ring4_small", motion="walk", frames=60,
                                masks=False)
    J, labels = np.asarray(seq.gt.joints), list(seq.gt.joint_names)
    xy, conf = keypoints_through(rig, J, 1.0)
    pose = out / "pose"
    if not pose.exists():         # the 19 joints in BODY_25B's first 19 slots
        write_openpose_folders(pose, rig.names, openpose_keypoints(xy, conf, len(J)))
    hip, ankle = labels.index("l_hip"), labels.index("l_ankle")
    leg = float(np.median(np.linalg.norm(J[:, hip] - J[:, ankle], axis=-1)))
    # the walking body's 19 joints were written in BODY_25B's first slots: name the leg by slot
    a_name, b_name = LAYOUTS["BODY_25B"][hip], LAYOUTS["BODY_25B"][ankle]
    base = ["--intrinsics", str(intr), "--board", "checkerboard:7x5:0.08", "--compare",
            str(out / "truth.json"), "--overwrite"]
    runs = {"board": ["--extrinsics", "board", "--board-views", str(views)],
            "points": ["--extrinsics", "points", "--points", str(out / "points.json")],
            "people": ["--extrinsics", "people", "--keypoints", str(pose), "--length", a_name, b_name,
                       f"{leg!r}"]}
    lines = []
    for method, extra in runs.items():
        assert mocap(["calibrate", str(out / method), *base, *extra]) == 0, method
        est = load_calibration(out / method / "calibration.json")
        sim = compare_rigs(est, rig)
        rigid = compare_rigs(est, rig, similarity=False)
        lines.append(f"{method:7s} focal max {100 * sim.focal_error.max():.3f} %  principal point max "
                     f"{sim.principal_point_error.max():.2f} px  centres max "
                     f"{100 * sim.centre_error.max():.2f} cm "
                     f"(rigid {100 * rigid.centre_error.max():.2f} cm)  orientation max "
                     f"{sim.rotation_error.max():.3f} deg  scale {sim.scale:.4f}")
    print("\n".join(lines))
    (out / "summary.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
