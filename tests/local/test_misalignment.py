"""The misalignment detector under model mismatch: a baseline set by the first check."""

from __future__ import annotations

import numpy as np
import pytest

import mocap
from mocap.local.misalignment import MisalignmentDetector


@pytest.fixture(scope="module")
def scene():
    body = mocap.load_body("paper22")
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=2, seed=0)
    return body, seq


def test_a_body_of_another_shape_is_not_misaligned_but_a_raised_arm_is(scene):
    body, seq = scene
    chi = seq.gt.chi[0]
    wide = seq.gt.alpha.copy()
    wide[2] -= 3.0                      # a body of another build than the one the masks show
    verts = body.shaped(wide).pose(chi).vertices[0]
    absolute = MisalignmentDetector(body, seq.rig, relative=False)
    relative = MisalignmentDetector(body, seq.rig)
    shape_only = absolute(verts, seq.masks[0])
    assert shape_only.names                                 # the paper's test flags the shape mismatch
    assert not relative(verts, seq.masks[0]).names          # the first check sets the baseline
    assert not relative(verts, seq.masks[0]).names
    raised = chi.copy()
    raised[body.dof_index("l_shoulder_abd")] += np.deg2rad(80)
    moved = relative(body.shaped(wide).pose(raised).vertices[0], seq.masks[0])
    assert {"l_elbow", "l_wrist"} <= set(moved.names) and "r_wrist" not in moved.names
    assert np.all(relative.baseline <= relative.baseline_cap)


def test_a_limb_already_off_at_the_first_check_stays_detectable(scene):
    body, seq = scene
    chi = seq.gt.chi[0].copy()
    chi[body.dof_index("l_shoulder_abd")] += np.deg2rad(80)
    det = MisalignmentDetector(body, seq.rig)
    check = det(body.shaped(seq.gt.alpha).pose(chi).vertices[0], seq.masks[0])
    assert "l_wrist" in check.names                         # its baseline is capped
