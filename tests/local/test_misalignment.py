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


@pytest.mark.parametrize("tolerance", [0, 1, 2])
def test_compiled_limb_errors_equal_the_dilated_mask_lookup(scene, tolerance, monkeypatch):
    """The limb errors counted in one compiled pass (a square of 2 tolerance + 1 pixels around
    each vertex) equal the numpy path's (cv2.dilate, then a lookup per vertex), bit for bit:
    the true pose, a perturbed one, vertices off the image and on half-pixels, an empty view."""
    pytest.importorskip("numba")
    from mocap.local import misalignment

    body, seq = scene
    det = MisalignmentDetector(body, seq.rig, tolerance_px=tolerance)
    rng = np.random.default_rng(tolerance)
    masks = seq.masks[0].copy()
    masks[1] = False
    for k in range(3):
        chi = seq.gt.chi[0].copy()
        chi[6:] += rng.normal(0, 0.2 * k, body.num_dofs - 6)
        chi[:3] += [0.8 * (k == 2), 0.0, 0.0]                        # partly off some images
        verts = body.shaped(seq.gt.alpha).pose(chi).vertices[0]
        obs, px, _ = det._observed(verts, masks)
        px = px.copy()
        px[:, :50] = np.round(px[:, :50]) + 0.5                         # ties: half to even
        got = det._limb_errors(obs, px)
        monkeypatch.setattr(misalignment, "HAVE_NUMBA", False)
        want = det._limb_errors(obs, px)
        monkeypatch.undo()
        np.testing.assert_array_equal(got, want)
        assert np.nanmax(want) > 0 and np.isnan(want).any() == np.isnan(got).any()
