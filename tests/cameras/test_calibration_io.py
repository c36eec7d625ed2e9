"""Calibration files: exact round trips in every format, the real Pose2Sim demo calibration,
and errors that name the file, the camera and the field."""

from __future__ import annotations

import itertools
import json
import tomllib
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from mocap.cameras import (
    CalibrationError,
    Rig,
    load_calibration,
    project,
    read_opencv_calibration,
    read_pose2sim_calibration,
    rig_to_dict,
    save_calibration,
    triangulate,
    write_opencv_calibration,
    write_pose2sim_calibration,
)

from .helpers import random_rig

DEMO_CALIB = (Path(__file__).resolve().parents[2].parent / "shared" / "data" / "pose2sim-demo"
              / "Calib.toml")


@pytest.fixture
def demo_calib() -> Path:
    if not DEMO_CALIB.is_file():
        pytest.skip(f"Pose2Sim demo calibration not found at {DEMO_CALIB} (shared data folder "
                    "absent in this checkout)")
    return DEMO_CALIB


def distorted_rig() -> Rig:
    """A rig whose cameras have k3 != 0 and one with a skewed K."""
    rig = random_rig(21, num_cameras=3)
    K = rig[1].K.copy()
    K[0, 1] = 0.7
    return Rig((rig[0], rig[1].replace(K=K), rig[2]))


# --- round trips ---------------------------------------------------------------------------


@pytest.mark.parametrize("filename", ["rig.json", "rig.yaml", "rig.yml"])
def test_mocap_format_round_trip_is_exact(tmp_path, filename):
    rig = distorted_rig()
    path = tmp_path / filename
    save_calibration(rig, path)
    assert load_calibration(path) == rig


@pytest.mark.parametrize("filename", ["rig.yaml", "rig.xml"])
def test_opencv_filestorage_round_trip_is_exact(tmp_path, filename):
    rig = distorted_rig()
    path = tmp_path / filename
    save_calibration(rig, path, format="opencv")
    if filename.endswith(".yaml"):
        text = path.read_text()
        assert text.startswith("%YAML") and "!!opencv-matrix" in text
    assert load_calibration(path) == rig  # dispatch by content for .yaml
    assert read_opencv_calibration(path) == rig


def test_opencv_filestorage_layout_is_one_map_per_camera(tmp_path):
    rig = distorted_rig()
    path = tmp_path / "rig.yaml"
    write_opencv_calibration(rig, path)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    node = fs.getNode("cameras")
    assert node.size() == 3
    cam = node.at(1)
    assert cam.getNode("name").string() == "cam_01"
    assert np.array_equal(cam.getNode("K").mat(), rig[1].K)
    assert cam.getNode("t").mat().shape == (3, 1) and cam.getNode("dist").mat().shape == (1, 5)
    assert int(cam.getNode("width").real()) == rig[1].width
    fs.release()


def test_hand_written_opencv_1_0_yaml_with_plain_sequences_loads(tmp_path):
    path = tmp_path / "calib.yml"
    path.write_text(
        "%YAML:1.0\n---\ncameras:\n"
        "  - name: left\n    width: 640\n    height: 480\n"
        "    K: [[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]]\n"
        "    dist: [-0.1, 0.01, 0.0, 0.0]\n"
        "    R: !!opencv-matrix\n      rows: 3\n      cols: 3\n      dt: d\n"
        "      data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n"
        "    t: [0.0, 0.0, 3.0]\n")
    (cam,) = load_calibration(path)
    assert cam.name == "left" and cam.size == (640, 480)
    assert np.array_equal(cam.dist, [-0.1, 0.01, 0.0, 0.0, 0.0])
    assert np.array_equal(cam.center, [0.0, 0.0, -3.0])


@pytest.mark.parametrize("k3", [0.0, 0.02])
def test_pose2sim_toml_round_trip_is_exact_to_float_precision(tmp_path, k3):
    rig = distorted_rig()
    rig = Rig(tuple(c.replace(dist=np.r_[c.dist[:4], k3]) for c in rig))
    path = tmp_path / "Calib.toml"
    save_calibration(rig, path)
    data = tomllib.loads(path.read_text())
    assert len(data["cam_00"]["distortions"]) == (4 if k3 == 0 else 5)
    assert data["metadata"] == {"adjusted": False, "error": 0.0}
    back = load_calibration(path)
    assert back.names == rig.names
    assert back.allclose(rig, rtol=1e-13, atol=1e-13)
    assert all(np.array_equal(a.K, b.K) and np.array_equal(a.t, b.t)
               for a, b in zip(back, rig, strict=True))


