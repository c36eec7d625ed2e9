"""Real-data loader for calibration + OpenPose JSON folders (mocap/data/openpose.py)."""

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from mocap.body.skeletons import LAYOUTS
from mocap.cameras import project, ring_rig, write_pose2sim_calibration
from mocap.data.openpose import OpenPoseFormatError, load_openpose_sequence
from mocap.eval.keypoint_metrics import detection_residuals, triangulate_detections

# the shared data folder: $MOCAP_SHARED_DATA, else ../shared/data next to the repository
SHARED = Path(os.environ.get("MOCAP_SHARED_DATA")
              or Path(__file__).resolve().parents[2].parent / "shared" / "data")
DEMO = SHARED / "pose2sim-demo"
needs_demo = pytest.mark.skipif(not (DEMO / "Calib.toml").is_file(), reason="Pose2Sim demo data not present")


def write_project(root: Path, frames: int = 3, bystander: bool = True) -> tuple:
    """A Pose2Sim-style folder: 3 cameras, BODY_25B keypoints of a subject at the centre and
    of a bystander off-centre, seen by two of the cameras, projected exactly (the subject
    listed second); returns (rig, subject points (25, 3))."""
    rig = ring_rig(3, 3.0, 1.5, 640, 480, fov_deg=50, look_at=(0, 0, 1.0),
                   names=["cam_01", "cam_02", "cam_03"])
    write_pose2sim_calibration(rig, root / "Calib.toml")
    rng = np.random.default_rng(0)
    subject = rng.uniform([-0.3, -0.2, 0.1], [0.3, 0.2, 1.7], (25, 3))
    other = subject + [1.2, 0.3, 0.0]
    for c, name in enumerate(["cam01", "cam02", "cam03"]):
        folder = root / "pose" / f"{name}_json"
        folder.mkdir(parents=True)
        for f in range(frames):
            people = []
            for pts in [other, subject] if bystander and c < 2 else [subject]:
                px = project(rig[c], pts + [0.01 * f, 0, 0])
                kp = np.concatenate([px, np.full((25, 1), 0.8)], axis=1)
                kp[3] = 0.0                                                    # l_ear not found
                people.append({"person_id": [-1], "pose_keypoints_2d": kp.ravel().tolist()})
            (folder / f"{name}.{f:04d}.json").write_text(json.dumps({"version": 1.3, "people": people}))
    return rig, subject


def test_synthetic_project_is_read_with_the_subject_and_landmark_labels(tmp_path):
    rig, subject = write_project(tmp_path)
    seq = load_openpose_sequence(tmp_path, fps=60)
    assert seq.rig.names == ("cam_01", "cam_02", "cam_03") and seq.num_frames == 3 and seq.gt is None
    assert seq.detections.labels == LAYOUTS["BODY_25B"]
    det = seq.detections.select(0)
    assert len(det) == 3 * 24 and "l_ear" not in {det.labels[i] for i in det.label}
    X = triangulate_detections(seq.rig, seq.detections, det.labels, 1)[0]
    ok = np.isfinite(X[:, 0])
    np.testing.assert_allclose(X[ok], subject[ok], atol=1e-6)            # the subject, not the bystander
    everyone = load_openpose_sequence(tmp_path, person="all")
    assert len(everyone.detections) == len(seq.detections) * 5 // 3


def test_malformed_json_is_rejected_naming_the_file(tmp_path):
    write_project(tmp_path, frames=2)
    bad = tmp_path / "pose" / "cam02_json" / "cam02.0001.json"
    bad.write_text('{"people": [{"pose_keypoints_2d": [1, 2, 3')
    with pytest.raises(OpenPoseFormatError, match=r"cam02\.0001\.json.*not valid JSON"):
        load_openpose_sequence(tmp_path)
    bad.write_text(json.dumps({"people": [{"pose_keypoints_2d": [1.0, 2.0, 0.5] * 18}]}))
    with pytest.raises(OpenPoseFormatError, match="54 values.*expected 75"):
        load_openpose_sequence(tmp_path)
    bad.write_text(json.dumps({"persons": []}))
    with pytest.raises(OpenPoseFormatError, match="'people' list"):
        load_openpose_sequence(tmp_path)


def test_camera_names_that_do_not_match_the_folders_are_rejected(tmp_path):
    write_project(tmp_path, frames=1)
    shutil.move(tmp_path / "pose" / "cam03_json", tmp_path / "pose" / "side_json")
    match = r"do not match the keypoint folders.*no folder for \['cam_03'\]"
    with pytest.raises(OpenPoseFormatError, match=match):
        load_openpose_sequence(tmp_path)


@needs_demo
def test_the_pose2sim_demo_loads_and_its_subject_triangulates_consistently():
    seq = load_openpose_sequence(DEMO, fps=60)
    assert seq.rig.names == ("cam_01", "cam_02", "cam_03", "cam_04") and seq.num_frames == 100
    assert tuple(seq.rig.sizes[0]) == (1088, 1920)
    det = seq.detections
    assert 20 <= np.bincount(det.frame * 4 + det.view).mean() <= 25          # one person per view
    X = triangulate_detections(seq.rig, det, det.labels, seq.num_frames)
    err, view = detection_residuals(seq.rig, X, det.labels, det)
    assert 5.0 < np.median(err) < 20.0                                       # README: ~12 px
    height = np.nanmax(X[:, :, 2], axis=1) - np.nanmin(X[:, :, 2], axis=1)
    assert 1.4 < np.nanmedian(height) < 2.0                                  # an adult, in metres


