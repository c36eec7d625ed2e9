"""Extrinsics against known rigs: a board rendered through several cameras, points of known
coordinates, and a walking body's keypoints (bundle adjustment from noisy keypoints)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mocap.calibration.board_extrinsics import calibrate_board_extrinsics
from mocap.calibration.bundle import adjust_points
from mocap.calibration.compare import compare_rigs, poses_of, rig_from_poses, transform_rig, umeyama
from mocap.calibration.errors import CalibrationInputError
from mocap.calibration.known_points import calibrate_known_points, read_known_points
from mocap.calibration.people import calibrate_from_keypoints
from mocap.calibration.scale_floor import floor_frame, measured_length
from mocap.cameras import project
from tests.calibration.scenes import (
    BIG_BOARD,
    arc_rig,
    arc_views,
    walking_joints,
    walking_keypoints,
    walking_rig,
)


def _sizes(rig):
    return [tuple(int(v) for v in s) for s in rig.sizes]


def test_board_seen_by_several_cameras_gives_back_the_rig_in_metres():
    rig = arc_rig()
    views = arc_views()
    assert all(len(v) >= 4 for v in views)
    res = calibrate_board_extrinsics(rig.names, rig.K, rig.dist, BIG_BOARD, views)
    est = rig_from_poses(rig.names, rig.K, rig.dist, _sizes(rig), res.cams)
    cmp = compare_rigs(est, rig, similarity=False)        # metres from the squares: no scale freedom
    assert cmp.centre_error.max() < 0.01
    assert cmp.rotation_error.max() < 0.1
    # the reference camera is the world frame
    assert np.allclose(res.cams[0], 0)


def test_a_camera_sharing_no_board_frame_is_named():
    rig = arc_rig()
    views = [dict(v) for v in arc_views()]
    views[2] = {f"9{k}": d for k, d in views[2].items()}        # frames no other camera has
    with pytest.raises(CalibrationInputError, match="'c2'.*no overlap"):
        calibrate_board_extrinsics(rig.names, rig.K, rig.dist, BIG_BOARD, views)


def _known_points_file(tmp_path, rig, noise_px, fmt):
    rng = np.random.default_rng(5)
    X = rng.uniform([-1, -1, 0], [1, 1, 1.8], (10, 3))
    px = project(rig, X) + rng.normal(0, noise_px, (len(rig), 10, 2))
    names = [f"p{i}" for i in range(10)]
    if fmt == "json":
        data = {"points": {n: x.tolist() for n, x in zip(names, X, strict=True)},
                "cameras": {cam: {n: px[c, i].tolist() for i, n in enumerate(names)}
                            for c, cam in enumerate(rig.names)}}
        path = tmp_path / "points.json"
        path.write_text(json.dumps(data))
    else:
        rows = ["camera,point,x,y,z,u,v"] + [
            ",".join([cam, n, *(f"{v:.17g}" for v in (*X[i], *px[c, i]))])
            for c, cam in enumerate(rig.names) for i, n in enumerate(names)]
        path = tmp_path / "points.csv"
        path.write_text("\n".join(rows))
    return path


@pytest.mark.parametrize("fmt", ["json", "csv"])
def test_known_points_give_back_the_cameras(tmp_path, fmt):
    rig = arc_rig()
    known = read_known_points(_known_points_file(tmp_path, rig, 0.3, fmt))
    cams, residuals = calibrate_known_points(rig.names, rig.K, rig.dist, known)
    est = rig_from_poses(rig.names, rig.K, rig.dist, _sizes(rig), cams)
    assert np.linalg.norm(est.centers - rig.centers, axis=1).max() < 0.01
    assert all(np.abs(r).max() < 2.0 for r in residuals)


def test_known_points_too_few_for_a_camera_are_refused(tmp_path):
    rig = arc_rig()
    known = read_known_points(_known_points_file(tmp_path, rig, 0.0, "json"))
    X, uv, names = known["c1"]
    known["c1"] = (X[:3], uv[:3], names[:3])
    with pytest.raises(CalibrationInputError, match="'c1'.*3 known points"):
        calibrate_known_points(rig.names, rig.K, rig.dist, known)


def test_bundle_adjustment_from_perturbed_start_reaches_the_exact_rig():
    """Noise-free observations: from cameras and points perturbed by a few cm, the residuals
    go to zero and the cameras back to the truth (the first camera and one point held)."""
    rig = walking_rig()
    J, _ = walking_joints()
    X = J[::6].reshape(-1, 3)
    px = project(rig, X)                                        # (C, N, 2)
    rng = np.random.default_rng(2)
    truth = poses_of(rig)
    start = truth + np.concatenate([np.zeros((1, 6)), rng.normal(0, 0.01, (3, 6))])
    c_idx, p_idx = np.nonzero(np.ones(px.shape[:2], bool))
    fixed_pts = np.zeros(len(X), bool)
    fixed_pts[:3] = True                                        # scale and position held by 3 points
    res = adjust_points(start, X + np.where(fixed_pts[:, None], 0, rng.normal(0, 0.02, X.shape)), rig.K,
                        rig.dist, c_idx, p_idx, px[c_idx, p_idx], fixed_cams=np.eye(4, dtype=bool)[0],
                        fixed_points=fixed_pts)
    assert np.abs(res.residuals).max() < 1e-4
    assert np.abs(res.cams - truth).max() < 1e-5


def test_noisy_keypoints_of_a_walking_body_give_back_the_rig():
    """1 px noise on the joints of a 60-frame walk in four 1280x960 views: centres within 1 cm
    and orientations within 0.1 degree after a similarity; then the floor from the feet and the
    scale from a leg's length put it in metres, z up: centres within 1 cm without scale freedom."""
    rig = walking_rig()
    xy, conf = walking_keypoints(rig, 1.0)
    res = calibrate_from_keypoints(rig.names, rig.K, rig.dist, xy, conf)
    est = rig_from_poses(rig.names, rig.K, rig.dist, _sizes(rig), res.cams)
    cmp = compare_rigs(est, rig)
    assert cmp.centre_error.max() < 0.01
    assert cmp.rotation_error.max() < 0.1
    J, labels = walking_joints()
    pts = res.points.reshape(J.shape[0], J.shape[1], 3)
    R, t, how = floor_frame(pts, labels, est.R)
    assert how == "plane of the feet"
    true_len = np.median(np.linalg.norm(J[:, labels.index("l_hip")] - J[:, labels.index("l_ankle")], axis=-1))
    s = true_len / measured_length(pts @ R.T + t, labels, "l_hip", "l_ankle")
    metric = transform_rig(est, s, R, s * t)
    rigid = compare_rigs(metric, rig, similarity=False)
    assert rigid.centre_error.max() < 0.01
    # z up: the floor's normal within 2 degrees of the truth (measured 0.74: the skeleton's lowest
    # joints are the ankles, which rise and fall with the gait)
    R_align = umeyama(metric.centers, rig.centers, scale=False)[1]
    assert np.degrees(np.arccos((R_align @ [0, 0, 1.0])[2])) < 2.0


