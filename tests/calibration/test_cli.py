"""``mocap calibrate`` end to end, and its refusals: one line naming the camera and what to do,
exit 2, nothing written."""

from __future__ import annotations

import json
import tomllib

import cv2
import numpy as np
import pytest

from mocap.calibration.synthetic import board_poses_facing, render_board
from mocap.cameras import Rig, load_calibration, save_calibration
from mocap_cli.main import main
from tests.calibration.scenes import BOARD, K, close_camera, openpose_folders, walking_keypoints, walking_rig

BOARD_ARG = "checkerboard:7x5:0.05"


def _renders(folder, camera_name, n, seed=0):
    cam = close_camera()
    poses = board_poses_facing(np.random.default_rng(seed), n, BOARD, np.array([0, 0, 1.0]),
                               np.array([0, -1.0, 0]), spread=0.15, tilt_deg=45)
    folder.mkdir(parents=True, exist_ok=True)
    for i, T in enumerate(poses):
        cv2.imwrite(str(folder / f"{camera_name}_{i:02d}.png"), render_board(cam, BOARD, T, supersample=2))


def _refused(capsys, argv, out, *patterns):
    assert main(["calibrate", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for p in patterns:
        assert p in err, err
    assert not out.exists() and not out.with_name(out.name + ".partial").exists()
    return err


def test_intrinsics_from_board_images_written_in_both_formats(tmp_path, capsys):
    _renders(tmp_path / "boards", "cama", 8)
    out = tmp_path / "calib"
    assert main(["calibrate", str(out), "--intrinsics", str(tmp_path / "boards"), "--board", BOARD_ARG]) == 0
    rig = load_calibration(out / "calibration.json")
    toml = tomllib.loads((out / "Calib.toml").read_text())          # an independent reader
    fx = toml["cama"]["matrix"][0][0]
    assert rig.names == ("cama",) and abs(fx / K[0, 0] - 1) < 0.005 and abs(rig.K[0, 0, 0] - fx) < 1e-9
    report = json.loads((out / "report.json").read_text())
    assert len(report["intrinsics"]["cama"]["views_px"]) == 8
    assert cv2.imread(str(out / "contact_sheet.png")) is not None


def test_board_found_in_no_image_of_a_camera_is_named(tmp_path, capsys):
    _renders(tmp_path / "boards", "cama", 5)
    for i in range(3):
        cv2.imwrite(str(tmp_path / "boards" / f"camb_{i:02d}.png"), np.full((480, 640), 128, np.uint8))
    _refused(capsys, ["--intrinsics", str(tmp_path / "boards"), "--board", BOARD_ARG], tmp_path / "out",
             "camera 'camb'", "not found in any of its 3 images", "--board")


def test_too_few_views_of_the_board_are_named(tmp_path, capsys):
    _renders(tmp_path / "boards", "cama", 5)
    _renders(tmp_path / "boards", "camb", 2, seed=1)
    _refused(capsys, ["--intrinsics", str(tmp_path / "boards"), "--board", BOARD_ARG], tmp_path / "out",
             "camera 'camb'", "found in 2 view(s), at least 4", "add images")


def test_a_video_that_does_not_open_is_named(tmp_path, capsys):
    _renders(tmp_path / "boards", "cama", 5)
    (tmp_path / "boards" / "camb.mp4").write_bytes(b"not a video at all" * 10)
    _refused(capsys, ["--intrinsics", str(tmp_path / "boards"), "--board", BOARD_ARG], tmp_path / "out",
             "camera 'camb'", "does not open")


def _video(path, frames):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    assert w.isOpened()
    for i in range(frames):
        w.write(np.full((48, 64, 3), i * 10 % 255, np.uint8))
    w.release()


def test_synchronised_videos_of_different_lengths_are_named(tmp_path, capsys):
    rig = Rig(tuple(close_camera().replace(name=n, width=64, height=48, K=np.array(
        [[60.0, 0, 31.5], [0, 60, 23.5], [0, 0, 1]])) for n in ("cama", "camb", "camc")))
    save_calibration(rig, tmp_path / "intr.json")
    (tmp_path / "views").mkdir()
    for n, f in (("cama", 10), ("camb", 10), ("camc", 13)):
        _video(tmp_path / "views" / f"{n}.avi", f)
    _refused(capsys, ["--intrinsics-from", str(tmp_path / "intr.json"), "--extrinsics", "board",
                      "--board-views", str(tmp_path / "views"), "--board", BOARD_ARG], tmp_path / "out",
             "camera 'camc'", "13 frames", "synchronised")


def test_cameras_without_overlap_are_named(tmp_path, capsys):
    rig = walking_rig()
    save_calibration(rig, tmp_path / "intr.json")
    xy, conf = walking_keypoints(rig, 0.5)
    conf = conf.reshape(len(rig), 60, -1)
    conf[3, 2:] = 0                     # the last camera sees the person in two frames only
    openpose_folders(tmp_path / "pose", rig, xy, conf.reshape(len(rig), -1), 60)
    _refused(capsys, ["--intrinsics-from", str(tmp_path / "intr.json"), "--extrinsics", "people",
                      "--keypoints", str(tmp_path / "pose")], tmp_path / "out",
             "camera 'cam_03'", "no overlap")


def test_existing_output_is_refused_before_any_work(tmp_path, capsys):
    (tmp_path / "out").mkdir()
    assert main(["calibrate", str(tmp_path / "out"), "--intrinsics", str(tmp_path / "nowhere")]) == 2
    assert "exists" in capsys.readouterr().err


@pytest.mark.parametrize("argv, words", [
    (["--extrinsics", "people"], "exactly one of --intrinsics"),
    (["--intrinsics-from", "x.json", "--extrinsics", "people"], "needs --keypoints"),
    (["--intrinsics-from", "x.json", "--board", "checkerboard:4x7"], "checkerboard:COLSxROWS:SQUARE_M"),
])
def test_bad_options_are_one_line(tmp_path, capsys, argv, words):
    _refused(capsys, argv, tmp_path / "out", words)


def test_people_in_the_scene_calibrate_a_rig_through_the_command(tmp_path, capsys):
    rig = walking_rig()
    save_calibration(rig, tmp_path / "intr.json")
    xy, conf = walking_keypoints(rig, 1.0)
    openpose_folders(tmp_path / "pose", rig, xy, conf, 60)
    out = tmp_path / "out"
    assert main(["calibrate", str(out), "--intrinsics-from", str(tmp_path / "intr.json"), "--extrinsics",
                 "people", "--keypoints", str(tmp_path / "pose"), "--layout", "BODY_25B",
                 "--compare", str(tmp_path / "intr.json")]) == 0
    report = json.loads((out / "report.json").read_text())
    assert max(report["compare"]["centre_error_m"].values()) < 0.01
    assert max(report["compare"]["rotation_error_deg"].values()) < 0.1
    assert load_calibration(out / "Calib.toml").names == rig.names


def test_intrinsics_from_a_video_of_the_board(tmp_path, capsys):
    cam = close_camera()
    poses = board_poses_facing(np.random.default_rng(0), 8, BOARD, np.array([0, 0, 1.0]),
                               np.array([0, -1.0, 0]), spread=0.15, tilt_deg=45)
    (tmp_path / "clips").mkdir()
    w = cv2.VideoWriter(str(tmp_path / "clips" / "cama.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, cam.size)
    for T in poses:
        img = cv2.cvtColor(render_board(cam, BOARD, T, supersample=2), cv2.COLOR_GRAY2BGR)
        for _ in range(3):                                            # each pose held 3 frames
            w.write(img)
    w.release()
    out = tmp_path / "calib"
    assert main(["calibrate", str(out), "--intrinsics", str(tmp_path / "clips"), "--board", BOARD_ARG,
                 "--max-video-frames", "8"]) == 0
    report = json.loads((out / "report.json").read_text())["intrinsics"]["cama"]
    assert len(report["views_px"]) + len(report["dropped_views_px"]) == 8
    assert abs(report["K"][0][0] / K[0, 0] - 1) < 0.005          # JPEG-compressed frames: same bound