def body25_from_body25b(src: Path, dst: Path, frames: int = 10) -> None:
    """The demo's BODY_25B keypoints re-indexed into OpenPose BODY_25 (neck: mid-shoulders,
    mid-hip: mid-hips, confidence the lower of the two), first ``frames`` frames."""
    b25b = {n: i for i, n in enumerate(LAYOUTS["BODY_25B"])}
    shutil.copy(src / "Calib.toml", dst / "Calib.toml")
    for folder in sorted((src / "pose").iterdir()):
        out = dst / "pose" / folder.name
        out.mkdir(parents=True)
        for f in sorted(folder.glob("*.json"))[:frames]:
            people = []
            for p in json.loads(f.read_text())["people"]:
                kp = np.asarray(p["pose_keypoints_2d"]).reshape(25, 3)
                new = np.zeros((25, 3))
                for i, name in enumerate(LAYOUTS["BODY_25"]):
                    pair = {"neck_base": ("l_shoulder", "r_shoulder"), "pelvis": ("l_hip", "r_hip")}.get(name)
                    if pair:
                        a, b = kp[b25b[pair[0]]], kp[b25b[pair[1]]]
                        new[i] = [*(a[:2] + b[:2]) / 2, min(a[2], b[2])]
                    else:
                        new[i] = kp[b25b[name]]
                people.append({"pose_keypoints_2d": new.ravel().tolist()})
            (out / f.name).write_text(json.dumps({"people": people}))


@needs_demo
def test_a_body25_recording_read_as_body25b_is_detected(tmp_path):
    body25_from_body25b(DEMO, tmp_path)
    with pytest.raises(OpenPoseFormatError, match="do not look like BODY_25B.*layout=BODY_25"):
        load_openpose_sequence(tmp_path, layout="BODY_25B")
    seq = load_openpose_sequence(tmp_path, layout="auto")
    assert seq.meta["layout"] == "BODY_25" and seq.detections.labels == LAYOUTS["BODY_25"]
    right = load_openpose_sequence(DEMO, layout="auto", frames=10)      # the original is BODY_25B
    assert right.meta["layout"] == "BODY_25B"
    # the same subject: its left knee triangulates to the same place from both files
    a = triangulate_detections(seq.rig, seq.detections, seq.detections.labels, 1)[0]
    b = triangulate_detections(right.rig, right.detections, right.detections.labels, 1)[0]
    knee_a, knee_b = a[seq.detections.labels.index("l_knee")], b[right.detections.labels.index("l_knee")]
    np.testing.assert_allclose(knee_a, knee_b, atol=1e-6)


def test_every_layout_has_its_documented_size_and_known_landmarks():
    from mocap.body.catalogue import CATALOGUE

    sizes = {"BODY_25B": 25, "BODY_25": 25, "COCO": 18, "COCO_17": 17, "HALPE_26": 26, "MEDIAPIPE_33": 33}
    assert {k: len(v) for k, v in LAYOUTS.items()} == sizes
    for name, labels in LAYOUTS.items():
        used = [n for n in labels if n is not None]
        assert len(set(used)) == len(used), name
        assert set(used) <= set(CATALOGUE), (name, set(used) - set(CATALOGUE))


def test_coco17_files_are_detected_and_a_wrong_count_is_named(tmp_path):
    rig, subject = write_project(tmp_path, frames=1, bystander=False)
    for f in (tmp_path / "pose").rglob("*.json"):                   # keep the COCO_17 part of BODY_25B
        d = json.loads(f.read_text())
        for p in d["people"]:
            p["pose_keypoints_2d"] = p["pose_keypoints_2d"][:17 * 3]
        f.write_text(json.dumps(d))
    seq = load_openpose_sequence(tmp_path, layout="auto")
    assert seq.meta["layout"] == "COCO_17" and len(seq.detections.select(0)) == 3 * 16
    with pytest.raises(OpenPoseFormatError, match=r"layout BODY_25B has 25 keypoints, the files have 17 "
                                                  r"\(layouts with 17: \['COCO_17'\]"):
        load_openpose_sequence(tmp_path, layout="BODY_25B")


@pytest.mark.parametrize("value", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_keypoints_are_rejected_naming_file_and_frame(tmp_path, value):
    write_project(tmp_path, frames=3)
    bad = tmp_path / "pose" / "cam03_json" / "cam03.0002.json"
    s = bad.read_text()
    i = s.index('"pose_keypoints_2d": [') + len('"pose_keypoints_2d": [')
    j = s.index(",", i)
    bad.write_text(s[:i] + value + s[j:])                       # the first x of the file
    with pytest.raises(OpenPoseFormatError, match=r"cam03\.0002\.json: frame 2, person 0: non-finite"):
        load_openpose_sequence(tmp_path)


def test_a_missing_camera_folder_is_named(tmp_path):
    write_project(tmp_path, frames=1)
    shutil.rmtree(tmp_path / "pose" / "cam02_json")
    with pytest.raises(OpenPoseFormatError, match=r"no folder for \['cam_02'\]"):
        load_openpose_sequence(tmp_path)


def test_frames_missing_in_one_view_are_named(tmp_path):
    write_project(tmp_path, frames=4)
    (tmp_path / "pose" / "cam01_json" / "cam01.0002.json").unlink()
    with pytest.raises(OpenPoseFormatError, match=r"cam01_json: 1 frame\(s\) present in other views are "
                                                  r"missing here: 2"):
        load_openpose_sequence(tmp_path)