def test_pose2sim_writer_quotes_camera_names_that_are_not_bare_keys(tmp_path):
    rig = random_rig(2, num_cameras=2)
    # (quotes are not allowed in a camera name since names become file names: issue 36)
    rig = Rig((rig[0].replace(name="left cam"), rig[1].replace(name="cam.ü (2)")))
    path = tmp_path / "Calib.toml"
    write_pose2sim_calibration(rig, path, metadata={})
    assert read_pose2sim_calibration(path).names == ("left cam", "cam.ü (2)")


# --- the real Pose2Sim demo calibration -----------------------------------------------------


def test_pose2sim_demo_calibration_loads_into_four_valid_cameras(demo_calib):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rig = load_calibration(demo_calib)
    assert rig.names == ("cam_01", "cam_02", "cam_03", "cam_04")
    assert np.all(rig.sizes == [1088, 1920])  # portrait videos, size is [width, height]
    for cam in rig:
        assert np.allclose(cam.R @ cam.R.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(cam.R), 1.0)
        assert cam.K[0, 0] > 1000 and cam.K[1, 1] > 1000
    distances = np.linalg.norm(rig.centers, axis=1)
    assert np.all((distances > 2.5) & (distances < 5.0)), distances  # 3.06 .. 4.44 m
    assert np.all((rig.centers[:, 2] > 1.0) & (rig.centers[:, 2] < 3.0))  # z up, eye height
    # matches OpenCV's reading of the raw values
    raw = tomllib.loads(demo_calib.read_text())
    for cam in rig:
        table = raw[cam.name]
        assert np.allclose(cam.R, cv2.Rodrigues(np.array(table["rotation"]))[0], atol=1e-14)
        assert np.array_equal(cam.dist[:4], table["distortions"]) and cam.dist[4] == 0
    # a person standing at the world origin is in every image, upright
    pixels, depth = project(rig, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
                            return_depth=True)
    assert np.all(depth > 0)
    assert np.all((pixels >= 0) & (pixels < rig.sizes[:, None, :]))
    assert np.all(pixels[:, 1, 1] < pixels[:, 0, 1])


@pytest.mark.parametrize("filename", ["demo.json", "demo.yaml", "demo.toml", "demo.xml"])
def test_pose2sim_demo_survives_conversion_to_every_format(demo_calib, tmp_path, filename):
    rig = load_calibration(demo_calib)
    save_calibration(rig, tmp_path / filename)
    assert load_calibration(tmp_path / filename).allclose(rig, rtol=1e-13, atol=1e-13)


def test_expected_image_sizes_must_match(demo_calib):
    sizes = {"cam_01": (1080, 1920)}
    with pytest.raises(CalibrationError, match=r"camera 'cam_01': field 'size'.*1080x1920"):
        load_calibration(demo_calib, image_sizes=sizes)
    assert len(load_calibration(demo_calib, image_sizes=[(1088, 1920)] * 4)) == 4


# --- bad input -------------------------------------------------------------------------------


def _demo_like_toml(tmp_path: Path, **overrides: str) -> Path:
    """A two-camera Pose2Sim file; overrides replace (or with "" remove) lines of cam_01."""
    cam = {
        "name": '"cam_01"', "size": "[ 1088.0, 1920.0]",
        "matrix": "[ [ 1681.2, 0.0, 532.9], [ 0.0, 1681.0, 948.1], [ 0.0, 0.0, 1.0]]",
        "distortions": "[ -0.0007, 0.0021, 9.5e-06, 1.07e-05]",
        "rotation": "[ 1.688, 1.048, -0.419]", "translation": "[ 0.321, 0.956, 2.890]",
        "fisheye": "false",
    }
    lines = ["[cam_01]"]
    for key, value in cam.items():
        value = overrides.get(key, value)
        if value:
            lines.append(f"{key} = {value}")
    lines += ["", "[cam_02]"] + [f"{k} = {v}" for k, v in cam.items() if k != "name"]
    lines += ['name = "cam_02"', "", "[metadata]", "adjusted = false", "error = 0.0", ""]
    path = tmp_path / "Calib.toml"
    path.write_text("\n".join(lines))
    return path


