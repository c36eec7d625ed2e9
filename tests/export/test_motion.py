"""motion.npz: what a run keeps of its motion, and what its recording shows."""

import numpy as np
import pytest

from mocap.export import motion as motion_mod
from mocap.export.motion import MotionFileError, load_motion, motion_arrays, write_motion
from mocap.recording.reader import latest_at
from mocap.trackers.base import Estimate


def test_run_motion_matches_its_pose_and_recording(short_run, body):
    m = load_motion(short_run)
    assert m.num_frames == 4 and m.fps == 25 and m.info["tracker"] == "apf_prior"
    assert m.joint_names == body.joint_names and m.chi.shape == (4, body.num_dofs)
    out = body.shaped(m.alpha[0]).pose(m.chi)
    np.testing.assert_allclose(m.joints, out.joints, atol=1e-6)
    np.testing.assert_allclose(m.timestamps, np.arange(4) / 25)
    assert m.per_frame["initial"].tolist() == [True, False, False, False]
    assert np.isnan(m.per_frame["energy"][0]) and np.isfinite(m.per_frame["energy"][1:]).all()
    # what the viewer shows at frame f is this frame's posed mesh (not static zeros)
    for f in (1, 3):
        shown = latest_at(short_run / "recording.rrd", "world/body/estimate", "Mesh3D:vertex_positions", f)
        np.testing.assert_allclose(shown, out.vertices[f], atol=1e-5)


def _estimates(body, F=3, rng=None):
    rng = rng or np.random.default_rng(0)
    chis = 0.1 * rng.standard_normal((F, body.num_dofs))
    alpha = np.zeros(body.num_shape)
    diags = [{"initial": True}] + [
        {"energy": 1.5 + f, "energy_terms": {"silhouette": 1.0, "prior": 0.5 + f}, "apf_called": f % 2,
         "misaligned_limbs": ["l_knee"] if f == 2 else [], "limb_errors": {"l_knee": 0.1 * f},
         "unexplained": {"l_hip": 0.01 * f}, "unexplained_limit": {"l_hip": 0.005 + f},
         "energy_evaluations": 10} for f in range(1, F)]
    return [Estimate(c, alpha, d) for c, d in zip(chis, diags, strict=True)]


def test_motion_round_trips_with_decisions(tmp_path, body):
    ests = _estimates(body)
    path = write_motion(tmp_path / "motion.npz", motion_arrays(body, ests, [0, 0.1, 0.2], 30.0,
                                                               info={"seed": 3}, vertices=True))
    m = load_motion(path)
    np.testing.assert_array_equal(m.chi, np.stack([e.chi for e in ests]))
    pf = m.per_frame
    assert pf["apf_called"].tolist() == [-1, 1, 0]
    assert pf["misaligned"][:, list(pf["limb_names"]).index("l_knee")].tolist() == [False, False, True]
    assert list(pf["energy_term_names"]) == ["silhouette", "prior"]
    assert list(pf["chain_names"]) == ["l_hip"]
    np.testing.assert_array_equal(pf["unexplained"][:, 0], [np.nan, 0.01, 0.02])
    np.testing.assert_array_equal(pf["unexplained_limit"][:, 0], [np.nan, 1.005, 2.005])
    np.testing.assert_allclose(pf["energy_terms"][2], [1.0, 2.5])
    assert m.info["seed"] == 3 and len(m.info["model_hash"]) == 12
    assert m.vertices.shape == (3, body.num_vertices, 3) and m.faces.shape == body.faces.shape
    with pytest.raises(AttributeError):
        m.fps = 1.0                                         # frozen


def test_interrupted_write_leaves_no_motion_file(tmp_path, body, monkeypatch):
    arrays = motion_arrays(body, _estimates(body), [0, 0, 0], 25.0)

    def dies_midway(fh, **kw):
        fh.write(b"PK\x03\x04 half a zip")
        raise KeyboardInterrupt

    monkeypatch.setattr(motion_mod.np, "savez_compressed", dies_midway)
    with pytest.raises(KeyboardInterrupt):
        write_motion(tmp_path / "motion.npz", arrays)
    assert list(tmp_path.iterdir()) == []
    # a truncated file (what a non-atomic writer would leave) is refused with a clear error
    (tmp_path / "motion.npz").write_bytes(b"PK\x03\x04 half a zip")
    with pytest.raises(MotionFileError, match="not a readable"):
        load_motion(tmp_path)
    with pytest.raises(MotionFileError, match="not found"):
        load_motion(tmp_path / "nothing")


def test_marker_tracker_landmarks_are_kept_and_exported(tmp_path, body):
    from mocap.export.trc import trc_text

    ests = _estimates(body)
    pts = np.arange(6, dtype=float).reshape(2, 3)
    ests = [ests[0]] + [Estimate(e.chi, e.alpha, {**e.diagnostics, "landmarks": pts + f,
                                                   "landmark_names": ["LHeel", "RHeel"]})
                        for f, e in enumerate(ests[1:], start=1)]
    m = load_motion(write_motion(tmp_path / "motion.npz", motion_arrays(body, ests, [0, 0, 0], 25.0)))
    tl = m.per_frame["tracker_landmarks"]
    assert list(m.per_frame["tracker_landmark_names"]) == ["LHeel", "RHeel"]
    assert np.isnan(tl[0]).all() and np.array_equal(tl[2], pts + 2)
    rows = trc_text(m, which="tracker").split("\n")
    assert rows[3].startswith("Frame#\tTime\tLHeel\t\t\tRHeel")
    assert rows[6].split("\t")[2:] == [""] * 6                        # frame 0: not reported
    # OpenSim axes (y, z, x) in mm: landmark LHeel at frame 1 = (1, 2, 3) m -> (2000, 3000, 1000)
    assert [float(v) for v in rows[7].split("\t")[2:5]] == [2000.0, 3000.0, 1000.0]


def test_joint_offsets_round_trip_and_an_old_file_reads_zeros(tmp_path, body):
    """A run whose estimates carry rest-joint corrections keeps them per frame (``joint_offsets``)
    and its joints are those of the corrected body; a file without the field (written before it
    existed) reads as zeros, and one of the wrong shape is refused naming the field."""
    ests = _estimates(body)
    d = np.random.default_rng(5).normal(scale=0.02, size=(body.num_joints, 3))
    ests = [ests[0]] + [Estimate(e.chi, e.alpha, e.diagnostics, joint_offsets=d) for e in ests[1:]]
    arrays = motion_arrays(body, ests, [0, 0, 0], 25.0)
    m = load_motion(write_motion(tmp_path / "motion.npz", arrays))
    np.testing.assert_array_equal(m.joint_offsets, [np.zeros_like(d), d, d])
    np.testing.assert_array_equal(m.joints[1:], body.shaped(ests[1].alpha, d).pose(m.chi[1:]).joints)
    np.testing.assert_array_equal(m.joints[0], body.shaped(ests[0].alpha).pose(m.chi[0]).joints[0])
    old = {k: v for k, v in arrays.items() if k != "joint_offsets"}
    m_old = load_motion(write_motion(tmp_path / "old.npz", old))
    assert m_old.joint_offsets.shape == (3, body.num_joints, 3) and not m_old.joint_offsets.any()
    bad = {**arrays, "joint_offsets": np.zeros((2, body.num_joints, 3))}
    with pytest.raises(MotionFileError, match=r"field 'joint_offsets' has shape \(2, 19, 3\)"):
        load_motion(write_motion(tmp_path / "bad.npz", bad))
