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