def test_valid_hand_written_toml_loads(tmp_path):
    assert load_calibration(_demo_like_toml(tmp_path)).names == ("cam_01", "cam_02")


@pytest.mark.parametrize(
    ("overrides", "field", "reason"),
    [
        ({"matrix": ""}, "matrix", "missing"),
        ({"rotation": ""}, "rotation", "missing"),
        ({"size": ""}, "size", "missing"),
        ({"rotation": "[[1.0, 0.0, 0.0], [0.0, 1.1, 0.0], [0.0, 0.0, 1.0]]"}, "rotation",
         "orthonormal"),
        ({"rotation": "[1.0, 2.0]"}, "rotation", "Rodrigues"),
        ({"matrix": "[[1681.2, 0.0, 532.9], [0.0, 1681.0, 948.1]]"}, "matrix", "shape"),
        ({"matrix": "[[-1681.2, 0.0, 532.9], [0.0, 1681.0, 948.1], [0.0, 0.0, 1.0]]"},
         "matrix", "positive"),
        ({"size": "[ 272.0, 480.0]"}, "size", "principal point"),  # quarter-resolution size
        ({"size": "[ 1088.0, 1920.0, 3.0]"}, "size", "width, height"),
        ({"translation": "[ 0.321, 0.956]"}, "translation", "shape"),
        ({"fisheye": "true"}, "fisheye", "fisheye"),
    ],
)
def test_bad_pose2sim_file_raises_naming_file_camera_and_field(tmp_path, overrides, field,
                                                                 reason):
    path = _demo_like_toml(tmp_path, **overrides)
    with pytest.raises(CalibrationError, match=reason) as info:
        load_calibration(path)
    message = str(info.value)
    assert message.startswith(f"{path}: camera 'cam_01': field '{field}'"), message
    assert (info.value.path, info.value.camera, info.value.field) == (str(path), "cam_01", field)


def test_swapped_width_and_height_warn(tmp_path):
    path = _demo_like_toml(tmp_path, size="[ 1920.0, 1088.0]")
    with pytest.warns(UserWarning, match=r"camera 'cam_01'.*swapped"):
        load_calibration(path)


def test_missing_field_message_has_the_documented_form(tmp_path):
    path = _demo_like_toml(tmp_path, matrix="")
    with pytest.raises(CalibrationError) as info:
        load_calibration(path)
    assert str(info.value) == f"{path}: camera 'cam_01': field 'matrix' missing"
    assert isinstance(info.value, ValueError)


def _write_mocap(path: Path, mutate) -> Path:
    data = rig_to_dict(random_rig(5, num_cameras=2))
    mutate(data["cameras"][1])
    path.write_text(json.dumps(data) if path.suffix == ".json" else yaml.safe_dump(data))
    return path


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
@pytest.mark.parametrize(
    ("mutate", "field", "reason"),
    [
        (lambda c: c.pop("K"), "K", "missing"),
        (lambda c: c.pop("height"), "height", "missing"),
        (lambda c: c.__setitem__("R", (1.2 * np.eye(3)).tolist()), "R", "orthonormal"),
        (lambda c: c.__setitem__("R", [[1.0, 0.0], [0.0, 1.0]]), "R", "shape"),
        (lambda c: c.__setitem__("K", [[1.0, 0.0, 1.0], [0.0, 1.0]]), "K", "numeric"),
        (lambda c: c.__setitem__("width", 100), "width", "principal point"),
        (lambda c: c.__setitem__("height", 0), "height", "positive"),
    ],
)
def test_bad_mocap_file_raises_naming_file_camera_and_field(tmp_path, suffix, mutate, field,
                                                              reason):
    path = _write_mocap(tmp_path / f"rig{suffix}", mutate)
    with pytest.raises(CalibrationError, match=reason) as info:
        load_calibration(path)
    assert str(info.value).startswith(f"{path}: camera 'cam_01': field '{field}'")


