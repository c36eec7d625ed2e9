"""``mocap import-motion``: a clip of our own body's motion, exported to BVH, comes back through
the command as a run's motion.npz with the same angles (< 1 degree) and points (< 1 mm); bad
input is one line and exit code 2, before anything is written."""

from __future__ import annotations

import numpy as np
import pytest

from mocap.export.motion import load_motion
from mocap_cli.main import main
from tests.clips.test_retarget import own_bvh, own_motion


@pytest.mark.slow
def test_import_motion_round_trip(body, tmp_path, capsys):
    chi, alpha = own_motion(body, "walk", frames=10, seed=2)
    clip = own_bvh(body, chi, alpha, tmp_path / "own.bvh")
    assert main(["import-motion", str(clip), "--out", str(tmp_path / "run")]) == 0
    line = capsys.readouterr().out
    assert "10 frames on paper22" in line and "-> " + str(tmp_path / "run" / "motion.npz") in line
    motion = load_motion(tmp_path / "run")
    assert motion.info["tracker"] == "retarget" and motion.num_frames == 10
    np.testing.assert_allclose(motion.chi[:, 6:], chi[:, 6:], atol=np.radians(1.0))
    truth = body.shaped(alpha).joints(chi).astype(np.float64)
    assert 1e3 * np.abs(motion.joints - truth).max() < 5.0   # rigid-torso joints: see test_retarget
    # --frames and --step select the file's frames 2, 5, 8
    assert main(["import-motion", str(clip), "--out", str(tmp_path / "sub.npz"),
                 "--frames", "2:", "--step", "3"]) == 0
    sub = load_motion(tmp_path / "sub.npz")
    np.testing.assert_allclose(sub.chi[:, 6:], chi[2::3, 6:], atol=np.radians(1.0))


def test_import_motion_errors(body, tmp_path, capsys):
    chi, alpha = own_motion(body, "walk", frames=4)
    clip = own_bvh(body, chi, alpha, tmp_path / "own.bvh")
    (tmp_path / "exists.npz").write_bytes(b"keep")
    text = tmp_path / "notes.bvh"
    text.write_text("not a motion\n")
    for args, message in [
        ([str(tmp_path / "missing.bvh"), "--out", str(tmp_path / "a.npz")], "no such BVH file"),
        ([str(text), "--out", str(tmp_path / "b.npz")], "not a BVH file"),
        ([str(clip), "--out", str(tmp_path / "exists.npz")], "exists (--overwrite"),
        ([str(clip), "--out", str(tmp_path / "c.npz"), "--step", "0"], "--step 0"),
    ]:
        assert main(["import-motion", *args]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("mocap import-motion: error:") and message in err, err
        assert len(err.splitlines()) == 1
    assert (tmp_path / "exists.npz").read_bytes() == b"keep"
    assert not (tmp_path / "b.npz").exists() and not (tmp_path / "c.npz").exists()


def test_imported_motion_is_exported_and_replayed_and_not_rescored(body, tmp_path, capsys):
    """docs/clips.md: export and replay take import-motion's file (its folder or the .npz
    itself); what cannot use it (rescore: no data to score against) says so in one line."""
    from mocap.export.axes import BVH_FROM_WORLD
    from tests.export.test_exports import read_bvh_joints

    chi, alpha = own_motion(body, "walk", frames=4, seed=1)
    clip = own_bvh(body, chi, alpha, tmp_path / "own.bvh")
    assert main(["import-motion", str(clip), "--out", str(tmp_path / "run")]) == 0
    assert main(["import-motion", str(clip), "--out", str(tmp_path / "walk.npz")]) == 0
    capsys.readouterr()
    motion = load_motion(tmp_path / "run")
    for fmt, ext in (("bvh", ".bvh"), ("trc", ".trc"), ("c3d", ".c3d"), ("gltf", ".glb")):
        assert main(["export", str(tmp_path / "run"), "--format", fmt]) == 0, capsys.readouterr().err
        assert (tmp_path / "run" / f"motion{ext}").is_file()
    _, pos, _ = read_bvh_joints(tmp_path / "run" / "motion.bvh")         # read back: the motion's joints
    assert 1e3 * np.abs(pos - motion.joints.astype(np.float64) @ BVH_FROM_WORLD.T).max() < 1.0
    assert main(["export", str(tmp_path / "walk.npz"), "--format", "bvh"]) == 0      # the .npz by itself
    assert (tmp_path / "walk.bvh").is_file()
    capsys.readouterr()
    assert main(["replay", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert "an imported clip" in out and "motion: 4 frames" in out and "tracker retarget" in out
    assert main(["replay", str(tmp_path / "walk.npz")]) == 0
    assert main(["rescore", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no data to score it against" in err and len(err.splitlines()) == 1
    # a run's motion.npz alone is not exported by itself (its folder says whether it is complete)
    arrays = dict(np.load(tmp_path / "walk.npz"))
    arrays["tracker"] = np.array("marker_apf")
    np.savez(tmp_path / "other.npz", **arrays)
    assert main(["export", str(tmp_path / "other.npz"), "--format", "bvh"]) == 2
    assert "is exported by its run folder" in capsys.readouterr().err
    assert not (tmp_path / "other.bvh").exists()
