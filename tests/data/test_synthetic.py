import json
import shutil

import numpy as np
import pytest

from mocap.body.landmarks import LandmarkSet
from mocap.cameras import project, ring_rig
from mocap.data.corruption import DetectionModel, SilhouetteNoise
from mocap.data.generate import make_synthetic
from mocap.data.sequence_io import SequenceFormatError, load_sequence, write_sequence


@pytest.fixture(scope="module")
def rig():
    return ring_rig(4, 3.5, 1.5, 240, 180, fov_deg=50)


@pytest.fixture(scope="module")
def seq(body, rig):
    return make_synthetic(body, rig, motion="walk", frames=6, fps=25, seed=1,
                          detections={"enabled": True, "detection_rate": 0.9,
                                      "false_positive_rate": 0.1, "noise_px": 1.0})


def test_ground_truth_joints_project_inside_their_silhouettes(seq):
    px = project(seq.rig, seq.gt.joints)                       # (F, C, J, 2)
    F, C, J, _ = px.shape
    inside = np.zeros((F, C, J), bool)
    for f in range(F):
        for c in range(C):
            u, v = np.round(px[f, c]).astype(int).T
            ok = (u >= 0) & (u < 240) & (v >= 0) & (v < 180)
            inside[f, c, ok] = seq.masks[f, c, v[ok], u[ok]]
    assert inside.all()


def test_landmarks_follow_the_body(body, seq):
    lm = LandmarkSet(body)
    names = list(lm.names)
    for j in ("pelvis", "l_knee", "r_wrist"):
        np.testing.assert_allclose(seq.gt.markers[:, names.index(j)],
                                   seq.gt.joints[:, body.joint_index(j)], atol=1e-5)
    head_top = seq.gt.markers[:, names.index("head_top"), 2]
    assert np.all(head_top > seq.gt.joints[:, body.joint_index("head"), 2] + 0.1)


def test_detection_model_rates_and_noise():
    rng = np.random.default_rng(0)
    px = rng.uniform(50, 150, size=(20, 2))
    vis = np.ones(20, bool)
    vis[:5] = False
    model = DetectionModel(detection_rate=0.8, false_positive_rate=0.0, noise_px=2.0)
    hits, errs = 0, []
    for _ in range(300):
        lab, xy, _ = model.sample(px, vis, 400, 400, rng)
        assert np.all(lab >= 5)                                 # invisible markers never detected
        hits += len(lab)
        errs.append(xy - px[lab])
    assert hits / (300 * 15) == pytest.approx(0.8, abs=0.03)
    assert np.concatenate(errs).std() == pytest.approx(2.0, rel=0.1)
    fp = DetectionModel(detection_rate=0.0, false_positive_rate=0.5)
    n = [len(fp.sample(px, vis, 400, 400, rng)[0]) for _ in range(300)]
    assert np.mean(n) == pytest.approx(10.0, rel=0.15)        # Poisson(0.5 x 20)


def test_silhouette_noise_changes_the_outline(seq):
    m = seq.masks[0, 0]
    rng = np.random.default_rng(0)
    grown = SilhouetteNoise(dilate_px=3).apply(m, rng)
    assert grown[m].all()
    noisy = SilhouetteNoise(blobs=3, holes=3, missing_part=1.0).apply(m, rng)
    assert (noisy != m).sum() > 50


def test_write_load_round_trip_is_identical(seq, tmp_path):
    out = write_sequence(seq, tmp_path / "seq")
    back = load_sequence(out)
    assert back.name == seq.name and back.fps == seq.fps and back.rig.allclose(seq.rig)
    np.testing.assert_array_equal(back.masks, seq.masks)
    for f in ("alpha", "chi", "joints", "markers"):
        np.testing.assert_array_equal(getattr(back.gt, f), getattr(seq.gt, f))
    assert back.gt.marker_names == seq.gt.marker_names
    d0, d1 = seq.detections, back.detections
    for f in ("frame", "view", "label", "xy", "confidence"):
        np.testing.assert_array_equal(getattr(d1, f), getattr(d0, f))
    assert not list(tmp_path.glob(".seq.tmp-*"))


def test_interrupted_write_leaves_nothing(seq, tmp_path, monkeypatch):
    import mocap.data.sequence_io as sio

    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sio.np, "savez_compressed", boom)
    with pytest.raises(KeyboardInterrupt):
        write_sequence(seq, tmp_path / "seq")
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def written(seq, tmp_path):
    return write_sequence(seq, tmp_path / "seq")


def test_missing_frame_file_is_named(written):
    (written / "masks" / "cam_01" / "000003.png").unlink()
    with pytest.raises(SequenceFormatError, match=r"cam_01/000003.png: missing frame file"):
        load_sequence(written)


def test_mask_of_the_wrong_size_is_named(written):
    import cv2

    cv2.imwrite(str(written / "masks" / "cam_00" / "000002.png"), np.zeros((10, 10), np.uint8))
    with pytest.raises(SequenceFormatError, match=r"cam_00/000002.png: image is 10x10.*'image_size'"):
        load_sequence(written)


def test_missing_field_and_camera_mismatch_are_named(written, tmp_path):
    info = json.loads((written / "sequence.json").read_text())
    broken = tmp_path / "broken"
    shutil.copytree(written, broken)
    del info["frames"]
    (broken / "sequence.json").write_text(json.dumps(info))
    with pytest.raises(SequenceFormatError, match=r"sequence.json: missing field 'frames'"):
        load_sequence(broken)
    info = json.loads((written / "sequence.json").read_text())
    info["views"] = ["a", "b", "c", "d"]
    (broken / "sequence.json").write_text(json.dumps(info))
    with pytest.raises(SequenceFormatError, match=r"calibration.json: cameras .* do not match"):
        load_sequence(broken)
