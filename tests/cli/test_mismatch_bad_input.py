"""Bad input on data our model did not generate: views whose silhouettes are empty are left out
and reported; ground truth naming joints the body does not have fails before any work."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import mocap
from mocap.data.sequence_io import write_sequence
from mocap.data.sources import folder_sequence
from mocap.eval.mismatch import fit_oracle
from mocap.trackers.initialization import initialize_from_silhouettes
from tests.cli import in_process

REPO = Path(__file__).resolve().parents[2]
BOX = REPO / "data" / "mismatch" / "box"


@pytest.fixture(scope="module")
def body():
    return mocap.load_body("paper22")


def test_views_with_empty_silhouettes_are_left_out_and_reported(body):
    seq = folder_sequence(body=body, path=str(BOX), images=False)
    masks = seq.masks[:3].copy()
    masks[:, [1, 2]] = False                                  # two views see nothing
    gt = dataclasses.replace(seq.gt, joints=seq.gt.joints[:3], joint_valid=None, surface=None,
                             surface_faces=None)
    seq = dataclasses.replace(seq, masks=masks, gt=gt)
    start = fit_oracle(body, seq.gt.joint_names, seq.gt.joints[:3], None, seq.gt.skeleton)
    res = mocap.track(seq, tracker="apf_prior", body=body, init=start.chi[0], alpha=start.alpha, frames=3,
                      seed=0, particles=8, layers=2)
    for est in res.estimates[1:]:
        assert est.diagnostics.ignored_views == (seq.rig.names[1], seq.rig.names[2])
        assert np.all(np.isfinite(est.chi))


def test_initialisation_refuses_silhouettes_in_fewer_than_two_views(body):
    seq = folder_sequence(body=body, path=str(BOX), images=False)
    masks = seq.masks[0].copy()
    masks[1:] = False
    with pytest.raises(ValueError, match="at least 2 views"):
        initialize_from_silhouettes(body, seq.rig, masks, np.random.default_rng(0))


def test_ground_truth_with_joints_the_body_lacks_fails_before_any_work(body, tmp_path):
    seq = folder_sequence(body=body, path=str(BOX), images=False)
    gt = seq.gt
    names = [*gt.joint_names, "tail_tip"]
    joints = np.concatenate([gt.joints[:2], gt.joints[:2, :1]], axis=1)
    bad = dataclasses.replace(seq, masks=seq.masks[:2],
                              gt=dataclasses.replace(gt, joints=joints, joint_names=tuple(names), skeleton="",
                                                     joint_valid=None, surface=None, surface_faces=None))
    write_sequence(bad, tmp_path / "seq")
    out = in_process.mocap("track", "data=folder", f"data.path={tmp_path / 'seq'}",     # in this process
                           "tracker=local", "init.mode=tracker", f"hydra.run.dir={tmp_path / 'run'}")
    assert out.returncode != 0
    assert "tail_tip" in out.stderr and "unknown joints" in out.stderr
    assert not (tmp_path / "run" / "recording.rrd").exists()
    assert not (tmp_path / "run" / "motion.npz").exists()