def test_checkerboard_read_from_the_other_end_in_some_views_is_resolved():
    """A checkerboard's corners may come in either order (a half turn); reversing them in some
    frames of two cameras changes nothing."""
    rig = arc_rig()
    views = [dict(v) for v in arc_views()]
    for c in (1, 3):
        for k in sorted(views[c])[::2]:
            corners, ids = views[c][k]
            views[c][k] = (corners[::-1].copy(), ids)
    res = calibrate_board_extrinsics(rig.names, rig.K, rig.dist, BIG_BOARD, views)
    est = rig_from_poses(rig.names, rig.K, rig.dist, _sizes(rig), res.cams)
    assert compare_rigs(est, rig, similarity=False).centre_error.max() < 0.01


def test_demo_person_places_the_cameras_as_qualisys_did():
    """The Pose2Sim demo's 100 frames of OpenPose keypoints, no board, Qualisys' intrinsics:
    centres within 5 cm and orientations within 1 degree of Qualisys' after a similarity
    (measured 1.0-3.4 cm, 0.39-0.87 degrees)."""
    import os
    from pathlib import Path

    from mocap.calibration.keypoints import read_view_keypoints
    from mocap.cameras import load_calibration
    from tests.conftest import SHARED

    demo = Path(os.environ.get("MOCAP_SHARED_DATA") or SHARED / "data") / "pose2sim-demo"
    if not (demo / "pose").is_dir():
        pytest.skip("../shared/data/pose2sim-demo is absent")
    ref = load_calibration(demo / "Calib.toml")
    kp = read_view_keypoints(demo / "pose", ref.names)
    res = calibrate_from_keypoints(ref.names, ref.K, ref.dist, *kp.flat())
    cmp = compare_rigs(rig_from_poses(ref.names, ref.K, ref.dist, _sizes(ref), res.cams), ref)
    assert cmp.centre_error.max() < 0.05, cmp.table()
    assert cmp.rotation_error.max() < 1.0, cmp.table()