def test_bad_opencv_file_raises_naming_file_camera_and_field(tmp_path):
    path = tmp_path / "rig.yaml"
    rig = random_rig(5, num_cameras=2)
    write_opencv_calibration(rig, path)
    text = path.read_text()
    broken = tmp_path / "broken.yaml"
    broken.write_text(text.replace("   R: !!opencv-matrix", "   Rot: !!opencv-matrix", 1))
    with pytest.raises(CalibrationError, match=r"camera 'cam_00': field 'R' missing"):
        load_calibration(broken)
    # replace the second camera's R data by a non-rotation matrix
    fs_text = text
    start = fs_text.rindex("R: !!opencv-matrix")
    data_start = fs_text.index("data: [", start)
    data_end = fs_text.index("]", data_start)
    fs_text = fs_text[:data_start] + "data: [ 2., 0., 0., 0., 1., 0., 0., 0., 1." + \
        fs_text[data_end:]
    path.write_text(fs_text)
    with pytest.raises(CalibrationError, match=r"camera 'cam_01': field 'R': not orthonormal"):
        load_calibration(path)


@pytest.mark.parametrize(
    ("filename", "content", "reason"),
    [
        ("rig.json", "{not json", "cannot parse"),
        ("rig.yaml", "cameras: [ {", "cannot parse"),
        ("Calib.toml", "[cam_01\nname = 1", "cannot parse TOML"),
        ("rig.yaml", "%YAML:1.0\n---\ncameras: [ {\n", "cannot parse OpenCV"),
        ("rig.json", "[1, 2]", "mapping"),
        ("rig.json", '{"cams": []}', "field 'cameras' missing"),
        ("rig.json", '{"cameras": []}', "no cameras"),
        ("rig.txt", "", "unknown calibration extension"),
    ],
)
def test_unreadable_files_raise_calibration_error_naming_the_file(tmp_path, filename, content,
                                                                  reason):
    path = tmp_path / filename
    path.write_text(content)
    with pytest.raises(CalibrationError, match=reason) as info:
        load_calibration(path)
    assert str(info.value).startswith(str(path))


@pytest.mark.parametrize("filename", ["missing.json", "missing.toml", "missing.xml"])
def test_missing_file_raises_calibration_error(tmp_path, filename):
    with pytest.raises(CalibrationError, match=r"cannot read file"):
        load_calibration(tmp_path / filename)


def test_duplicate_camera_names_are_rejected(tmp_path):
    data = rig_to_dict(random_rig(5, num_cameras=2))
    data["cameras"][1]["name"] = data["cameras"][0]["name"]
    path = tmp_path / "rig.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match=r"camera 'cam_00': field 'name': duplicate"):
        load_calibration(path)


def test_pose2sim_demo_keypoints_triangulate_consistently_with_its_calibration(demo_calib):
    """Real data: the subject's OpenPose keypoints of frame 0 in all 4 views, triangulated with
    the loaded calibration, reproject within the ~12 px the data's README reports and stand on
    a z-up floor (z from ~0 to ~1.7 m)."""
    pose_dir = demo_calib.parent / "pose"
    files = [sorted((pose_dir / f"cam{c:02d}_json").glob("*.json"))[:1] for c in range(1, 5)]
    if not all(files):
        pytest.skip(f"Pose2Sim demo keypoints not found under {pose_dir}")
    people = [[np.reshape(p["pose_keypoints_2d"], (-1, 3))
               for p in json.loads(f[0].read_text())["people"]] for f in files]
    rig = load_calibration(demo_calib)
    best = None
    for choice in itertools.product(*(range(len(p)) for p in people)):  # who is who per view
        keypoints = np.stack([people[c][i] for c, i in enumerate(choice)])
        valid = keypoints[..., 2] > 0.3
        X = triangulate(rig, keypoints[..., :2], valid, weights=keypoints[..., 2])
        error = np.linalg.norm(project(rig, X) - keypoints[..., :2], axis=-1)
        median = np.median(error[valid & np.isfinite(X[:, 0])])
        if best is None or median < best[0]:
            best = (median, X)
    median, X = best
    assert median < 15.0
    assert -0.1 < np.nanmin(X[:, 2]) < 0.2 and 1.4 < np.nanmax(X[:, 2]) < 2.0
